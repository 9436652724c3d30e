// Heavy work off the main thread: one wasm `explore` call per state (CI, nmCI, the sampled
// SDP, the region of possible fused covariances and every rule's conservativeness margin).
import { explore, panic_for_test } from "./pkg/nmci.js";
import { ready, crashMessage } from "./worker-init.js";

self.onmessage = async (event) => {
  const { id, request, panic } = event.data;
  try {
    await ready;
    if (panic) panic_for_test(panic); // the end-to-end test's forced panic
    const t0 = performance.now();
    const result = explore(request);
    const ms = performance.now() - t0;
    self.postMessage({ id, ok: true, result, ms }, [result.region.buffer]);
  } catch (err) {
    const crash = crashMessage(err);
    if (crash) {
      self.postMessage({ id, ok: false, crashed: true, error: crash });
      self.close();
      return;
    }
    // `field`: the request field at fault (set by the wasm layer; the page places the message by it).
    self.postMessage({ id, ok: false, error: String(err && err.message ? err.message : err), field: err?.field });
  }
};
