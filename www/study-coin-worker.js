// The tracking study's exact COIN off the runs' critical path: the wasm `StudyCoin` (every
// estimator's true error covariance, propagated exactly; it does not depend on the runs)
// advanced a chunk of estimator-steps at a time in its own Web Worker, beside the runs'
// workers. Its estimators are shared with a second COIN worker (www/study-coin-part-worker.js:
// `StudyCoin.with_second_worker` propagates `COIN_WORKER_ESTIMATORS[0]` here,
// src/sim/live.rs), whose steps arrive straight here as "tails" (through the `MessageChannel`
// port of the start message). After each chunk the view (the mean and largest COIN per
// estimator over the steps every estimator reached, the series as a Float64Array) and the
// chart go back to the page; once its own estimators are done it waits for the second's. A
// "stop" message is seen between chunks and while waiting.
import { StudyCoin } from "./pkg/nmci.js";
import { COIN_CHUNK } from "./study-chunk.js";
import { onRun, ready, reportFailure as fail, tailReceiver } from "./worker-init.js";

// The second worker's tails for the run in progress.
const receiver = tailReceiver();

onRun(async ({ config, port }, stopped) => {
  receiver.listen(port);
  let coin;
  try {
    await ready;
    coin = StudyCoin.with_second_worker(config);
  } catch (err) {
    fail(err);
    return;
  }
  const t0 = performance.now();
  try {
    let finished = false;
    while (!finished && !stopped()) {
      // Its own estimators done: nothing to do until the second worker's next tail.
      if (coin.waiting() && !receiver.tails.length) await receiver.arrival();
      if (stopped()) break;
      coin.advance(COIN_CHUNK);
      while (receiver.tails.length) coin.absorb(receiver.tails.shift());
      const view = coin.view();
      finished = view.finished;
      view.elapsed_ms = performance.now() - t0;
      self.postMessage({ type: "coin", view, chart: coin.chart() }, [view.coin.buffer]);
      await new Promise((resolve) => setTimeout(resolve, 0));
    }
    self.postMessage({ type: stopped() ? "stopped" : "done" });
  } catch (err) {
    if (fail(err)) return;
  }
  port.close();
  coin.free();
}, [], receiver.nudge);
