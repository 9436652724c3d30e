// Heavy work off the main thread: one wasm `explore` call per state (CI, nmCI, the sampled
// SDP, the region of possible fused covariances and every rule's conservativeness margin).
import init, { explore } from "./pkg/nmci.js";

const ready = init();

self.onmessage = async (event) => {
  const { id, request } = event.data;
  try {
    await ready;
    const t0 = performance.now();
    const result = explore(request);
    const ms = performance.now() - t0;
    self.postMessage({ id, ok: true, result, ms }, [result.region.buffer]);
  } catch (err) {
    // `field`: the request field at fault (set by the wasm layer; the page places the message by it).
    self.postMessage({ id, ok: false, error: String(err && err.message ? err.message : err), field: err?.field });
  }
};
