//! The golden tiny tracking study shared by the native test (`tests/native/sim.rs`, which writes it
//! with `NMCI_BLESS=1` and checks it otherwise) and the wasm test (`tests/web.rs`, which runs
//! the same configuration in headless Chromium and must match it to 1e-9).
#![allow(dead_code)]

use nmci::study::{StudyConfig, StudyReport};
use serde::{Deserialize, Serialize};

/// `tests/golden/tiny_study.json`.
pub const TINY_STUDY: &str = include_str!("tiny_study.json");

/// A finished study: its configuration, headline numbers and run-averaged series (flat, as
/// [`nmci::study::StudyView`] lays them out).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GoldenStudy {
    pub config: StudyConfig,
    pub report: StudyReport,
    pub nees: Vec<f64>,
    pub rmse: Vec<f64>,
    pub two_sigma: Vec<f64>,
    pub omega: Vec<f64>,
    /// Exact COIN per estimator and step (`5 × steps`).
    pub coin: Vec<f64>,
}

/// `|a − b| ≤ 1e-9 · max(|b|, 1)` element by element; the first offending index otherwise.
pub fn within_1e9(a: &[f64], b: &[f64]) -> Result<(), String> {
    if a.len() != b.len() {
        return Err(format!("lengths {} vs {}", a.len(), b.len()));
    }
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        let close = (x - y).abs() <= 1e-9 * y.abs().max(1.0); // false for NaN
        if !close {
            return Err(format!("index {i}: {x} vs {y}"));
        }
    }
    Ok(())
}

/// The headline numbers of a report as one vector (for [`within_1e9`]).
pub fn headline(r: &StudyReport) -> Vec<f64> {
    let mut v = Vec::new();
    for e in [&r.central, &r.ci, &r.nmci, &r.naive, &r.ici] {
        v.extend([
            e.rmse_mean,
            e.two_sigma_mean,
            e.nees_mean,
            e.nees_frac_above_upper,
        ]);
        v.extend(e.coin_mean.iter().chain(&e.coin_max));
    }
    v.extend(r.nees_bounds);
    v.push(r.omega_7_11.ci);
    v.extend(&r.omega_7_11.nmci);
    v.push(r.omega_7_11.ici);
    v
}

/// `tests/golden/native_responses.json`: `[{"request": …, "response": …}, …]`, native
/// responses of every method, written by the native test with `NMCI_BLESS=1`.
pub const NATIVE_RESPONSES: &str = include_str!("native_responses.json");

/// The requests of the fixture: every method, on 3-D problems with known zeros (and N-way).
pub fn fixture_requests() -> Vec<serde_json::Value> {
    let pa = serde_json::json!([[3.0, 0.4, -0.2], [0.4, 1.5, 0.3], [-0.2, 0.3, 2.0]]);
    let pb = serde_json::json!([[1.2, -0.3, 0.1], [-0.3, 2.5, 0.0], [0.1, 0.0, 0.8]]);
    let pattern = serde_json::json!([
        [true, false, true],
        [false, true, false],
        [true, false, true]
    ]);
    let chain = serde_json::json!([
        [true, true, false],
        [false, true, true],
        [false, false, true]
    ]);
    let two = |method: &str, pattern: &serde_json::Value, extra: serde_json::Value| {
        let mut r = serde_json::json!({
            "pa": pa, "pb": pb, "xa": [1.0, -0.5, 0.25], "xb": [0.5, 0.5, -1.0],
            "pab_unknown": pattern, "method": method,
        });
        for (k, v) in extra.as_object().unwrap() {
            r[k] = v.clone();
        }
        r
    };
    let none = serde_json::json!({});
    let mut out = Vec::new();
    for method in ["ci", "nmci", "ici", "ei", "naive"] {
        out.push(two(method, &pattern, none.clone()));
        // Log-det where the method has a weight to choose; the other pattern otherwise.
        let logdet = if matches!(method, "ei" | "naive") {
            none.clone()
        } else {
            serde_json::json!({"criterion": "logdet"})
        };
        out.push(two(method, &chain, logdet));
    }
    out.push(two(
        "sdp",
        &pattern,
        serde_json::json!({"samples": 100, "seed": 2}),
    ));
    // The sampler chosen by a pilot (here the rejection sampler): the same choice and the same
    // samples on both targets.
    out.push(two(
        "sdp",
        &chain,
        serde_json::json!({"samples": 60, "seed": 4, "sampler": "auto"}),
    ));
    out.push(two("sdp_cuts", &chain, none.clone()));
    out.push(two("certified", &chain, none.clone()));
    let estimates = serde_json::json!([
        {"x": [1.0, 0.0, 0.5], "p": [[1.0, 0.0, 0.0], [0.0, 9.0, 0.0], [0.0, 0.0, 2.0]]},
        {"x": [0.0, 1.0, -0.5], "p": [[9.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 3.0]]},
        {"p": [[4.0, 0.5, 0.0], [0.5, 4.0, 0.0], [0.0, 0.0, 1.5]]}
    ]);
    out.push(serde_json::json!({"estimates": estimates, "method": "ci"}));
    out.push(serde_json::json!({"estimates": estimates, "method": "nmci", "patterns": [
        {"i": 0, "j": 1, "pab_unknown": [[true, true, false], [true, true, false], [false, false, true]]},
        {"i": 0, "j": 2, "pab_unknown": [[true, true, false], [true, true, false], [false, false, true]]},
        {"i": 1, "j": 2, "pab_unknown": [[true, true, false], [true, true, false], [false, false, true]]}
    ]}));
    out
}

