// The tracking study's exact COIN off the runs' critical path: the wasm `StudyCoin` (every
// estimator's true error covariance, propagated exactly; it does not depend on the runs)
// advanced a chunk of estimator-steps at a time in its own Web Worker, beside the runs'
// worker (www/study-worker.js). After each chunk its view (the mean and largest COIN per
// estimator, the series as a Float64Array) and its chart go back to the page. A "stop"
// message is seen between chunks.
import { StudyCoin } from "./pkg/nmci.js";
import { onRun, ready, reportFailure as fail } from "./worker-init.js";

const CHUNK = 25; // estimator-steps per message: about 0.2 s of work

onRun(async ({ config }, stopped) => {
  let coin;
  try {
    await ready;
    coin = new StudyCoin(config);
  } catch (err) {
    fail(err);
    return;
  }
  const t0 = performance.now();
  try {
    let finished = false;
    while (!finished && !stopped()) {
      finished = coin.advance(CHUNK);
      const view = coin.view();
      view.elapsed_ms = performance.now() - t0;
      self.postMessage({ type: "coin", view, chart: coin.chart() }, [view.coin.buffer]);
      await new Promise((resolve) => setTimeout(resolve, 0));
    }
    self.postMessage({ type: stopped() ? "stopped" : "done" });
  } catch (err) {
    if (fail(err)) return;
  }
  coin.free();
});
