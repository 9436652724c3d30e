//! The wasm module in headless Chromium (`scripts/wasm.sh test`): the exported `fuse` on the
//! paper's example for every method, every method against stored *native* responses
//! (`tests/golden/native_responses.json`) and fig. 2 records (`tests/golden/fig2.json`), and
//! invalid requests throwing with their message, and a share of the native fuzz cases
//! (`tests/common/fuzz.rs`) through the exported `fuse`: never a panic (wasm32 aborts on one,
//! which fails the test), every error a thrown `Error` with a message.
#![cfg(target_arch = "wasm32")]

use js_sys::{Reflect, JSON};
use nmci::{contract::FuseResponse, rules::Method};
use wasm_bindgen::{JsCast, JsValue};
use wasm_bindgen_test::*;

#[path = "common/fuzz.rs"]
mod fuzz;
#[path = "common/memo.rs"]
mod memo;

wasm_bindgen_test_configure!(run_in_browser);

fn request(method: &str) -> JsValue {
    JSON::parse(&format!(
        r#"{{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]],
            "pab_unknown": [[true, false], [false, true]], "method": "{method}", "samples": 100}}"#
    ))
    .unwrap()
}

fn call(req: JsValue) -> Result<FuseResponse, String> {
    call_with_field(req).map_err(|(message, _)| message)
}

/// The response, or the thrown `Error`'s message and `field`.
fn call_with_field(req: JsValue) -> Result<FuseResponse, (String, Option<String>)> {
    match nmci::wasm::fuse(req) {
        Ok(v) => Ok(serde_wasm_bindgen::from_value(v).unwrap()),
        Err(v) => {
            assert!(v.is_instance_of::<js_sys::Error>(), "throws a JS Error");
            let message = Reflect::get(&v, &"message".into())
                .unwrap()
                .as_string()
                .unwrap();
            Err((
                message,
                Reflect::get(&v, &"field".into()).unwrap().as_string(),
            ))
        }
    }
}

#[wasm_bindgen_test]
fn paper_example_ci() {
    let req = JSON::parse(
        r#"{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]],
            "pab_unknown": [[true, false], [false, true]], "method": "ci"}"#,
    )
    .unwrap();
    let r = call(req).unwrap();
    let omega = r.omega().unwrap();
    assert_eq!(omega.len(), 1);
    assert!(omega[0] > 0.0 && omega[0] < 1.0);
    assert!(r.trace > 2.5, "CI ignores the structure: trace {}", r.trace);
}

#[wasm_bindgen_test]
fn paper_example_nmci() {
    let req = JSON::parse(
        r#"{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]],
            "pab_unknown": [[true, false], [false, true]], "method": "nmci"}"#,
    )
    .unwrap();
    let r = call(req).unwrap();
    assert_eq!(r.omega(), Some(vec![0.0, 1.0]));
    assert_eq!(r.p, vec![vec![1.0, 0.0], vec![0.0, 1.0]]);
    assert_eq!(r.blocks(), Some(&vec![vec![0], vec![1]]));
}

#[wasm_bindgen_test]
fn paper_example_sdp() {
    let r = call(request("sdp")).unwrap();
    assert!((r.trace - 2.0).abs() < 1e-6, "trace {}", r.trace);
    let nmci::contract::Details::Sdp(d) = &r.details else {
        panic!("{:?}", r.details)
    };
    assert_eq!(d.samples, 100);
    // The status crosses the boundary as Clarabel's name (a string), and parses back.
    let raw = nmci::wasm::fuse(request("sdp")).unwrap();
    let status = Reflect::get(&raw, &"status".into())
        .unwrap()
        .as_string()
        .expect("status is a string");
    assert!(status == "Solved" || status == "AlmostSolved", "{status}");
    assert_eq!(d.status.as_str(), status);
    assert!(d.iterations > 0);
    assert!(r.omega().is_none());
}

#[wasm_bindgen_test]
fn certified_rule_in_wasm() {
    // One known zero (P_ab[2,1]): nmCI = CI = 3.088; the certified rule proves diag(1, 1)
    // (the comparison with native responses is `every_method_matches_the_stored_…`).
    let body = r#"{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]],
        "pab_unknown": [[true, true], [false, true]], "method": "certified"}"#;
    let r = call(JSON::parse(body).unwrap()).unwrap();
    assert!((r.trace - 2.0).abs() < 1e-6, "trace {}", r.trace);
    assert!(matches!(r.details, nmci::contract::Details::Certified(_)));
    assert!(r.upper_bound().unwrap() >= r.trace);
}

