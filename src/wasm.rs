//! The wasm-bindgen bindings: a thin layer over [`crate::fuse`] and [`crate::explore`].
//! No logic lives here.

use serde::de::DeserializeOwned;
use serde::Serialize;
use wasm_bindgen::prelude::*;

use crate::api::FuseRequest;
use crate::ExploreRequest;

/// A request object, parsed exactly as the CLI parses JSON: through a `serde_json::Value`,
/// because serde-wasm-bindgen alone skips unknown fields instead of rejecting them.
fn parse<T: DeserializeOwned>(request: JsValue) -> Result<T, JsError> {
    let value: serde_json::Value = serde_wasm_bindgen::from_value(request)
        .map_err(|e| JsError::new(&format!("invalid request: {e}")))?;
    serde_json::from_value(value).map_err(|e| JsError::new(&format!("invalid request: {e}")))
}

/// A response as a plain JS object (absent optional fields are left out, not `null`).
fn to_js<T: Serialize>(value: &T) -> Result<JsValue, JsError> {
    let serializer = serde_wasm_bindgen::Serializer::new().serialize_missing_as_null(false);
    Ok(value.serialize(&serializer)?)
}

/// Runs a fusion request (the same object as `nmci fuse` reads) and returns the response
/// object; throws an `Error` carrying the message of any invalid input.
#[wasm_bindgen]
pub fn fuse(request: JsValue) -> Result<JsValue, JsError> {
    let request: FuseRequest = parse(request)?;
    to_js(&crate::api::fuse(&request)?)
}

/// Analyses one explorer state (see [`crate::ExploreRequest`]): CI, nmCI, the sampled-SDP
/// bound, the gap, the region of possible true fused covariances and each rule's worst
/// conservativeness margin. The region crosses as a `Float64Array` in `region`
/// (`region_count` row-major `n × n` matrices).
#[wasm_bindgen]
pub fn explore(request: JsValue) -> Result<JsValue, JsError> {
    let request: ExploreRequest = parse(request)?;
    let analysis = crate::explore(&request)?;
    let object = to_js(&analysis)?;
    let region = js_sys::Float64Array::from(analysis.region.as_slice());
    js_sys::Reflect::set(&object, &"region".into(), &region)
        .map_err(|_| JsError::new("cannot attach the region to the result"))?;
    Ok(object)
}

/// The crate version.
#[wasm_bindgen]
pub fn version() -> String {
    env!("CARGO_PKG_VERSION").into()
}
