// The explorer's round trip to its Web Worker (www/worker.js, one wasm `explore` per state):
// one request in flight, the latest state wins. A solve still running ABANDON_MS after a newer
// edit arrived is stale: the worker is terminated (wasm cannot be interrupted from outside)
// and a fresh one takes the newest state. A worker that crashed (a panic in wasm,
// www/worker-init.js) or failed is replaced the same way; the state it was given is not sent
// again (it would crash again), the next edit goes to the fresh worker. After
// MAX_FAILURES_IN_A_ROW failures without a result (say, the module cannot load) no worker is
// started until the next edit, so a broken worker cannot respawn in a loop. Timings of every
// round trip (edit → shown) and of the wasm call alone are kept in `window.nmciStats` (the
// end-to-end tests read them).
const ABANDON_MS = 300;
const MAX_FAILURES_IN_A_ROW = 3;
// The page's rejection-sampler budget per sample set: a tenth of the library's default
// (`SamplerSettings::default`, which `explore` would otherwise use as `fuse` does), so an edit
// never waits seconds on a sampler; under `auto` the smaller budget also means hit-and-run
// sooner.
const INTERACTIVE_MAX_TRIALS = 200_000;

/** The request of the wasm `explore` (and `prove`) for an explorer state. */
export function request(s) {
  return {
    pa: s.pa, pb: s.pb, pab_unknown: s.pattern, criterion: s.criterion,
    samples: s.samples, seed: s.seed, region_samples: s.region, sampler: s.sampler,
    max_trials: INTERACTIVE_MAX_TRIALS,
    ...(s.couplingTol === undefined ? {} : { coupling_tol: s.couplingTol }),
    ...(s.blocks === undefined ? {} : { blocks: s.blocks }),
  };
}

/**
 * `onResult(result, state)` gets each analysis with the state it is of; `onError(message,
 * field)` a request's error and the request field at fault; `onBusy(bool)` whether a request is
 * in flight; `onTimings(median, count)` after each round trip; `onWorkerError(message)` when the
 * worker itself fails.
 */
export function createExploreClient({ url, onResult, onError, onBusy, onTimings, onWorkerError }) {
  const timings = [];
  const computeTimings = []; // the wasm `explore` call alone, in the worker
  const medianOf = (values) => {
    if (values.length === 0) return NaN;
    const s = [...values].sort((a, b) => a - b);
    return s[Math.floor(s.length / 2)];
  };
  const stats = {
    timings,
    computeTimings,
    median: () => medianOf(timings),
    computeMedian: () => medianOf(computeTimings),
    runs: 0,
    abandoned: 0,
    crashes: 0,
  };
  window.nmciStats = stats;
  /** Test-only (the end-to-end test): makes the idle worker panic with `message`. */
  stats.panicForTest = (message) => {
    if (inFlight) throw new Error("a request is in flight");
    inFlight = { id: nextId++, t0: performance.now(), state: null };
    onBusy(true);
    worker ??= makeWorker();
    worker.postMessage({ id: inFlight.id, panic: message });
  };
  let worker = null;
  let failuresInARow = 0;
  let staleTimer = null;
  let nextId = 1;
  let inFlight = null; // { id, t0, state }
  let queued = null;

  function makeWorker() {
    const w = new Worker(url, { type: "module" });
    w.onmessage = onMessage;
    w.onerror = (e) => replace(`the worker failed: ${e.message || "unknown error"}`);
    return w;
  }

  /** Drops the current worker (crashed or failed) for a fresh one; reports `message`. */
  function replace(message) {
    clearStale();
    worker.terminate();
    stats.crashes++;
    failuresInARow++;
    inFlight = null;
    if (failuresInARow >= MAX_FAILURES_IN_A_ROW) {
      worker = null; // the next edit starts one (send)
      queued = null;
      onWorkerError(`${message}; ${failuresInARow} failures in a row: no new worker until the next edit`);
      onBusy(false);
      return;
    }
    worker = makeWorker();
    onWorkerError(`${message}; its worker was replaced`);
    sendQueuedOrIdle();
  }

  function clearStale() {
    if (staleTimer) {
      clearTimeout(staleTimer);
      staleTimer = null;
    }
  }

  function sendQueuedOrIdle() {
    if (queued) {
      const q = queued;
      queued = null;
      send(q);
    } else {
      onBusy(false);
    }
  }

  function send(s) {
    worker ??= makeWorker();
    inFlight = { id: nextId++, t0: performance.now(), state: s };
    onBusy(true);
    worker.postMessage({ id: inFlight.id, request: request(s) });
  }

  function onMessage(event) {
    const { id, ok, result, error, field, crashed, ms } = event.data;
    if (!inFlight || id !== inFlight.id) return;
    if (crashed) return replace(error);
    clearStale();
    const done = inFlight;
    inFlight = null;
    failuresInARow = 0;
    if (ok) {
      onResult(result, done.state);
      timings.push(performance.now() - done.t0);
      computeTimings.push(ms);
      if (timings.length > 200) timings.shift();
      if (computeTimings.length > 200) computeTimings.shift();
      stats.runs++;
    } else {
      onError(error, field);
    }
    onTimings(stats.median(), timings.length);
    sendQueuedOrIdle();
  }

  worker = makeWorker();
  return {
    /** Analyses `snapshot` (a copy of the state) as soon as the worker is free. */
    submit(snapshot) {
      if (inFlight) {
        queued = snapshot;
        if (!staleTimer) {
          const stale = inFlight.id;
          const wait = Math.max(0, ABANDON_MS - (performance.now() - inFlight.t0));
          staleTimer = setTimeout(() => {
            staleTimer = null;
            if (!inFlight || inFlight.id !== stale || !queued) return;
            worker.terminate();
            worker = makeWorker();
            stats.abandoned++;
            inFlight = null;
            sendQueuedOrIdle();
          }, wait);
        }
        return;
      }
      send(snapshot);
    },
  };
}
