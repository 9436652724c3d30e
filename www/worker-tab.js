// What the tabs that run a study in Web Workers (Tracking study: the runs and the exact COIN
// side by side; Fig. 2) share: reading whole-number fields with inline errors, and the
// workers' wiring — start and stop buttons, progress messages, errors, and
// `document.body.dataset[name]` ("running", "done", "stopped", "error") for tests. Workers
// that crashed (a panic in wasm, www/worker-init.js) or failed are dropped; the next start
// makes fresh ones.
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
 * Wires `#${name}-start`, `#${name}-stop` and `#err-${name}` to module workers, one per URL in
 * `urls` (or the one `url`). `readConfig()` gives the start's config (or throws, shown
 * inline); `split(config)` the config for each worker (`null`: that worker sits this one
 * out; by default the one worker gets the config). The tab is done when every started worker
 * said "done" (or "stopped"); an error or a crash in any of them ends the run for all (the
 * workers are dropped; the next start makes fresh ones). Every other message goes to
 * `onProgress(msg, index)`. For each pair `[i, j]` of `channels`, workers `i` and `j` get
 * the two ends of a fresh `MessageChannel` as `port` in their start messages (when both
 * start): they talk directly, and a late message of a previous run cannot reach this run's
 * port. Returns `{ start, running }`.
 */
export function workerTab({ name, label, url, urls = [url], readConfig, split = (config) => [config], channels = [], onProgress }) {
  const workers = urls.map(() => null);
  let running = false;
  let pending = 0; // started workers that have not finished
  let stopped = false;
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
  function dropAll() {
    workers.forEach((w, i) => {
      w?.terminate();
      workers[i] = null;
    });
  }
  function ensureWorker(i) {
    if (!workers[i]) {
      const worker = new Worker(urls[i], { type: "module" });
      worker.onmessage = (event) => {
        if (workers[i] !== worker) return; // a dropped worker's last words
        const msg = event.data;
        if (msg.type === "error" || msg.type === "crashed") {
          error.textContent = msg.type === "crashed" ? `${msg.error}; a fresh worker takes the next run` : msg.error;
          dropAll();
          finish("error");
        } else if (msg.type === "done" || msg.type === "stopped") {
          stopped ||= msg.type === "stopped";
          if (--pending === 0) finish(stopped ? "stopped" : "done");
        } else {
          onProgress(msg, i);
        }
      };
      worker.onerror = (event) => {
        if (workers[i] !== worker) return;
        error.textContent = `the ${label} worker failed: ${event.message || "unknown error"}`;
        dropAll();
        finish("error");
      };
      workers[i] = worker;
    }
    return workers[i];
  }
  function launch(messages) {
    document.body.dataset[name] = "running";
    setRunning(true);
    stopped = false;
    pending = 0;
    const ports = new Map();
    for (const [i, j] of channels) {
      if (!messages[i] || !messages[j]) continue;
      const { port1, port2 } = new MessageChannel();
      ports.set(i, port1).set(j, port2);
    }
    messages.forEach((message, i) => {
      if (message === null) return;
      const port = ports.get(i);
      ensureWorker(i).postMessage(port ? { ...message, port } : message, port ? [port] : []);
      pending++;
    });
  }
  function start() {
    error.textContent = "";
    let configs;
    try {
      configs = split(readConfig());
    } catch (err) {
      error.textContent = err.message;
      return;
    }
    launch(configs.map((config) => (config === null ? null : { type: "start", config })));
  }
  $(`#${name}-start`).addEventListener("click", start);
  $(`#${name}-stop`).addEventListener("click", () => workers.forEach((w) => w?.postMessage({ type: "stop" })));
  /** Test-only (the end-to-end test): makes the first worker panic with `message`. */
  const panicForTest = (message) => launch([{ type: "panic", message }]);
  (window.nmciTabs ??= {})[name] = { panicForTest };
  return { start, running: () => running };
}
