// The package's types: wasm-bindgen's declarations (nmci.d.ts), with `fuse` typed by the
// contract (contract.d.ts).
import type { FuseRequest, FuseResponse } from "./contract.js";

export * from "./nmci.js";
export { default } from "./nmci.js";
export type * from "./contract.js";

/**
 * Runs a fusion request and returns its response; throws an `Error` (`FuseError`) naming the
 * problem and, in `field`, the request field at fault.
 */
export function fuse(request: FuseRequest): FuseResponse;
/** A list of requests: the list of their responses; the first that fails throws, naming its index. */
export function fuse(requests: FuseRequest[]): FuseResponse[];

/** The contract's field names, from the Rust crate. */
export function contract_fields(): { request: string[]; response: string[] };
