// The fig. 2 study off the main thread: run after run of the wasm `fig2_run` (the same code
// as `nmci fig2`), the summary rows (`fig2_summary`) posted back after every run. A "stop"
// message is seen between runs.
import init, { fig2_run, fig2_summary } from "./pkg/nmci.js";

const ready = init();
let stopped = false;

self.onmessage = async (event) => {
  const { type, config } = event.data;
  if (type === "stop") {
    stopped = true;
    return;
  }
  if (type !== "start") return;
  stopped = false;
  const t0 = performance.now();
  const runs = [];
  try {
    await ready;
    for (let r = 0; r < config.runs && !stopped; r++) {
      runs.push(fig2_run(config, r));
      const rows = fig2_summary(config, runs);
      self.postMessage({ type: "rows", rows, runsDone: runs.length, elapsedMs: performance.now() - t0 });
      await new Promise((resolve) => setTimeout(resolve, 0));
    }
    self.postMessage({ type: stopped ? "stopped" : "done" });
  } catch (err) {
    self.postMessage({ type: "error", error: String(err && err.message ? err.message : err) });
  }
};
