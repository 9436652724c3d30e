//! Native responses of every method, stored (`tests/golden/native_responses.json`) for the
//! browser test to compare the wasm module against (`tests/web.rs`), and checked here against
//! today's native build. `NMCI_BLESS=1` rewrites the file.

use crate::golden;

#[test]
fn native_responses_of_every_method_match_the_fixture() {
    let requests = golden::fixture_requests();
    let fresh: Vec<serde_json::Value> = requests
        .iter()
        .map(|request| {
            let response = nmci::contract::fuse_json(&request.to_string()).unwrap();
            serde_json::json!({
                "request": request,
                "response": serde_json::from_str::<serde_json::Value>(&response).unwrap(),
            })
        })
        .collect();
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/native_responses.json"
    );
    if std::env::var_os("NMCI_BLESS").is_some() {
        std::fs::write(path, serde_json::to_string_pretty(&fresh).unwrap() + "\n").unwrap();
        return;
    }
    let stored: Vec<serde_json::Value> = serde_json::from_str(golden::NATIVE_RESPONSES).unwrap();
    assert_eq!(
        stored.len(),
        requests.len(),
        "re-bless: NMCI_BLESS=1 cargo test"
    );
    // Every method and both two-estimate criteria are in the fixture.
    for rule in nmci::rules::RULES {
        assert!(
            requests.iter().any(|r| r["method"] == rule.name),
            "{}",
            rule.name
        );
    }
    for (f, s) in fresh.iter().zip(&stored) {
        assert_eq!(f["request"], s["request"]);
        golden::same_response(&f["request"], &f["response"], &s["response"]).unwrap();
    }
}

/// The typed response (`FuseResponse`: common fields, `Gains`, the method's `Details`) and the
/// flat JSON object are one-to-one on the response of every fixture request: JSON → typed →
/// JSON gives the same object (the derived fields `guarantee`, `gap`, `gap_relative`
/// recomputed equal), and the typed value has the details of its method.
#[test]
fn every_response_survives_the_typed_round_trip() {
    let mut responses = Vec::new();
    for request in golden::fixture_requests() {
        let text = nmci::contract::fuse_json(&request.to_string()).unwrap();
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        let typed: nmci::contract::FuseResponse =
            serde_json::from_value(json.clone()).unwrap_or_else(|e| panic!("{request}: {e}"));
        assert_eq!(serde_json::to_value(&typed).unwrap(), json, "{request}");
        let nway = request.get("estimates").is_some();
        let kind_matches = match (&typed.details, typed.method) {
            (nmci::contract::Details::Nway { .. }, _) => nway,
            (
                nmci::contract::Details::Omega(_),
                nmci::rules::Method::Ci | nmci::rules::Method::Ici,
            ) => true,
            (nmci::contract::Details::Blocks { .. }, nmci::rules::Method::Nmci) => true,
            (
                nmci::contract::Details::None,
                nmci::rules::Method::Ei | nmci::rules::Method::Naive,
            ) => true,
            (nmci::contract::Details::Sdp(_), nmci::rules::Method::Sdp) => true,
            (nmci::contract::Details::SdpCuts(_), nmci::rules::Method::SdpCuts) => true,
            (nmci::contract::Details::Certified(_), nmci::rules::Method::Certified) => true,
            _ => false,
        };
        assert!(kind_matches, "{request}: {:?}", typed.details);
        responses.push((request, json));
    }
    // A response missing a field its method always has is refused, naming it.
    let (_, sdp) = responses
        .iter()
        .find(|(r, _)| r["method"] == "sdp")
        .unwrap();
    let mut broken = sdp.clone();
    broken.as_object_mut().unwrap().remove("lmis");
    let err = serde_json::from_value::<nmci::contract::FuseResponse>(broken).unwrap_err();
    assert!(err.to_string().contains("missing field `lmis`"), "{err}");
}
