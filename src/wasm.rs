//! The wasm-bindgen bindings: a thin layer over [`crate::fuse`]. No logic lives here.

use wasm_bindgen::prelude::*;

use crate::api::FuseRequest;

/// Runs a fusion request (the same object as `nmci fuse` reads) and returns the response
/// object; throws an `Error` carrying the message of any invalid input.
#[wasm_bindgen]
pub fn fuse(request: JsValue) -> Result<JsValue, JsError> {
    // Through a JSON value, so that parsing is exactly the CLI's (serde-wasm-bindgen alone
    // skips unknown fields instead of rejecting them).
    let value: serde_json::Value = serde_wasm_bindgen::from_value(request)
        .map_err(|e| JsError::new(&format!("invalid request: {e}")))?;
    let request: FuseRequest = serde_json::from_value(value)
        .map_err(|e| JsError::new(&format!("invalid request: {e}")))?;
    let response = crate::api::fuse(&request)?;
    let serializer = serde_wasm_bindgen::Serializer::new().serialize_missing_as_null(false);
    Ok(response.serialize(&serializer)?)
}

/// Analyses one explorer state (see [`crate::ExploreRequest`]): CI, nmCI, the sampled-SDP
/// bound, the gap, the region of possible true fused covariances and each rule's worst
/// conservativeness margin. The region crosses as a `Float64Array` in `region`
/// (`region_count` row-major `n × n` matrices).
#[wasm_bindgen]
pub fn explore(request: JsValue) -> Result<JsValue, JsError> {
    let value: serde_json::Value = serde_wasm_bindgen::from_value(request)
        .map_err(|e| JsError::new(&format!("invalid request: {e}")))?;
    let request: crate::ExploreRequest = serde_json::from_value(value)
        .map_err(|e| JsError::new(&format!("invalid request: {e}")))?;
    let analysis = crate::explore(&request)?;
    let serializer = serde_wasm_bindgen::Serializer::new().serialize_missing_as_null(false);
    let object = analysis.serialize(&serializer)?;
    let region = js_sys::Float64Array::from(analysis.region.as_slice());
    js_sys::Reflect::set(&object, &"region".into(), &region)
        .map_err(|_| JsError::new("cannot attach the region to the result"))?;
    Ok(object)
}

/// The crate version, for the page's footer.
#[wasm_bindgen]
pub fn version() -> String {
    env!("CARGO_PKG_VERSION").into()
}

use serde::Serialize;
