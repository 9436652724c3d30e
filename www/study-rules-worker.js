// The study's second run worker: the wasm `StudyRules` (the runs of `WORKER_RULES[1]`,
// src/sim/live.rs) advanced a chunk of steps at a time beside the first run worker
// (www/study-worker.js), which runs the other rules. After each chunk its new steps go
// straight to the first worker as a "tail" (through the `MessageChannel` port of the start
// message); the first's views and charts are then those of one worker running every rule,
// bit for bit. A "stop" message is seen between chunks.
import { StudyRules } from "./pkg/nmci.js";
import { chunk } from "./study-chunk.js";
import { onRun, ready, reportFailure as fail } from "./worker-init.js";

onRun(async ({ config, port }, stopped) => {
  let rules;
  try {
    await ready;
    rules = new StudyRules(config);
  } catch (err) {
    fail(err);
    return;
  }
  const steps = chunk(config.runs);
  try {
    let finished = false;
    while (!finished && !stopped()) {
      finished = rules.advance(steps);
      port.postMessage(rules.tail());
      // Yield so that a "stop" message can arrive.
      await new Promise((resolve) => setTimeout(resolve, 0));
    }
    self.postMessage({ type: stopped() ? "stopped" : "done" });
  } catch (err) {
    if (fail(err)) return; // the instance is unusable: no `free`
  }
  port.close();
  rules.free();
});
