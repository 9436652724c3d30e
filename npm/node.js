// The package's entry in Node: the wasm module read from this folder and instantiated
// synchronously, so every function is ready on import (no `await init()`). Bundlers and
// browsers take `nmci.js` instead, whose default export `init` loads the module.
import { readFileSync } from "node:fs";
import { initSync } from "./nmci.js";

initSync({ module: readFileSync(new URL("./nmci_bg.wasm", import.meta.url)) });

export * from "./nmci.js";
/** Already initialised in Node; kept so that code written for the browser entry runs unchanged. */
export default async function init() {}