/// The methods solved by an interior-point SDP (native uses faer's KKT solver, wasm QDLDL):
/// compared at solver tolerance on the keys that carry the result. Their optimal gain need
/// not be unique (the trace is; `sdp_cuts`' `x` differed by 8e-5 between the two builds), so
/// `x`, `p`, `ka`, `kb` are not compared for them.
const SOLVER_METHODS: [&str; 3] = ["sdp", "sdp_cuts", "certified"];
/// The sampler's bookkeeping (`acceptance_rate`, `sampler_choice`) is compared too: the samples
/// are the same on both targets.
const SOLVER_KEYS: [&str; 6] = [
    "method",
    "trace",
    "upper_bound",
    "blocks",
    "acceptance_rate",
    "sampler_choice",
];

/// Compares a response with the stored one: every key (for solver methods the keys of
/// `SOLVER_KEYS`), numbers to `1e-9` relative (`1e-6` for solver methods), the rest equal.
pub fn same_response(
    request: &serde_json::Value,
    got: &serde_json::Value,
    stored: &serde_json::Value,
) -> Result<(), String> {
    let method = request["method"].as_str().unwrap_or_default();
    let solver = SOLVER_METHODS.contains(&method);
    let tol = if solver { 1e-6 } else { 1e-9 };
    let keys: Vec<String> = if solver {
        SOLVER_KEYS.iter().map(|k| k.to_string()).collect()
    } else {
        let mut k: Vec<String> = stored.as_object().unwrap().keys().cloned().collect();
        k.extend(got.as_object().unwrap().keys().cloned());
        k.sort();
        k.dedup();
        k
    };
    for key in keys {
        close(&got[&key], &stored[&key], tol).map_err(|e| format!("{method}: `{key}`: {e}"))?;
    }
    Ok(())
}

fn close(a: &serde_json::Value, b: &serde_json::Value, tol: f64) -> Result<(), String> {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            if (x - y).abs() <= tol * x.abs().max(y.abs()).max(1.0) {
                Ok(())
            } else {
                Err(format!("{x} vs {y}"))
            }
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => {
            x.iter().zip(y).try_for_each(|(x, y)| close(x, y, tol))
        }
        _ if a == b => Ok(()),
        _ => Err(format!("{a} vs {b}")),
    }
}

/// `tests/golden/fig2.json`: the native records of [`fig2_config`]'s runs (one list per run),
/// written by the native test with `NMCI_BLESS=1`.
pub const FIG2: &str = include_str!("fig2.json");

/// A small fig. 2 study: 4 runs at N = 1, 10, 100.
pub fn fig2_config() -> nmci::fig2::Fig2Config {
    nmci::fig2::Fig2Config {
        runs: 4,
        sizes: vec![1, 10, 100],
        seed: 11,
    }
}

/// Compares fig. 2 records with the stored ones: sizes and failures equal, nmCI's numbers
/// (closed form) to `1e-9` relative, the SDP's (`deviation`, `eig_opt`, `coin_opt`) to the
/// solver's tolerance, `1e-6` (absolute below 1).
pub fn same_fig2(
    got: &[Vec<nmci::fig2::Fig2Record>],
    stored: &[Vec<nmci::fig2::Fig2Record>],
) -> Result<(), String> {
    let near = |a: f64, b: f64, tol: f64| (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0);
    let near_opt = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) => near(a, b, 1e-6),
        (None, None) => true,
        _ => false,
    };
    if got.len() != stored.len() {
        return Err(format!("{} runs vs {}", got.len(), stored.len()));
    }
    for (run, (g, s)) in got.iter().zip(stored).enumerate() {
        if g.len() != s.len() {
            return Err(format!("run {run}: {} records vs {}", g.len(), s.len()));
        }
        for (g, s) in g.iter().zip(s) {
            let ok = g.samples == s.samples
                && g.failure == s.failure
                && near(g.eig_nmci, s.eig_nmci, 1e-9)
                && near(g.coin_nmci, s.coin_nmci, 1e-9)
                && near_opt(g.deviation, s.deviation)
                && near_opt(g.eig_opt, s.eig_opt)
                && near_opt(g.coin_opt, s.coin_opt);
            if !ok {
                return Err(format!("run {run}, N = {}: {g:?} vs {s:?}", s.samples));
            }
        }
    }
    Ok(())
}
