// The tracking study off the main thread: the wasm `Study` advanced a chunk of steps at a
// time; after each chunk the current view (headline numbers) and the charts (`Study.charts`,
// drawn on the page by the wasm `draw_chart`) go back to the page. A "stop" message is seen between chunks.
import { Study, panic_for_test } from "./pkg/nmci.js";
import { onRun, ready, reportFailure as fail } from "./worker-init.js";

// Steps per message: about 0.1–0.2 s of work. Every run advances by each step (their shared
// covariances once, then each run's means), so many runs take fewer steps per message.
const chunk = (runs) => Math.max(1, Math.round(200 / Math.max(10, runs)));

onRun(async ({ type, config, message }, stopped) => {
  let study;
  const steps = chunk(config?.runs ?? 1);
  try {
    await ready;
    if (type === "panic") panic_for_test(message); // the end-to-end test's forced panic
    study = new Study(config);
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
      finished = study.advance(steps);
      const view = study.view();
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
  study.free();
}, ["panic"]);
