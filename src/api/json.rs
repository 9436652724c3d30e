//! Reading a request from JSON so that its errors speak of the request, not of the text.
//!
//! A request reaches the contract as JSON text (CLI, Python's `fuse`) or as a JS object turned
//! into a `serde_json::Value` (the wasm layer). Read straight from text, serde's data errors
//! end in "at line 1 column 63" of a text the Python or JS user never wrote, name internal
//! types ("expected struct FuseRequestWire") and say "invalid type: null, expected f64" for the
//! NaN that `JSON.stringify` writes as `null`, without saying where. So the text is parsed to
//! a `Value` first (a text that is not JSON keeps serde's line and column: that text is the
//! user's), then [`check_value`] names what it can before serde sees it:
//! - a request that is not a JSON object: what it is instead;
//! - a `null` inside an array (a matrix, a vector, a pattern): its path, `xa[0]` or
//!   `estimates[1].p[0][1]`, and that NaN and ±∞ have no JSON form;
//! - a `method` that is no rule's name: the names, and the lower-case one when it differs
//!   only in case.
//!
//! What remains is read by serde from the `Value` (no positions).

use serde::de::DeserializeOwned;
use serde_json::Value;

use crate::error::RequestError;
use crate::fusion::rules::{rules, Method};

/// The first `null` inside an array of `value`, as a path below `at` (`xa[0]`).
fn null_in_array(value: &Value, at: &str, inside: bool) -> Option<String> {
    match value {
        Value::Null if inside => Some(at.to_string()),
        Value::Array(items) => items
            .iter()
            .enumerate()
            .find_map(|(i, v)| null_in_array(v, &format!("{at}[{i}]"), true)),
        Value::Object(map) => map.iter().find_map(|(k, v)| {
            let path = if at.is_empty() {
                k.clone()
            } else {
                format!("{at}.{k}")
            };
            null_in_array(v, &path, false)
        }),
        _ => None,
    }
}

/// What a JSON value is, for a message (`an array`, `a number`).
fn kind(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// The field a path belongs to, for [`RequestError::field`]: the path without its trailing
/// indices (`xa[0]` → `xa`, `estimates[1].p[0][1]` → `estimates[1].p`).
fn field_of(path: &str) -> String {
    let mut field = path;
    while let Some(stripped) = field.strip_suffix(']') {
        match stripped.rfind('[') {
            Some(i) => field = &stripped[..i],
            None => break,
        }
    }
    field.to_string()
}

/// The errors of the module docs' list, named, before serde reads `value`; `what` is the kind
/// of object expected (`a request`).
pub(crate) fn check_value(value: &Value, what: &str) -> Result<(), RequestError> {
    let Value::Object(map) = value else {
        return Err(RequestError::Malformed(format!(
            "{what} is a JSON object (got {})",
            kind(value)
        )));
    };
    if let Some(path) = null_in_array(value, "", false) {
        return Err(RequestError::invalid(
            field_of(&path),
            format!("`{path}` is null where a number goes (NaN and ±∞ have no JSON form: JSON.stringify and json.dumps write them as null or NaN)"),
        ));
    }
    if let Some(Value::String(name)) = map.get("method") {
        if Method::from_name(name).is_none() {
            let names: Vec<&str> = rules().iter().map(|r| r.method.name()).collect();
            let hint = Method::from_name(&name.to_lowercase())
                .map(|m| format!(" (names are lower case: `{}`)", m.name()))
                .unwrap_or_default();
            return Err(RequestError::invalid(
                "method",
                format!(
                    "`method`: unknown method `{name}`{hint}; the methods are {}",
                    names.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

/// `value` read as a `T` after [`check_value`]; serde's remaining errors as
/// [`RequestError::Malformed`] (from a `Value`: no positions).
pub(crate) fn from_value<T: DeserializeOwned>(value: Value, what: &str) -> Result<T, RequestError> {
    check_value(&value, what)?;
    serde_json::from_value(value).map_err(|e| RequestError::Malformed(e.to_string()))
}

/// JSON text parsed to a `Value` (a text that is not JSON: serde's message, with its line and
/// column in the text).
pub(crate) fn parse_text(text: &str) -> Result<Value, RequestError> {
    serde_json::from_str(text).map_err(|e| RequestError::Malformed(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::FuseRequest;

    fn read(text: &str) -> RequestError {
        from_value::<FuseRequest>(parse_text(text).unwrap(), "a request").unwrap_err()
    }

    #[test]
    fn errors_name_the_field_and_no_text_position() {
        let e = read(r#"{"pa": [[1,0],[0,1]], "pb": [[1,0],[0,1]], "xa": [null, 0]}"#);
        assert_eq!(e.field().as_deref(), Some("xa"));
        assert!(e.to_string().contains("`xa[0]` is null"), "{e}");
        let e = read(r#"{"estimates": [{"p": [[1]]}, {"p": [[1, null]]}], "method": "ci"}"#);
        assert_eq!(e.field().as_deref(), Some("estimates[1].p"));
        assert!(e.to_string().contains("`estimates[1].p[0][1]`"), "{e}");
        let e = read(r#"{"pa": [[1]], "pb": [[1]], "method": "CI"}"#);
        assert_eq!(e.field().as_deref(), Some("method"));
        assert!(
            e.to_string().contains("(names are lower case: `ci`)"),
            "{e}"
        );
        assert!(e.to_string().contains("ci, nmci"), "{e}");
        let e = read("[1, 2]");
        assert_eq!(
            e.to_string(),
            "invalid request: a request is a JSON object (got an array)"
        );
        // serde's own errors: from the Value, so no line and column, no internal type.
        let e = read(r#"{"pa": [[1]], "pb": [[1]], "samples": "many", "method": "sdp"}"#);
        let text = e.to_string();
        assert!(!text.contains("line") && !text.contains("Wire"), "{text}");
        // Text that is not JSON keeps its position: that text is the user's.
        let e = parse_text(r#"{"pa": [[NaN]]}"#).unwrap_err();
        assert!(e.to_string().contains("line 1 column"), "{e}");
    }
}
