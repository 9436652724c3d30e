// What the tabs that run a study in a Web Worker (Tracking study, Fig. 2) share: reading
// whole-number fields with inline errors, and the worker's wiring — start and stop buttons,
// progress messages, errors, and `document.body.dataset[name]` ("running", "done",
// "stopped", "error") for tests. A worker that crashed (a panic in wasm, www/worker-init.js)
// or failed is dropped; the next start makes a fresh one.
const $ = (s) => document.querySelector(s);

/** `{key: value}` from the inputs `#${prefix}-${key}`, each a whole number in [min, max];
 * throws an Error naming the first bad field (and marks it). */
export function readWholeNumbers(prefix, fields) {
  const config = {};
  for (const [key, min, max] of fields) {
    const input = $(`#${prefix}-${key}`);
    const raw = input.value.trim();
    const v = Number(raw);
    if (raw === "" || !Number.isInteger(v) || v < min || v > max) {
      input.classList.add("bad");
      throw new Error(`${key} must be a whole number in ${min}…${max === Number.MAX_SAFE_INTEGER ? "2⁵³" : max} (got "${raw}")`);
    }
    input.classList.remove("bad");
    config[key] = v;
  }
  return config;
}

/**
 * Wires `#${name}-start`, `#${name}-stop` and `#err-${name}` to a module worker at `url`.
 * `readConfig()` gives the start message's config (or throws, shown inline); every message
 * other than "error", "done" and "stopped" goes to `onProgress(msg)`. Returns
 * `{ start, running }`.
 */
export function workerTab({ name, label, url, readConfig, onProgress }) {
  let worker = null;
  let running = false;
  const error = $(`#err-${name}`);
  const setRunning = (on) => {
    running = on;
    $(`#${name}-start`).disabled = on;
    $(`#${name}-stop`).disabled = !on;
  };
  const finish = (state) => {
    setRunning(false);
    document.body.dataset[name] = state;
  };
  function drop() {
    worker?.terminate();
    worker = null;
  }
  function ensureWorker() {
    if (!worker) {
      worker = new Worker(url, { type: "module" });
      worker.onmessage = (event) => {
        const msg = event.data;
        if (msg.type === "error" || msg.type === "crashed") {
          error.textContent = msg.type === "crashed" ? `${msg.error}; a fresh worker takes the next run` : msg.error;
          if (msg.type === "crashed") drop();
          finish("error");
        } else if (msg.type === "done" || msg.type === "stopped") {
          finish(msg.type);
        } else {
          onProgress(msg);
        }
      };
      worker.onerror = (event) => {
        error.textContent = `the ${label} worker failed: ${event.message || "unknown error"}`;
        drop();
        finish("error");
      };
    }
  }
  function start() {
    error.textContent = "";
    let config;
    try {
      config = readConfig();
    } catch (err) {
      error.textContent = err.message;
      return;
    }
    ensureWorker();
    document.body.dataset[name] = "running";
    setRunning(true);
    worker.postMessage({ type: "start", config });
  }
  $(`#${name}-start`).addEventListener("click", start);
  $(`#${name}-stop`).addEventListener("click", () => worker && worker.postMessage({ type: "stop" }));
  /** Test-only (the end-to-end test): makes the worker panic with `message`. */
  const panicForTest = (message) => {
    ensureWorker();
    document.body.dataset[name] = "running";
    setRunning(true);
    worker.postMessage({ type: "panic", message });
  };
  (window.nmciTabs ??= {})[name] = { panicForTest };
  return { start, running: () => running };
}
