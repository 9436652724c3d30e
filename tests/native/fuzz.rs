//! Fuzzing the JSON contract (`fuse_json`, what the CLI, the page and Python's `fuse` run) with
//! the structure-aware generator of `tests/common/fuzz.rs`: every case must end in a response
//! or a typed error with a message — never a panic — and a response must be a finite bound.
//!
//! The test command runs `NMCI_FUZZ_CASES` cases (default 1000);
//! `scripts/fuzz.sh` runs 100 000 (release build). A failing case prints its index; rerun it
//! with `NMCI_FUZZ_FIRST=i NMCI_FUZZ_CASES=1`.

use std::panic::{catch_unwind, AssertUnwindSafe};

use nmci::{contract::fuse_json, RequestError};

use crate::common::fuzz;

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .map(|v| {
            v.parse()
                .unwrap_or_else(|_| panic!("{name} must be a number"))
        })
        .unwrap_or(default)
}

/// What one case ended in.
#[derive(Debug, Default)]
struct Tally {
    responses: u64,
    malformed: u64,
    invalid: u64,
    input: u64,
    solve: u64,
    sample: u64,
}

#[test]
fn fuse_json_never_panics_and_every_error_is_typed() {
    let first = env_u64("NMCI_FUZZ_FIRST", 0);
    let cases = env_u64("NMCI_FUZZ_CASES", 1000);
    // A panic inside a case is caught and reported with its case; silence the default hook's
    // backtrace print for those (restored after).
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut tally = Tally::default();
    let mut panics = Vec::new();
    for i in first..first + cases {
        let text = fuzz::request(fuzz::SEED, i);
        match catch_unwind(AssertUnwindSafe(|| fuse_json(&text))) {
            Err(payload) => {
                let message = payload
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                panics.push(format!("case {i}: {message}\n  request: {text}"));
            }
            Ok(Ok(response)) => {
                tally.responses += 1;
                let v: serde_json::Value = serde_json::from_str(&response)
                    .unwrap_or_else(|e| panic!("case {i}: the response is not JSON ({e})"));
                let trace = v["trace"].as_f64();
                assert!(
                    trace.is_some_and(f64::is_finite),
                    "case {i}: trace {trace:?}\n  request: {text}"
                );
                for row in v["p"].as_array().expect("p") {
                    for e in row.as_array().expect("a row") {
                        assert!(
                            e.as_f64().is_some_and(f64::is_finite),
                            "case {i}: P has {e}\n  request: {text}"
                        );
                    }
                }
            }
            Ok(Err(e)) => {
                assert!(
                    !e.to_string().trim().is_empty(),
                    "case {i}: an empty message"
                );
                match e {
                    RequestError::Malformed(_) | RequestError::TooLarge { .. } => {
                        tally.malformed += 1
                    }
                    RequestError::Invalid { ref field, .. } => {
                        assert!(!field.is_empty(), "case {i}: {e} names no field");
                        tally.invalid += 1
                    }
                    RequestError::Input(_) => tally.input += 1,
                    RequestError::Solve(_) => tally.solve += 1,
                    RequestError::Sample(_) => tally.sample += 1,
                    // A text that is a JSON array is a list of requests.
                    RequestError::InList { .. } => tally.malformed += 1,
                    RequestError::InStack { .. } => {
                        panic!("case {i}: a stack's error from one request: {e}")
                    }
                }
            }
        }
    }
    std::panic::set_hook(hook);
    eprintln!("fuzz cases {first}..{}: {tally:?}", first + cases);
    assert!(
        panics.is_empty(),
        "{} of {cases} cases panicked:\n{}",
        panics.len(),
        panics.join("\n")
    );
    // The generator reaches every outcome (a fuzz that only hits the parser tests nothing).
    if cases >= 1000 {
        assert!(tally.responses >= cases / 50, "{tally:?}");
        assert!(
            tally.malformed > 0 && tally.invalid > 0 && tally.input > 0,
            "{tally:?}"
        );
    }
}
