// The exact COIN's second worker: the wasm `StudyCoinPart` (the estimators of
// `COIN_WORKER_ESTIMATORS[1]`, src/sim/live.rs) advanced a chunk of estimator-steps at a time
// beside the first COIN worker (www/study-coin-worker.js), which propagates the others. After
// each chunk its new steps go straight to the first worker as a "tail" (through the
// `MessageChannel` port of the start message). A "stop" message is seen between chunks.
import { StudyCoinPart } from "./pkg/nmci.js";
import { COIN_CHUNK } from "./study-chunk.js";
import { onRun, ready, reportFailure as fail } from "./worker-init.js";

onRun(async ({ config, port }, stopped) => {
  let part;
  try {
    await ready;
    part = new StudyCoinPart(config);
  } catch (err) {
    fail(err);
    return;
  }
  try {
    let finished = false;
    while (!finished && !stopped()) {
      finished = part.advance(COIN_CHUNK);
      port.postMessage(part.tail());
      // Yield so that a "stop" message can arrive.
      await new Promise((resolve) => setTimeout(resolve, 0));
    }
    self.postMessage({ type: stopped() ? "stopped" : "done" });
  } catch (err) {
    if (fail(err)) return; // the instance is unusable: no `free`
  }
  port.close();
  part.free();
});
