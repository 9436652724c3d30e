//! The JSON field names of a contract type, read from its `Deserialize` implementation.
//!
//! A derived `Deserialize` of a struct hands the list of its field names to
//! `Deserializer::deserialize_struct`; [`field_names`] runs it against a deserializer that
//! keeps that list and stops. So the names are serde's own (renames applied) and there is no
//! second list to keep in step: the Python bridge reads [`response_fields`] for the attributes
//! of its result type and the options' names for its keyword arguments.

use serde::de::{self, Deserialize, Visitor};

/// The field names of `T`, a struct deriving `Deserialize` (directly, or through
/// `#[serde(from/try_from = "Wire")]` of a struct): `None` for any other type.
///
/// ```
/// let names = nmci::contract::field_names::<nmci::contract::Options>().unwrap();
/// assert!(names.contains(&"samples") && names.contains(&"time_limit"));
/// assert_eq!(nmci::contract::field_names::<Vec<f64>>(), None);
/// ```
pub fn field_names<'de, T: Deserialize<'de>>() -> Option<&'static [&'static str]> {
    let mut names = None;
    // The deserializer always refuses, after keeping the names: the result is that error.
    let _ = T::deserialize(Names(&mut names));
    names
}

/// The fields a response ([`super::FuseResponse`]) can carry, in the order of
/// docs/contract.md: each is present exactly where its method reports it.
///
/// ```
/// let fields = nmci::contract::response_fields();
/// assert_eq!(&fields[..4], ["method", "criterion", "x", "p"]);
/// assert!(fields.contains(&"upper_bound_rule") && fields.contains(&"structure"));
/// ```
pub fn response_fields() -> &'static [&'static str] {
    field_names::<super::FuseResponse>().expect("a response is a struct")
}

/// The fields a fusion request ([`super::FuseRequest`]) takes, two-estimate and N-way, in the
/// order of the JSON object a request serialises to: read from a request with every field set
/// (the list the contract's "unknown field" error gives).
///
/// ```
/// let fields = nmci::contract::request_fields();
/// assert!(fields.iter().any(|f| f == "method") && fields.iter().any(|f| f == "coupling_tol"));
/// assert!(fields.iter().any(|f| f == "estimates") && fields.iter().any(|f| f == "samples"));
/// ```
pub fn request_fields() -> Vec<String> {
    match serde_json::to_value(super::FuseRequest::every_field()) {
        Ok(serde_json::Value::Object(map)) => map.keys().cloned().collect(),
        _ => Vec::new(),
    }
}

/// A deserializer that keeps the field names a struct passes it, then fails.
struct Names<'a>(&'a mut Option<&'static [&'static str]>);

#[derive(Debug)]
struct Stop;

impl std::fmt::Display for Stop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("field names read")
    }
}

impl std::error::Error for Stop {}

impl de::Error for Stop {
    fn custom<T: std::fmt::Display>(_: T) -> Self {
        Stop
    }
}

impl<'de> de::Deserializer<'de> for Names<'_> {
    type Error = Stop;

    fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Stop> {
        Err(Stop)
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, Stop> {
        *self.0 = Some(fields);
        Err(Stop)
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
        ignored_any
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::{FuseRequest, Options, PairInput};

    #[test]
    fn the_names_are_serde_s() {
        // Read from `Deserialize`, they are the keys `Serialize` writes for every field set.
        let pair = field_names::<PairInput>().unwrap();
        let written = serde_json::to_value(PairInput::every_field()).unwrap();
        let written: std::collections::BTreeSet<&str> = written
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        assert_eq!(pair.len(), written.len());
        assert!(pair.iter().all(|name| written.contains(name)));
        let options = field_names::<Options>().unwrap();
        // The criterion and one field per method-specific option.
        assert_eq!(
            options.len(),
            1 + crate::fusion::rules::RequestOption::ALL.len()
        );
        // A struct with flattened parts deserialises as a map: no list to read.
        assert_eq!(field_names::<FuseRequest>(), None);
        assert_eq!(field_names::<u32>(), None);
        // A request's fields are its parts' and its own, none twice.
        let request = request_fields();
        let mut expected: Vec<String> = pair.iter().chain(options).map(|s| s.to_string()).collect();
        expected.extend(["method", "estimates", "patterns"].map(String::from));
        let mut sorted = request.clone();
        sorted.sort();
        expected.sort();
        assert_eq!(sorted, expected);
    }

    #[test]
    fn every_field_a_response_writes_is_listed_and_every_listed_one_is_written() {
        use crate::api::{fuse, FuseRequest};
        let fields = response_fields();
        let requests = [
            r#"{"pa":[[3,0],[0,1]],"pb":[[1,0],[0,4]],"method":"ci"}"#,
            r#"{"pa":[[3,0],[0,1]],"pb":[[1,0],[0,4]],"pab_unknown":[[true,false],[false,true]],"method":"nmci"}"#,
            r#"{"pa":[[3,1e-13],[1e-13,1]],"pb":[[1,0],[0,4]],"blocks":[[0],[1]],"method":"certified"}"#,
            r#"{"pa":[[3,0],[0,1]],"pb":[[1,0],[0,4]],"method":"sdp","samples":20,"sampler":"auto"}"#,
            r#"{"pa":[[3,0],[0,1]],"pb":[[1,0],[0,4]],"method":"sdp_cuts"}"#,
            r#"{"estimates":[{"p":[[3,0],[0,1]]},{"p":[[1,0],[0,4]]},{"p":[[2,0],[0,2]]}],"method":"nmci","patterns":[{"i":0,"j":1,"pab_unknown":[[true,false],[false,true]]}]}"#,
        ];
        let mut written = std::collections::BTreeSet::new();
        for text in requests {
            let request: FuseRequest = serde_json::from_str(text).unwrap();
            let response = serde_json::to_value(fuse(&request).unwrap()).unwrap();
            for key in response.as_object().unwrap().keys() {
                assert!(fields.contains(&key.as_str()), "{key} is not listed");
                written.insert(key.clone());
            }
        }
        let listed: std::collections::BTreeSet<String> =
            fields.iter().map(|s| s.to_string()).collect();
        assert_eq!(written, listed);
    }
}
