// The fusion rules, read from the wasm module's registry (`rules()`, src/fusion/rules.rs):
// names, labels, legends, colours and guarantees. Nothing about a rule is written here.
import init, { rules } from "./pkg/nmci.js";

await init();

/** Every rule, in the registry's order. */
export const RULES = rules();
/** The rules the explorer computes for every state (`explorer` in the registry). */
export const EXPLORER_RULES = RULES.filter((r) => r.explorer);
/** A rule by its name in the JSON contract. */
export const RULE = Object.fromEntries(RULES.map((r) => [r.name, r]));
