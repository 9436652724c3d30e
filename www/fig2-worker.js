// The fig. 2 study off the main thread: run after run of the wasm `fig2_run` (the same code
// as `nmci fig2`), the summary rows (`fig2_summary`) posted back at most every 100 ms and at
// the end. A "stop" message is seen between runs.
import { fig2_run, fig2_summary } from "./pkg/nmci.js";
import { onRun, ready, reportFailure } from "./worker-init.js";


onRun(async ({ config }, stopped) => {
  const t0 = performance.now();
  const runs = [];
  try {
    await ready;
    // Summarising hands every run so far to wasm: done at most every 100 ms (and at the
    // end), not after each of up to 1000 runs.
    let posted = 0;
    let lastPost = -Infinity;
    const post = () => {
      const rows = fig2_summary(config, runs);
      self.postMessage({ type: "rows", rows, runsDone: runs.length, elapsedMs: performance.now() - t0 });
      posted = runs.length;
      lastPost = performance.now();
    };
    for (let r = 0; r < config.runs && !stopped(); r++) {
      runs.push(fig2_run(config, r));
      if (performance.now() - lastPost >= 100) post();
      await new Promise((resolve) => setTimeout(resolve, 0));
    }
    if (posted < runs.length) post();
    self.postMessage({ type: stopped() ? "stopped" : "done" });
  } catch (err) {
    reportFailure(err);
  }
});
