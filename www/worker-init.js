// The wasm module inside a Web Worker: loaded with its panic hook installed, and what a panic
// becomes. wasm32 aborts on a panic: the call ends in a `WebAssembly.RuntimeError`
// ("unreachable") and the instance must not be used again. The hook (wasm
// `install_panic_hook`) has stored the panic's message as `self.nmciPanic` first; the worker
// reports it and closes, and the page replaces the worker (explore-client.js, worker-tab.js).
import init, { install_panic_hook } from "./pkg/nmci.js";

/** Resolves once the module is loaded and its panic hook installed. */
export const ready = init().then(() => install_panic_hook());

/** The message to report when `err` is a panic (or any other trap) of the module; `null` for
 * an ordinary thrown error, after which the module is still usable. */
export function crashMessage(err) {
  if (!(err instanceof WebAssembly.RuntimeError)) return null;
  const what = (self.nmciPanic ?? err.message).replace(/\s+/g, " ").trim();
  return `the computation crashed (${what})`;
}

/** Reports `err` to the page ("error", or "crashed" for a trap, after which the worker closes
 * and the page replaces it). Returns whether it was a crash. */
export function reportFailure(err) {
  const crash = crashMessage(err);
  self.postMessage({ type: crash ? "crashed" : "error", error: crash ?? String(err && err.message ? err.message : err) });
  if (crash) self.close();
  return crash !== null;
}

/** The worker side of a tab's run (www/worker-tab.js): on a "start" message (or one of the
 * `also` types) calls `run(message, stopped)`, where `stopped()` says whether a "stop"
 * message has come since; the work checks it between chunks. `onStop()` is called on "stop"
 * (a run waiting on another worker wakes up, www/study-worker.js). */
export function onRun(run, also = [], onStop = () => {}) {
  let stop = false;
  self.onmessage = async (event) => {
    const message = event.data;
    if (message.type === "stop") {
      stop = true;
      onStop();
      return;
    }
    if (message.type !== "start" && !also.includes(message.type)) return;
    stop = false;
    await run(message, () => stop);
  };
}

/** A second worker of a tab (www/study-rules-worker.js, www/study-coin-part-worker.js): on
 * "start", `make(config)` builds the wasm object, which is advanced by `units(config)` at a
 * time until it says it is done or a "stop" comes; after each chunk its `tail()` (the steps
 * since the previous one) goes through the `port` of the start message to the first worker,
 * which shows them. */
export function secondWorker(make, units) {
  onRun(async ({ config, port }, stopped) => {
    let part;
    try {
      await ready;
      part = make(config);
    } catch (err) {
      reportFailure(err);
      return;
    }
    try {
      let finished = false;
      while (!finished && !stopped()) {
        finished = part.advance(units(config));
        port.postMessage(part.tail());
        // Yield so that a "stop" message can arrive.
        await new Promise((resolve) => setTimeout(resolve, 0));
      }
      self.postMessage({ type: stopped() ? "stopped" : "done" });
    } catch (err) {
      if (reportFailure(err)) return; // the instance is unusable: no `free`
    }
    port.close();
    part.free();
  });
}

/** The receiving side of a second worker's tails (www/study-worker.js,
 * www/study-coin-worker.js): `listen(port)` at each start collects that run's tails (a fresh
 * channel per run); `tails` is the queue; `arrival()` resolves on the next tail or on `nudge()`
 * (pass it to `onRun` as `onStop`, so a run waiting for a tail sees a "stop"). */
export function tailReceiver() {
  const tails = [];
  let wake = null;
  const nudge = () => {
    wake?.();
    wake = null;
  };
  return {
    tails,
    nudge,
    listen(port) {
      tails.length = 0;
      if (!port) return;
      port.onmessage = (event) => {
        tails.push(event.data);
        nudge();
      };
    },
    arrival: () => new Promise((resolve) => { wake = resolve; }),
  };
}
