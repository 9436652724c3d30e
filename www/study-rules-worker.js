// The study's second run worker: the wasm `StudyRules` (the runs of `WORKER_RULES[1]`,
// src/sim/live.rs) advanced a chunk of steps at a time beside the first run worker
// (www/study-worker.js), which runs the other rules. After each chunk its new steps go
// straight to the first worker as a "tail" (through the `MessageChannel` port of the start
// message); the first's views and charts are then those of one worker running every rule,
// bit for bit. A "stop" message is seen between chunks.
import { StudyRules } from "./pkg/nmci.js";
import { chunk } from "./study-chunk.js";
import { secondWorker } from "./worker-init.js";

secondWorker((config) => new StudyRules(config), (config) => chunk(config.runs));
