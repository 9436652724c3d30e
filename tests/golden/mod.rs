//! The golden tiny tracking study shared by the native test (`tests/native/sim.rs`, which writes it
//! with `NMCI_BLESS=1` and checks it otherwise) and the wasm test (`tests/web.rs`, which runs
//! the same configuration in headless Chromium and must match it to 1e-9).
#![allow(dead_code)]

use nmci::sim::{StudyConfig, StudyReport};
use serde::{Deserialize, Serialize};

/// `tests/golden/tiny_study.json`.
pub const TINY_STUDY: &str = include_str!("tiny_study.json");

/// A finished study: its configuration, headline numbers and run-averaged series (flat, as
/// [`nmci::sim::StudyView`] lays them out).
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
