// The explorer's second stage, in its own Web Worker: one wasm `prove` per message (the
// cutting-plane SDP's proven bracket, www/prove-client.js). Separate from the analysis worker,
// so that worker keeps its certificate memo when a proof is abandoned.
import { prove } from "./pkg/nmci.js";
import { ready, crashMessage } from "./worker-init.js";

self.onmessage = async (event) => {
  const { id, request } = event.data;
  try {
    await ready;
    const t0 = performance.now();
    const proof = prove(request);
    self.postMessage({ id, ok: true, proof, ms: performance.now() - t0 });
  } catch (err) {
    const crash = crashMessage(err);
    self.postMessage({ id, ok: false, crashed: crash !== null, error: crash ?? String(err && err.message ? err.message : err) });
    if (crash) self.close();
  }
};
