//! What a run records ([`RunTrace`]) and its specification ([`RunSpec`]); traces of one
//! run's rules merged; the NEES consistency bounds.

use serde::{Deserialize, Serialize};

use super::estimators::Storage;

/// Per-step results of one run for the headline agent (and the centralized filter).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunTrace {
    /// NEES per step: `central`, then one series per rule in [`STUDY_RULES`](super::estimators::STUDY_RULES) order.
    pub nees: Vec<Vec<f64>>,
    /// Position RMSE over all targets per step, same order.
    pub rmse: Vec<Vec<f64>>,
    /// Mean 2σ of the position coordinates per step, same order.
    pub two_sigma: Vec<Vec<f64>>,
    /// CI's ω when the headline agent fuses the watched neighbour, per step.
    pub omega_ci: Vec<f64>,
    /// nmCI's ω per block (model block order) for that fusion, per step.
    pub omega_nmci: Vec<Vec<f64>>,
    /// ICI's ω for that fusion, per step (`0` keeps the agent's own estimate).
    pub omega_ici: Vec<f64>,
    /// Per series (same order) and target group, the sums over the steps so far of the
    /// group's position RMSE and of its mean 2σ (`[rmse, 2σ]`; divided by the steps, the
    /// per-group means of [`super::EstimatorSummary`]).
    pub group_sums: Vec<Vec<[f64; 2]>>,
}

/// What one run computes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSpec {
    /// Time steps.
    pub steps: usize,
    /// Seed; run `r` uses stream `r` of `ChaCha8Rng::seed_from_u64(seed)`.
    pub seed: u64,
    /// Run index.
    pub run: u64,
    /// Headline agent (0-based).
    pub agent: usize,
    /// The neighbour whose fusion into `agent` is watched for ω (0-based).
    pub watched: usize,
    /// Block or dense storage.
    pub storage: Storage,
}

/// Assembles the per-rule traces of one run (from [`simulate_run_for_rule`](super::simulate_run_for_rule), in [`STUDY_RULES`](super::estimators::STUDY_RULES)
/// order) into the trace [`simulate_run`](super::simulate_run) gives.
pub fn merge_rule_traces(parts: Vec<RunTrace>) -> RunTrace {
    assemble_traces(parts.into_iter().enumerate().map(|(k, t)| (vec![k], t)))
}

/// Assembles traces of one run computed for disjoint sets of rules into one trace. Each part
/// is `(positions, trace)`: the trace's series `1 + i` becomes series `1 + positions[i]` of the
/// result. Series 0, the centralized filter, is the same in every part (its filter does not
/// depend on the rules); the first part's is kept. Each ω series is one rule's and moves as it
/// is. The positions of all parts together must be `0..` without gaps.
pub(super) fn assemble_traces(parts: impl IntoIterator<Item = (Vec<usize>, RunTrace)>) -> RunTrace {
    let mut merged = RunTrace {
        nees: Vec::new(),
        rmse: Vec::new(),
        two_sigma: Vec::new(),
        omega_ci: Vec::new(),
        omega_nmci: Vec::new(),
        omega_ici: Vec::new(),
        group_sums: Vec::new(),
    };
    // Per result series: (nees, rmse, two_sigma, group_sums).
    type Series = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<[f64; 2]>);
    let mut series: Vec<Option<Series>> = Vec::new();
    for (k, (positions, part)) in parts.into_iter().enumerate() {
        let RunTrace {
            nees,
            rmse,
            two_sigma,
            omega_ci,
            omega_nmci,
            omega_ici,
            group_sums,
        } = part;
        let mut all = nees
            .into_iter()
            .zip(rmse)
            .zip(two_sigma)
            .zip(group_sums)
            .map(|(((n, r), t), g)| (n, r, t, g));
        let central = all.next();
        for (&position, one) in positions.iter().zip(all) {
            if series.len() <= position + 1 {
                series.resize_with(position + 2, || None);
            }
            series[position + 1] = Some(one);
        }
        if k == 0 {
            if series.is_empty() {
                series.push(None);
            }
            series[0] = central;
        }
        merged.omega_ci.extend(omega_ci);
        merged.omega_nmci.extend(omega_nmci);
        merged.omega_ici.extend(omega_ici);
    }
    for (n, r, t, g) in series.into_iter().flatten() {
        merged.nees.push(n);
        merged.rmse.push(r);
        merged.two_sigma.push(t);
        merged.group_sums.push(g);
    }
    merged
}

impl RunTrace {
    /// Steps in the trace.
    pub(super) fn steps(&self) -> usize {
        self.nees.first().map_or(0, Vec::len)
    }

    /// The steps from `from` on (each series and ω from there; the group sums, which are
    /// sums over every step so far, as they are).
    pub(super) fn tail(&self, from: usize) -> RunTrace {
        let rows = |v: &[Vec<f64>]| v.iter().map(|s| s[from.min(s.len())..].to_vec()).collect();
        RunTrace {
            nees: rows(&self.nees),
            rmse: rows(&self.rmse),
            two_sigma: rows(&self.two_sigma),
            omega_ci: self.omega_ci[from.min(self.omega_ci.len())..].to_vec(),
            omega_nmci: self.omega_nmci[from.min(self.omega_nmci.len())..].to_vec(),
            omega_ici: self.omega_ici[from.min(self.omega_ici.len())..].to_vec(),
            group_sums: self.group_sums.clone(),
        }
    }

    /// Appends `tail` ([`RunTrace::tail`] of the same run, continuing where this trace ends),
    /// whose group sums replace these.
    pub(super) fn append(&mut self, tail: RunTrace) {
        for (mine, theirs) in [
            (&mut self.nees, tail.nees),
            (&mut self.rmse, tail.rmse),
            (&mut self.two_sigma, tail.two_sigma),
        ] {
            for (s, t) in mine.iter_mut().zip(theirs) {
                s.extend(t);
            }
        }
        self.omega_ci.extend(tail.omega_ci);
        self.omega_nmci.extend(tail.omega_nmci);
        self.omega_ici.extend(tail.omega_ici);
        self.group_sums = tail.group_sums;
    }

    /// The first `steps` steps (a fusion's ω is recorded once per step, as each agent fuses
    /// each neighbour once), the group sums left as they are.
    pub(super) fn truncate(&mut self, steps: usize) {
        for s in self
            .nees
            .iter_mut()
            .chain(&mut self.rmse)
            .chain(&mut self.two_sigma)
        {
            s.truncate(steps);
        }
        self.omega_ci.truncate(steps);
        self.omega_nmci.truncate(steps);
        self.omega_ici.truncate(steps);
    }
}

/// Two-sided 95 % bounds of the mean NEES of `runs` runs for `dof` degrees of freedom
/// (Wilson–Hilferty approximation of the χ² quantiles, relative error < 10⁻³ at these sizes).
pub fn nees_bounds(runs: usize, dof: usize) -> (f64, f64) {
    let k = (runs * dof) as f64;
    let z = 1.959_963_984_540_054;
    let quantile = |z: f64| k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3);
    (quantile(-z) / runs as f64, quantile(z) / runs as f64)
}