#[wasm_bindgen_test]
fn the_solver_based_rules_do_not_depend_on_the_units_in_wasm() {
    // As natively (`tests/native/scale.rs`), on wasm's KKT solver: the paper's covariances
    // with one known zero in km²-like and 10¹²-sized units give the robust optimum 2 s.
    for (s, method) in [
        (1e-8, "sdp"),
        (1e-8, "certified"),
        (1e12, "sdp"),
        (1e12, "certified"),
    ] {
        let body = format!(
            r#"{{"pa": [[{a}, 0], [0, {s}]], "pb": [[{s}, 0], [0, {b}]],
                "pab_unknown": [[true, true], [false, true]], "method": "{method}"}}"#,
            a = 3.0 * s,
            b = 4.0 * s
        );
        let r = call(JSON::parse(&body).unwrap()).unwrap();
        assert!(
            (r.trace / s - 2.0).abs() < 1e-6,
            "{method}, s {s}: {}",
            r.trace / s
        );
    }
}

#[wasm_bindgen_test]
fn invalid_requests_throw_with_their_message() {
    let not_pd =
        JSON::parse(r#"{"pa": [[1, 2], [2, 1]], "pb": [[1, 0], [0, 4]], "method": "ci"}"#).unwrap();
    let msg = call(not_pd).unwrap_err();
    assert!(msg.contains("P_a is not positive definite"), "{msg}");

    let unknown =
        JSON::parse(r#"{"pa": [[1]], "pb": [[1]], "method": "ci", "colour": 3}"#).unwrap();
    let msg = call(unknown).unwrap_err();
    assert!(msg.contains("unknown field `colour`"), "{msg}");

    let bad_method = JSON::parse(r#"{"pa": [[1]], "pb": [[1]], "method": "magic"}"#).unwrap();
    let msg = call(bad_method).unwrap_err();
    assert!(msg.contains("magic"), "{msg}");

    let mismatch =
        JSON::parse(r#"{"pa": [[1]], "pb": [[1, 0], [0, 1]], "method": "nmci"}"#).unwrap();
    let msg = call(mismatch).unwrap_err();
    assert!(msg.contains("P_b has size 2, expected 1"), "{msg}");
}

/// The thrown `Error` names the request field at fault (`RequestError::field`), which the page
/// places its messages by.
#[wasm_bindgen_test]
fn thrown_errors_carry_the_field() {
    for (json, field) in [
        (
            r#"{"pa": [[1, 2], [2, 1]], "pb": [[1, 0], [0, 4]], "method": "ci"}"#,
            Some("pa"),
        ),
        (
            r#"{"pa": [[1]], "pb": [[1]], "method": "ci", "colour": 3}"#,
            Some("colour"),
        ),
        (
            r#"{"pa": [[1]], "pb": [[1]], "method": "ci", "samples": 3}"#,
            Some("samples"),
        ),
        (
            r#"{"pa": [[1]], "pb": [[1]], "xb": [1, 2], "method": "ci"}"#,
            Some("xb"),
        ),
        (
            r#"{"pa": [[1]], "pb": [[1]], "method": "CI"}"#,
            Some("method"),
        ),
    ] {
        let (_, got) = call_with_field(JSON::parse(json).unwrap()).unwrap_err();
        assert_eq!(got.as_deref(), field, "{json}");
    }
    // A NaN (no JSON form: a null once converted) is named by its path.
    let req =
        JSON::parse(r#"{"pa": [[1, 0], [0, 1]], "pb": [[1, 0], [0, 1]], "method": "ci"}"#).unwrap();
    let xa = js_sys::Array::of2(&JsValue::from_f64(f64::NAN), &JsValue::from_f64(0.0));
    Reflect::set(&req, &"xa".into(), &xa).unwrap();
    let (message, field) = call_with_field(req).unwrap_err();
    assert_eq!(field.as_deref(), Some("xa"));
    assert!(message.contains("`xa[0]` is null"), "{message}");
}

/// The page reads the rules from the registry: `rules()` is `nmci::rules::RULES`, serialised.
#[wasm_bindgen_test]
fn rules_are_the_registry() {
    let rules: serde_json::Value =
        serde_wasm_bindgen::from_value(nmci::wasm::rules().unwrap()).unwrap();
    assert_eq!(rules, serde_json::to_value(nmci::rules::RULES).unwrap());
    let estimators: serde_json::Value =
        serde_wasm_bindgen::from_value(nmci::wasm::study_estimators().unwrap()).unwrap();
    assert_eq!(estimators[0]["name"], "central");
    assert_eq!(
        estimators[1]["colour"],
        nmci::rules::Method::Ci.info().colour
    );
}

#[wasm_bindgen_test]
fn explore_hands_the_region_over_as_a_typed_array() {
    let req = JSON::parse(
        r#"{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]],
            "pab_unknown": [[true, false], [false, true]], "samples": 60, "region_samples": 50}"#,
    )
    .unwrap();
    let out = nmci::wasm::explore(req).unwrap();
    let region = Reflect::get(&out, &"region".into()).unwrap();
    assert!(region.is_instance_of::<js_sys::Float64Array>());
    let region = js_sys::Float64Array::from(region).to_vec();
    assert_eq!(region.len(), 50 * 4);
    let rules: Vec<nmci::explore::RuleReport> =
        serde_wasm_bindgen::from_value(Reflect::get(&out, &"rules".into()).unwrap()).unwrap();
    let nmci = rules.iter().find(|r| r.method == Method::Nmci).unwrap();
    assert_eq!(nmci.response.as_ref().unwrap().trace, 2.0);
    let gap = Reflect::get(&out, &"gap".into()).unwrap();
    let abs = Reflect::get(&gap, &"absolute".into())
        .unwrap()
        .as_f64()
        .unwrap();
    assert!(abs.abs() < 1e-6, "gap {abs}");
    // The gap's flattened certificates arrive as plain properties of a plain object.
    assert!(!gap.is_instance_of::<js_sys::Map>());
    let levels = Reflect::get(&gap, &"levels".into()).unwrap();
    assert!(js_sys::Array::is_array(&levels), "levels {levels:?}");
}

#[path = "golden/mod.rs"]
mod golden;

/// A `Float64Array` property of a view as a `Vec`.
fn series(view: &JsValue, name: &str) -> Vec<f64> {
    let value = Reflect::get(view, &name.into()).unwrap();
    assert!(
        value.is_instance_of::<js_sys::Float64Array>(),
        "{name} is a Float64Array"
    );
    js_sys::Float64Array::from(value).to_vec()
}

#[wasm_bindgen_test]
fn tiny_study_matches_the_native_golden_numbers() {
    let stored: golden::GoldenStudy = serde_json::from_str(golden::TINY_STUDY).unwrap();
    let config = JSON::parse(&serde_json::to_string(&stored.config).unwrap()).unwrap();
    let mut study = nmci::wasm::Study::new(config).unwrap();
    while !study.advance(7).unwrap() {}
    let view = study.view().unwrap();
    let report: nmci::study::StudyReport =
        serde_wasm_bindgen::from_value(Reflect::get(&view, &"report".into()).unwrap()).unwrap();
    golden::within_1e9(
        &golden::headline(&report),
        &golden::headline(&stored.report),
    )
    .unwrap();
    golden::within_1e9(&series(&view, "nees"), &stored.nees).unwrap();
    golden::within_1e9(&series(&view, "rmse"), &stored.rmse).unwrap();
    golden::within_1e9(&series(&view, "two_sigma"), &stored.two_sigma).unwrap();
    golden::within_1e9(&series(&view, "omega"), &stored.omega).unwrap();
    golden::within_1e9(&series(&view, "coin"), &stored.coin).unwrap();
}

/// The page's two run workers through the bindings: the second worker's tails cross as JS
/// objects, and the first's view is that of one worker running every rule, bit for bit.
#[wasm_bindgen_test]
fn a_study_shared_by_two_workers_is_the_one_worker_study_bit_for_bit() {
    let stored: golden::GoldenStudy = serde_json::from_str(golden::TINY_STUDY).unwrap();
    let config = || JSON::parse(&serde_json::to_string(&stored.config).unwrap()).unwrap();
    let mut whole = nmci::wasm::Study::new(config()).unwrap();
    let mut first = nmci::wasm::Study::with_second_worker(config()).unwrap();
    let mut second = nmci::wasm::StudyRules::new(config()).unwrap();
    loop {
        let done = whole.advance(5).unwrap();
        first.advance(5).unwrap();
        while first.waiting() {
            second.advance(5).unwrap();
            first.absorb(second.tail().unwrap()).unwrap();
        }
        let (a, b) = (first.view().unwrap(), whole.view().unwrap());
        for name in ["nees", "rmse", "two_sigma", "omega", "coin"] {
            assert_eq!(series(&a, name), series(&b, name), "{name}");
        }
        let report = |v: &JsValue| -> nmci::study::StudyReport {
            serde_wasm_bindgen::from_value(Reflect::get(v, &"report".into()).unwrap()).unwrap()
        };
        assert_eq!(report(&a), report(&b));
        if done {
            break;
        }
    }
    // A tail that does not continue where the previous ended throws its message.
    let mut again = nmci::wasm::StudyRules::new(config()).unwrap();
    again.advance(5).unwrap();
    let e = JsValue::from(first.absorb(again.tail().unwrap()).unwrap_err());
    let message = Reflect::get(&e, &"message".into()).unwrap().as_string();
    assert_eq!(
        message.as_deref(),
        Some("two-worker study: the second worker's steps start at step 0 but step 12 is next")
    );
}

#[wasm_bindgen_test]
fn invalid_study_configuration_throws_its_message() {
    let config = JSON::parse(r#"{"runs": 0}"#).unwrap();
    let e = JsValue::from(nmci::wasm::Study::new(config).err().unwrap());
    let message = Reflect::get(&e, &"message".into())
        .unwrap()
        .as_string()
        .unwrap();
    assert_eq!(
        message,
        "invalid scenario: steps must be at least 2 and runs at least 1"
    );
    let unknown = JSON::parse(r#"{"stepz": 3}"#).unwrap();
    let e = JsValue::from(nmci::wasm::Study::new(unknown).err().unwrap());
    let message = Reflect::get(&e, &"message".into())
        .unwrap()
        .as_string()
        .unwrap();
    assert!(message.contains("unknown field `stepz`"), "{message}");
}

#[wasm_bindgen_test]
fn every_method_matches_the_stored_native_responses() {
    let stored: Vec<serde_json::Value> = serde_json::from_str(golden::NATIVE_RESPONSES).unwrap();
    assert!(stored.len() >= 15);
    for case in &stored {
        let request = &case["request"];
        let js = nmci::wasm::fuse(JSON::parse(&request.to_string()).unwrap())
            .unwrap_or_else(|e| panic!("{request}: {:?}", e));
        let got: serde_json::Value = serde_wasm_bindgen::from_value(js).unwrap();
        golden::same_response(request, &got, &case["response"]).unwrap();
    }
}

#[wasm_bindgen_test]
fn fig2_matches_the_stored_native_records() {
    let config = golden::fig2_config();
    let stored: Vec<Vec<nmci::fig2::Fig2Record>> = serde_json::from_str(golden::FIG2).unwrap();
    let js_config = JSON::parse(&serde_json::to_string(&config).unwrap()).unwrap();
    let got: Vec<Vec<nmci::fig2::Fig2Record>> = (0..config.runs)
        .map(|run| {
            let js = nmci::wasm::fig2_run(js_config.clone(), run)
                .unwrap_or_else(|e| panic!("run {run}: {:?}", JsValue::from(e)));
            serde_wasm_bindgen::from_value(js).unwrap()
        })
        .collect();
    golden::same_fig2(&got, &stored).unwrap();
}

#[wasm_bindgen_test]
fn fuzz_cases_never_panic_in_wasm() {
    // The first cases of the native fuzz stream that are JSON (a JS caller hands `fuse` an
    // object; text that `JSON.parse` refuses never reaches it).
    let (mut responses, mut errors) = (0, 0);
    for i in 0..150 {
        let text = fuzz::request(fuzz::SEED, i);
        let Ok(js) = JSON::parse(&text) else { continue };
        match call(js) {
            Ok(r) => {
                assert!(r.trace.is_finite(), "case {i}: {text}");
                responses += 1;
            }
            Err(message) => {
                assert!(!message.trim().is_empty(), "case {i}: {text}");
                errors += 1;
            }
        }
    }
    assert!(
        responses > 0 && errors > 0,
        "{responses} responses, {errors} errors"
    );
}

/// The explorer's memo of certified blocks in wasm (the page's worker keeps one): the same
/// analyses as fresh ones, bit for bit, and the expected reuse.
#[wasm_bindgen_test]
fn the_memo_reuses_blocks_certified_before_and_changes_no_number() {
    memo::memo_sequence_matches_fresh_analyses();
}
