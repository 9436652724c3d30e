// The exact COIN's second worker: the wasm `StudyCoinPart` (the estimators of
// `COIN_WORKER_ESTIMATORS[1]`, src/sim/live.rs) advanced a chunk of estimator-steps at a time
// beside the first COIN worker (www/study-coin-worker.js), which propagates the others. After
// each chunk its new steps go straight to the first worker as a "tail" (through the
// `MessageChannel` port of the start message). A "stop" message is seen between chunks.
import { StudyCoinPart } from "./pkg/nmci.js";
import { COIN_CHUNK } from "./study-chunk.js";
import { secondWorker } from "./worker-init.js";

secondWorker((config) => new StudyCoinPart(config), () => COIN_CHUNK);
