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
            let response = nmci::fuse_json(&request.to_string()).unwrap();
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
    for rule in nmci::RULES {
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
