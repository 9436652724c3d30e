// The tracking study off the main thread: the wasm `Study` advanced a chunk of steps at a
// time; after each chunk the current view (headline numbers) and the charts (`Study.charts`,
// drawn on the page by the wasm `draw_chart`) go back to the page. The rules are shared with
// a second run worker (www/study-rules-worker.js: `Study.with_second_worker` runs
// `WORKER_RULES[0]` here, src/sim/live.rs), which sends its steps straight here as "tails"
// (through the `MessageChannel` port of the start message): after each chunk this worker
// waits for the second's steps up to the same step, so every view is that of one worker
// running every rule, bit for bit. A "stop" message is seen between chunks and while
// waiting.
import { Study, panic_for_test } from "./pkg/nmci.js";
import { chunk } from "./study-chunk.js";
import { onRun, ready, reportFailure as fail, tailReceiver } from "./worker-init.js";

// The second worker's tails for the run in progress.
const receiver = tailReceiver();

onRun(async ({ type, config, message, port }, stopped) => {
  receiver.listen(port);
  let study;
  const steps = chunk(config?.runs ?? 1);
  try {
    await ready;
    if (type === "panic") panic_for_test(message); // the end-to-end test's forced panic
    study = Study.with_second_worker(config);
  } catch (err) {
    fail(err);
    return;
  }
  const t0 = performance.now();
  let runStarted = t0;
  const runTimes = [];
  try {
    let finished = false;
    let runsDone = 0;
    while (!finished && !stopped()) {
      study.advance(steps);
      while (study.waiting() && !stopped()) {
        if (receiver.tails.length) study.absorb(receiver.tails.shift());
        else await receiver.arrival();
      }
      if (stopped()) break;
      const view = study.view();
      finished = view.finished;
      // The runs finish together: the time per run is their time over their number.
      if (view.runs_done > runsDone) {
        const now = performance.now();
        runTimes.push((now - runStarted) / (view.runs_done - runsDone));
        runStarted = now;
        runsDone = view.runs_done;
      }
      view.elapsed_ms = performance.now() - t0;
      view.run_ms = runTimes.slice();
      self.postMessage({ type: "view", view, charts: study.charts() }, [view.nees.buffer, view.rmse.buffer, view.two_sigma.buffer, view.omega.buffer, view.coin.buffer]);
      // Yield so that a "stop" message can arrive.
      await new Promise((resolve) => setTimeout(resolve, 0));
    }
    self.postMessage({ type: stopped() ? "stopped" : "done" });
  } catch (err) {
    if (fail(err)) return; // the instance is unusable: no `free`
  }
  port?.close();
  study.free();
}, ["panic"], receiver.nudge);
