// The explorer's second stage (wasm `prove`: the cutting planes, and at three states their own
// rule proven on cones of directions): run after an analysis whose proven bracket is open at
// n ≤ PROVE_MAX_N, where it can close it (at four states its lower end: the worst cases the
// samples missed, e.g. a correlation of exactly ±1 between tied variances), in a worker of
// its own (www/prove-worker.js) with a time limit of PROVE_SECONDS. A new edit cancels it: a proof still running is abandoned (its
// worker terminated; wasm cannot be interrupted from outside) and the next one gets a fresh
// worker. A worker that crashed is dropped the same way. Timings go to
// `window.nmciStats.proofTimings` (the end-to-end test reads them).
import { request } from "./explore-client.js";

/** The largest n the page proves at: at four states the cutting planes' upper end is the
 * certificate's the page has already, but their lower end finds the worst cases the sampled
 * SDP missed (the paper's preset at n = 4 closes so, as `nmci fuse` with `sdp_cuts` does).
 * Five and six states are not offered: what the proof achieves there within PROVE_SECONDS has
 * not been measured (issue 65). */
export const PROVE_MAX_N = 4;
/** The proof's time limit in seconds (the wasm `prove` then returns its best bracket so far). */
export const PROVE_SECONDS = 30;

/** Whether the page runs the second stage on `analysis`. */
export const worthProving = (analysis) => Boolean(analysis.gap && !analysis.gap.closed && analysis.n <= PROVE_MAX_N);

/**
 * `onProof(proof, state)` gets the proof of a state (`null`: the loop has no bracket);
 * `onProofError(message, state)` why it failed; `onProving(bool)` whether a proof is running.
 */
export function createProveClient({ url, onProof, onProofError, onProving }) {
  const stats = (window.nmciStats ??= {});
  stats.proofTimings = [];
  stats.proofsAbandoned = 0;
  let worker = null;
  let running = null; // { id, state }
  let nextId = 1;

  function onMessage(event) {
    const { id, ok, proof, error, crashed, ms } = event.data;
    if (!running || id !== running.id) return;
    const { state } = running;
    running = null;
    if (crashed) {
      worker.terminate();
      worker = null;
    }
    if (ok) {
      stats.proofTimings.push(ms);
      onProof(proof, state);
    } else {
      onProofError(error, state);
    }
    onProving(false);
  }

  return {
    /** Proves `state` (the snapshot its analysis was of), cancelling any proof running. */
    start(state) {
      this.cancel();
      if (!worker) {
        worker = new Worker(url, { type: "module" });
        worker.onmessage = onMessage;
        worker.onerror = (e) => {
          const failed = running;
          running = null;
          worker?.terminate();
          worker = null;
          if (failed) {
            onProofError(`the proof's worker failed: ${e.message || "unknown error"}`, failed.state);
            onProving(false);
          }
        };
      }
      running = { id: nextId++, state };
      onProving(true);
      worker.postMessage({ id: running.id, request: { ...request(state), time_limit: PROVE_SECONDS } });
    },
    /** Abandons the proof running, if any. */
    cancel() {
      if (!running) return;
      running = null;
      worker.terminate();
      worker = null;
      stats.proofsAbandoned++;
      onProving(false);
    },
  };
}
