//! Monte Carlo runs of the tracking study: truth, measurements, the centralized Kalman
//! filter and the decentralized agents fusing with CI, nmCI, naive fusion or ICI.
//!
//! Every estimate is kept in *storage blocks*: with [`Storage::Blocks`] one `(x, P)` per
//! independent block of the model (8 of 14 states by default), with [`Storage::Dense`] a
//! single `112 × 112` block. The dense run uses the generic dense rules
//! ([`covariance_intersection`], [`non_monolithic_ci`] with the model's cross pattern,
//! [`naive_fusion`]); the block run uses their block forms. Both give the same numbers
//! (tested to 1e-9): the structure is a fact of the model, not an assumption of the code.

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::model::Model;
use super::SimError;
use crate::fusion::ci::{ci_in_place, covariance_intersection, nmci_in_place};
use crate::fusion::ici::{ici_in_place, inverse_covariance_intersection};
use crate::fusion::known::{naive_fusion, naive_in_place};
use crate::fusion::nmci::non_monolithic_ci;
use crate::fusion::rules::{Guarantee, Method};
use crate::fusion::{Criterion, FusionProblem, MeanPlan};
use crate::linalg::{cholesky, symmetrize_in_place};

/// The decentralized fusion rules of the study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StudyRule {
    /// Monolithic CI (one ω).
    Ci,
    /// Non-monolithic CI (one ω per independent block).
    Nmci,
    /// Naive fusion as if independent.
    Naive,
    /// Inverse covariance intersection (one ω): conservative for common-information
    /// correlation only (not the paper's; issue 6).
    Ici,
}

/// The rules, in report order (series `1..` of a [`RunTrace`]; series 0 is the centralized
/// filter).
pub const STUDY_RULES: [StudyRule; 4] = [
    StudyRule::Ci,
    StudyRule::Nmci,
    StudyRule::Naive,
    StudyRule::Ici,
];

impl StudyRule {
    /// The rule in the registry of rules ([`crate::rules::RULES`]: name, label, colour, guarantee).
    pub fn method(self) -> Method {
        match self {
            StudyRule::Ci => Method::Ci,
            StudyRule::Nmci => Method::Nmci,
            StudyRule::Naive => Method::Naive,
            StudyRule::Ici => Method::Ici,
        }
    }

    /// The name used in reports (`ci`, `nmci`, `naive`, `ici`: [`Method::name`]).
    pub fn name(self) -> &'static str {
        self.method().name()
    }
}

/// An estimator of the study: the centralized Kalman filter (every measurement) or a
/// decentralized fusion rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    /// The centralized Kalman filter.
    Central,
    /// The agents' filters fusing with a rule.
    Decentralized(StudyRule),
}

impl Estimator {
    /// The rule, for the decentralized estimators.
    pub fn rule(self) -> Option<StudyRule> {
        match self {
            Estimator::Central => None,
            Estimator::Decentralized(rule) => Some(rule),
        }
    }

    /// The name used in reports and CSV columns (`central`, then the rules' names).
    pub fn name(self) -> &'static str {
        self.rule().map_or("central", StudyRule::name)
    }

    /// The label in charts and tables (`centralized KF`, then the rules' legends).
    pub fn label(self) -> String {
        self.rule()
            .map_or(self.short_label().into(), |r| r.method().info().legend())
    }

    /// The short label, without the guarantee's phrase (`centralized KF`, `ICI`).
    pub fn short_label(self) -> &'static str {
        self.rule().map_or("centralized KF", |r| r.method().label())
    }

    /// The colour in charts (the rules' colours from the registry).
    pub fn colour(self) -> &'static str {
        self.rule().map_or("#1d1f21", |r| r.method().info().colour)
    }

    /// Whether the study's charts draw it: all but the rules guaranteed nothing (naive
    /// fusion's NEES and COIN grow by orders of magnitude; the CSV files have them).
    pub fn charted(self) -> bool {
        self.rule()
            .is_none_or(|r| r.method().guarantee() != Guarantee::None)
    }
}

impl Serialize for Estimator {
    /// `{name, label, short_label, colour, charted}` (what the page's study tab draws with).
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut s = serializer.serialize_struct("Estimator", 5)?;
        s.serialize_field("name", self.name())?;
        s.serialize_field("label", &self.label())?;
        s.serialize_field("short_label", self.short_label())?;
        s.serialize_field("colour", self.colour())?;
        s.serialize_field("charted", &self.charted())?;
        s.end()
    }
}

/// How estimates are stored and fused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Storage {
    /// One `(x, P)` per independent block of the model.
    Blocks,
    /// One dense `(x, P)` for the whole state.
    Dense,
}

/// The covariance side of a filter state stored in blocks: one covariance per storage block.
/// Kalman and fusion covariances do not depend on the data, so the runs of a study share it
/// ([`RunBatch`]); each run keeps only its means ([`BlockMeans`]).
pub(super) type BlockCovariance = Vec<DMatrix<f64>>;

/// The mean side of a filter state stored in blocks: one mean per storage block.
pub(super) type BlockMeans = Vec<DVector<f64>>;

/// One scalar measurement in block coordinates: `(block, local sparse row, noise variance)`.
pub(super) type LocalMeasurement = (usize, Vec<(usize, f64)>, f64);

/// Per-block restrictions of the model.
#[allow(non_snake_case)]
pub(super) struct Partition {
    pub(super) blocks: Vec<Vec<usize>>,
    /// The non-zeros of each block's transition matrix, row by row: `F[k][i] = [(j, F_ij)]`
    /// (at most two per row for nearly-constant-velocity targets and constant biases, so the
    /// prediction `F P Fᵀ` is O(n²) instead of two dense products).
    pub(super) F: Vec<Vec<Vec<(usize, f64)>>>,
    pub(super) Q: Vec<DMatrix<f64>>,
    /// For each agent: `(block, local row, variance)` per scalar measurement.
    pub(super) measurements: Vec<Vec<LocalMeasurement>>,
    /// Local indices of the target position coordinates in each block.
    positions: Vec<Vec<usize>>,
    /// The target group (`target / targets_per_group`) of each of those coordinates.
    position_groups: Vec<Vec<usize>>,
}

#[allow(non_snake_case)]
impl Partition {
    pub(super) fn new(model: &Model, storage: Storage) -> Self {
        let blocks = match storage {
            Storage::Blocks => model.blocks.clone(),
            Storage::Dense => vec![(0..model.dim()).collect()],
        };
        let mut where_ = vec![(0, 0); model.dim()];
        for (b, block) in blocks.iter().enumerate() {
            for (k, &i) in block.iter().enumerate() {
                where_[i] = (b, k);
            }
        }
        let restrict = |m: &DMatrix<f64>, b: &[usize]| {
            DMatrix::from_fn(b.len(), b.len(), |i, j| m[(b[i], b[j])])
        };
        let measurements = model
            .measurements
            .iter()
            .map(|ms| {
                ms.iter()
                    .map(|m| {
                        let block = where_[m.row[0].0].0;
                        let local = m.row.iter().map(|&(i, c)| (where_[i].1, c)).collect();
                        (block, local, m.variance)
                    })
                    .collect()
            })
            .collect();
        let sc = &model.scenario;
        let is_position: Vec<bool> = (0..model.dim())
            .map(|i| i < 4 * sc.targets() && i % 2 == 0)
            .collect();
        let positions: Vec<Vec<usize>> = blocks
            .iter()
            .map(|b| (0..b.len()).filter(|&k| is_position[b[k]]).collect())
            .collect();
        let position_groups = blocks
            .iter()
            .zip(&positions)
            .map(|(b, p)| p.iter().map(|&k| b[k] / 4 / sc.targets_per_group).collect())
            .collect();
        Self {
            positions,
            position_groups,
            F: blocks
                .iter()
                .map(|b| {
                    let f = restrict(&model.F, b);
                    (0..b.len())
                        .map(|i| {
                            (0..b.len())
                                .filter(|&j| f[(i, j)] != 0.0)
                                .map(|j| (j, f[(i, j)]))
                                .collect()
                        })
                        .collect()
                })
                .collect(),
            Q: blocks.iter().map(|b| restrict(&model.Q, b)).collect(),
            measurements,
            blocks,
        }
    }

    /// The common prior's covariance, block by block (its mean is zero).
    pub(super) fn prior(&self, model: &Model) -> BlockCovariance {
        self.blocks
            .iter()
            .map(|b| DMatrix::from_fn(b.len(), b.len(), |i, j| model.P0[(b[i], b[j])]))
            .collect()
    }

    /// The common prior's mean (zero), block by block.
    fn prior_mean(&self) -> BlockMeans {
        self.blocks
            .iter()
            .map(|b| DVector::zeros(b.len()))
            .collect()
    }

    /// The mean 2σ of the position coordinates: `2·√(mean of P_ii)` over every target's `x`
    /// and `y` (blocks in order, positions in order within a block). Depends on `P` only.
    pub(super) fn two_sigma(&self, e: &[DMatrix<f64>]) -> f64 {
        let mut var = 0.0;
        let mut count = 0usize;
        for (k, P) in e.iter().enumerate() {
            for &i in &self.positions[k] {
                var += P[(i, i)];
                count += 1;
            }
        }
        2.0 * (var / count as f64).sqrt()
    }

    /// `P ← F P Fᵀ + Q` block by block, with the sparse rows of `F`.
    pub(super) fn predict(&self, e: &mut [DMatrix<f64>]) {
        for (k, P) in e.iter_mut().enumerate() {
            let F = &self.F[k];
            let n = P.nrows();
            // FP = F P (row i of FP combines the rows of P that row i of F names) …
            let mut FP = DMatrix::<f64>::zeros(n, n);
            for (i, row) in F.iter().enumerate() {
                for &(l, f) in row {
                    for j in 0..n {
                        FP[(i, j)] += f * P[(l, j)];
                    }
                }
            }
            // … then P = FP Fᵀ + Q (column j of the result combines the columns of FP that row
            // j of F names).
            let mut next = self.Q[k].clone();
            for (j, row) in F.iter().enumerate() {
                for &(l, f) in row {
                    for i in 0..n {
                        next[(i, j)] += f * FP[(i, l)];
                    }
                }
            }
            *P = next;
        }
    }

    /// `x ← F x` block by block (the mean side of [`Partition::predict`]).
    fn predict_mean(&self, x: &mut [DVector<f64>]) {
        for (k, g) in x.iter_mut().enumerate() {
            let F = &self.F[k];
            *g = DVector::from_fn(g.len(), |i, _| F[i].iter().map(|&(j, f)| f * g[j]).sum());
        }
    }

    /// Joseph-form scalar update of the covariance with agent `a`'s measurement `m`:
    /// `P ← (I − K hᵀ) P (I − K hᵀ)ᵀ + r K Kᵀ`, evaluated exactly through its rank-one factors
    /// (`(I − K hᵀ) P = P − K (P h)ᵀ`, then `Y (I − h Kᵀ) = Y − (Y h) Kᵀ`): O(n²) instead of
    /// two dense products. Returns the gain `K` (of the measurement's block), which the means
    /// take ([`Partition::update_mean`]) and the exact COIN propagation applies to the joint
    /// error covariance.
    pub(super) fn update(&self, e: &mut [DMatrix<f64>], a: usize, m: usize) -> DVector<f64> {
        let (b, row, r) = &self.measurements[a][m];
        let P = &mut e[*b];
        let sparse_dot = |v: &DMatrix<f64>, col: usize| -> f64 {
            row.iter().map(|&(i, c)| c * v[(col, i)]).sum()
        };
        let n = P.nrows();
        // P h (P symmetric: row `i` of P dotted with h).
        let Ph = DVector::from_fn(n, |i, _| sparse_dot(P, i));
        let s = row.iter().map(|&(i, c)| c * Ph[i]).sum::<f64>() + r;
        let K = Ph.unscale(s);
        P.ger(-1.0, &K, &Ph, 1.0); // Y = (I − K hᵀ) P
        let Yh = DVector::from_fn(n, |i, _| sparse_dot(P, i));
        P.ger(-1.0, &Yh, &K, 1.0); // Y (I − h Kᵀ)
        P.ger(*r, &K, &K, 1.0);
        symmetrize_in_place(P);
        K
    }

    /// The mean side of [`Partition::update`]: `x ← x + K (z − hᵀx)` with its gain `K`.
    fn update_mean(&self, x: &mut [DVector<f64>], a: usize, m: usize, z: f64, K: &DVector<f64>) {
        let (b, row, _) = &self.measurements[a][m];
        let x = &mut x[*b];
        let innovation = z - row.iter().map(|&(i, c)| c * x[i]).sum::<f64>();
        x.axpy(innovation, K, 1.0);
    }
}

/// The study's exchange schedule, in one place (the Monte Carlo runs, the exact COIN and the
/// covariance-only sweep all call it, so a change of schedule cannot make them drift): every
/// agent sends a copy of its current estimate (after its own prediction and update) to all
/// its neighbours at once; then each agent, in ascending id, fuses what it received one
/// neighbour at a time, in ascending neighbour id: `fuse_one(a, b, estimate of a, copy sent
/// by b)`. `sent` is a reused buffer.
pub(super) fn exchange<E: Clone>(
    agents: &mut [E],
    sent: &mut Vec<E>,
    neighbours: &[Vec<usize>],
    mut fuse_one: impl FnMut(usize, usize, &mut E, &E) -> Result<(), SimError>,
) -> Result<(), SimError> {
    sent.truncate(agents.len());
    for (k, estimate) in agents.iter().enumerate() {
        match sent.get_mut(k) {
            Some(copy) => copy.clone_from(estimate),
            None => sent.push(estimate.clone()),
        }
    }
    for (a, mine) in agents.iter_mut().enumerate() {
        for &b in &neighbours[a] {
            fuse_one(a, b, mine, &sent[b])?;
        }
    }
    Ok(())
}

/// Fuses the covariances of `b` into those of `a` with `rule`; returns the weights used (CI:
/// one; nmCI: one per model block) and the plan that fuses the means ([`MeanPlan`]).
pub(super) fn fuse(
    model: &Model,
    storage: Storage,
    rule: StudyRule,
    a: &mut [DMatrix<f64>],
    b: &[DMatrix<f64>],
) -> Result<(Vec<f64>, MeanPlan), SimError> {
    match storage {
        Storage::Blocks => Ok(match rule {
            StudyRule::Ci => {
                let (omega, plan) = ci_in_place(a, b, Criterion::Trace)?;
                (vec![omega], plan)
            }
            StudyRule::Nmci => nmci_in_place(a, b, Criterion::Trace)?,
            StudyRule::Naive => (vec![], naive_in_place(a, b)),
            StudyRule::Ici => {
                let (omega, plan) = ici_in_place(a, b, Criterion::Trace)?;
                (vec![omega], plan)
            }
        }),
        Storage::Dense => {
            // The generic dense rules; the means follow from their gains,
            // `x = K_a x_a + K_b x_b`, as the rules compute it.
            let n = a[0].nrows();
            let p = FusionProblem::new_trusted(
                DVector::zeros(n),
                a[0].clone(),
                DVector::zeros(n),
                b[0].clone(),
                model.cross_pattern.clone(),
            );
            let (fused, omega) = match rule {
                StudyRule::Ci => {
                    let ci = covariance_intersection(&p, Criterion::Trace)?;
                    (ci.fused, vec![ci.omega])
                }
                StudyRule::Nmci => {
                    let nm = non_monolithic_ci(&p, Criterion::Trace)?;
                    (nm.fused, nm.omega)
                }
                StudyRule::Naive => (naive_fusion(&p), vec![]),
                StudyRule::Ici => {
                    let ici = inverse_covariance_intersection(&p, Criterion::Trace)?;
                    (ici.fused, vec![ici.omega])
                }
            };
            a[0] = fused.P;
            Ok((omega, MeanPlan::from_gains(fused.K_a, fused.K_b)))
        }
    }
}

/// Per-step results of one run for the headline agent (and the centralized filter).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunTrace {
    /// NEES per step: `central`, then one series per rule in [`STUDY_RULES`] order.
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

/// Simulates one Monte Carlo run.
pub fn simulate_run(model: &Model, spec: &RunSpec) -> Result<RunTrace, SimError> {
    let mut run = RunState::new(model, spec);
    while !run.finished() {
        run.step(model)?;
    }
    Ok(run.into_trace())
}

/// Simulates one run for one rule only: the truth, the measurements and the centralized
/// filter are those of [`simulate_run`] (the random stream does not depend on the rules), and
/// so are the rule's agents — the rules never interact. The trace has two series,
/// `central` and the rule's; [`merge_rule_traces`] puts the rules back together, bit for bit
/// equal to [`simulate_run`]. Lets a parallel study balance its work in smaller pieces.
pub fn simulate_run_for_rule(
    model: &Model,
    spec: &RunSpec,
    rule: StudyRule,
) -> Result<RunTrace, SimError> {
    let mut run = RunState::with_rules(model, spec, &[rule]);
    while !run.finished() {
        run.step(model)?;
    }
    Ok(run.into_trace())
}

/// Simulates runs `runs` of `spec` (its `run` replaced by each) for one rule, as one
/// [`RunBatch`]: the covariance work once, the means of every run beside it. Each trace is bit
/// for bit [`simulate_run_for_rule`]'s for its run.
pub fn simulate_runs_for_rule(
    model: &Model,
    spec: &RunSpec,
    runs: std::ops::Range<u64>,
    rule: StudyRule,
) -> Result<Vec<RunTrace>, SimError> {
    let mut batch = RunBatch::new(model, spec, runs, &[rule]);
    while !batch.finished() {
        batch.step(model)?;
    }
    Ok(batch.into_traces())
}

/// Assembles the per-rule traces of one run (from [`simulate_run_for_rule`], in [`STUDY_RULES`]
/// order) into the trace [`simulate_run`] gives.
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

/// Monte Carlo runs advanced together, a step at a time: the runs of one study (one seed,
/// length, headline agent and storage; any run indices) for the agents of some rules.
///
/// Every covariance of the study is the same in every run — Kalman covariances do not depend
/// on the measurements, and the fusion rules choose their weights from covariances only (the
/// argument of the exact COIN, [`super::ErrorPropagation`]) — so the batch keeps *one*
/// covariance per filter and block, and each run only its truth, its measurements and its
/// means. Per step, the covariance side predicts, updates and fuses once, returning each
/// update's gain and each fusion's `fusion::MeanPlan`; every run then applies them to its own
/// means. A run's numbers are therefore bit for bit those of the run alone (the same operations on the same numbers, in
/// the same order; tested), and the `O(n³)` work of a step (factorizations,
/// eigendecompositions, fused covariances) is done once per batch instead of once per run.
#[allow(non_snake_case)]
pub struct RunBatch {
    spec: RunSpec,
    part: Partition,
    neighbours: Vec<Vec<usize>>,
    /// Cholesky factor `[[l11, 0], [l21, l22]]` of one axis' process noise.
    noise_factor: (f64, f64, f64),
    /// The rules simulated.
    rules: Vec<StudyRule>,
    /// The centralized filter's covariances.
    central: BlockCovariance,
    /// `agents[rule][agent]`: the agents' covariances, rules as in `rules`.
    agents: Vec<Vec<BlockCovariance>>,
    /// What the agents sent this step (a reused buffer).
    sent: Vec<BlockCovariance>,
    runs: Vec<RunMeans>,
    done: usize,
}

/// What one run of a [`RunBatch`] keeps of its own: its random stream, truth and means.
struct RunMeans {
    rng: ChaCha8Rng,
    truth: DVector<f64>,
    central: BlockMeans,
    /// `agents[rule][agent]`.
    agents: Vec<Vec<BlockMeans>>,
    sent: Vec<BlockMeans>,
    trace: RunTrace,
}

/// `eᵀ P⁻¹ e` for one covariance and any number of errors `e`: the factorization once.
/// Naive fusion double counts until its covariance is numerically singular (the biases have
/// no process noise); then the eigenvalues are floored at `λ_max · ε` (machine precision) so
/// the NEES is reported as the huge finite number it is, not as a failure.
enum Nees {
    Cholesky(nalgebra::Cholesky<f64, nalgebra::Dyn>),
    Floored(nalgebra::SymmetricEigen<f64, nalgebra::Dyn>, f64),
}

#[allow(non_snake_case)]
impl Nees {
    fn new(P: &DMatrix<f64>) -> Self {
        match cholesky(P) {
            Some(c) => Nees::Cholesky(c),
            None => {
                let eig = nalgebra::SymmetricEigen::new(P.clone());
                let floor = eig.eigenvalues.amax() * f64::EPSILON;
                Nees::Floored(eig, floor)
            }
        }
    }

    fn of(&self, err: &DVector<f64>) -> f64 {
        match self {
            Nees::Cholesky(c) => err.dot(&c.solve(err)),
            Nees::Floored(eig, floor) => {
                let proj = eig.eigenvectors.transpose() * err;
                proj.iter()
                    .zip(eig.eigenvalues.iter())
                    .map(|(p, l)| p * p / l.max(*floor))
                    .sum()
            }
        }
    }
}

#[allow(non_snake_case)]
impl RunBatch {
    /// Runs `runs` of `spec` (its `run` is replaced by each), each drawing its truth from the
    /// common prior and starting every filter at it, for the agents of `rules` (the traces
    /// have `central` and one series per rule, in the order given).
    pub fn new(
        model: &Model,
        spec: &RunSpec,
        runs: impl IntoIterator<Item = u64>,
        rules: &[StudyRule],
    ) -> Self {
        let sc = &model.scenario;
        let part = Partition::new(model, spec.storage);
        let (dt, q) = (sc.dt, sc.q);
        // Cholesky of one axis' process noise [[q dt³/3, q dt²/2], [q dt²/2, q dt]].
        let l11 = (q * dt.powi(3) / 3.0).sqrt();
        let l21 = q * dt.powi(2) / 2.0 / l11;
        let l22 = (q * dt - l21 * l21).sqrt();
        let series = rules.len() + 1;
        let runs = runs
            .into_iter()
            .map(|run| {
                let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
                rng.set_stream(run);
                // Truth from the common prior (diagonal P0).
                let truth = DVector::from_fn(model.dim(), |i, _| {
                    let u: f64 = StandardNormal.sample(&mut rng);
                    model.P0[(i, i)].sqrt() * u
                });
                RunMeans {
                    rng,
                    truth,
                    central: part.prior_mean(),
                    agents: rules
                        .iter()
                        .map(|_| (0..sc.agents()).map(|_| part.prior_mean()).collect())
                        .collect(),
                    sent: Vec::new(),
                    trace: RunTrace {
                        nees: vec![Vec::with_capacity(spec.steps); series],
                        rmse: vec![Vec::with_capacity(spec.steps); series],
                        two_sigma: vec![Vec::with_capacity(spec.steps); series],
                        omega_ci: Vec::with_capacity(spec.steps),
                        omega_nmci: Vec::with_capacity(spec.steps),
                        omega_ici: Vec::with_capacity(spec.steps),
                        group_sums: vec![vec![[0.0; 2]; sc.groups]; series],
                    },
                }
            })
            .collect();
        Self {
            spec: *spec,
            neighbours: sc.neighbours(),
            noise_factor: (l11, l21, l22),
            central: part.prior(model),
            agents: rules
                .iter()
                .map(|_| (0..sc.agents()).map(|_| part.prior(model)).collect())
                .collect(),
            sent: Vec::new(),
            part,
            rules: rules.to_vec(),
            runs,
            done: 0,
        }
    }

    /// Steps done so far.
    pub fn steps_done(&self) -> usize {
        self.done
    }

    /// Whether all `spec.steps` steps are done.
    pub fn finished(&self) -> bool {
        self.done >= self.spec.steps
    }

    /// The per-step results of every run so far, in the order given.
    pub fn traces(&self) -> Vec<RunTrace> {
        self.runs.iter().map(|r| r.trace.clone()).collect()
    }

    /// Every run's trace from step `from` on ([`RunTrace::tail`]), in the order given.
    pub(super) fn traces_from(&self, from: usize) -> Vec<RunTrace> {
        self.runs.iter().map(|r| r.trace.tail(from)).collect()
    }

    /// Every run's group sums so far ([`RunTrace::group_sums`]), in the order given.
    pub(super) fn group_sums(&self) -> Vec<Vec<Vec<[f64; 2]>>> {
        self.runs
            .iter()
            .map(|r| r.trace.group_sums.clone())
            .collect()
    }

    /// Runs in the batch.
    pub fn runs(&self) -> usize {
        self.runs.len()
    }

    /// The per-step results of every run, in the order given.
    pub fn into_traces(self) -> Vec<RunTrace> {
        self.runs.into_iter().map(|r| r.trace).collect()
    }

    /// One time step of every run: truth, measurements, every filter's prediction and update,
    /// the exchange and fusion of every rule, and the headline agent's metrics. `model` must be
    /// the one the batch was created with.
    pub fn step(&mut self, model: &Model) -> Result<(), SimError> {
        let sc = &model.scenario;
        let spec = self.spec;
        let part = &self.part;
        let (l11, l21, l22) = self.noise_factor;
        // Each run's truth and measurements (the same realisations for every filter).
        let z: Vec<Vec<Vec<f64>>> = self
            .runs
            .iter_mut()
            .map(|run| {
                let rng = &mut run.rng;
                let mut normal = || -> f64 { StandardNormal.sample(&mut *rng) };
                let mut truth = &model.F * &run.truth;
                for t in 0..sc.targets() {
                    for axis in 0..2 {
                        let (u, v) = (normal(), normal());
                        truth[sc.target_index(t, 2 * axis)] += l11 * u;
                        truth[sc.target_index(t, 2 * axis + 1)] += l21 * u + l22 * v;
                    }
                }
                run.truth = truth;
                let truth = &run.truth;
                model
                    .measurements
                    .iter()
                    .map(|ms| {
                        ms.iter()
                            .map(|m| {
                                m.row.iter().map(|&(i, c)| c * truth[i]).sum::<f64>()
                                    + m.variance.sqrt() * normal()
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect();
        let runs = &mut self.runs;
        predict_update(
            part,
            &mut self.central,
            runs.iter_mut()
                .zip(&z)
                .map(|(run, z)| (&mut run.central, z)),
            0..sc.agents(),
        );
        for (r, &rule) in self.rules.iter().enumerate() {
            for a in 0..sc.agents() {
                predict_update(
                    part,
                    &mut self.agents[r][a],
                    runs.iter_mut()
                        .zip(&z)
                        .map(|(run, z)| (&mut run.agents[r][a], z)),
                    a..a + 1,
                );
            }
            // The covariances' exchange: each fusion's weights and mean plan, in order.
            let mut plans = Vec::new();
            let mut watched = Vec::new();
            exchange(
                &mut self.agents[r],
                &mut self.sent,
                &self.neighbours,
                |a, b, mine, theirs| {
                    let (omega, plan) = fuse(model, spec.storage, rule, mine, theirs)?;
                    if a == spec.agent && b == spec.watched {
                        watched.push(omega);
                    }
                    plans.push(plan);
                    Ok(())
                },
            )?;
            // Each run's means: the same schedule, the same plans.
            for run in runs.iter_mut() {
                let mut plan = plans.iter();
                exchange(
                    &mut run.agents[r],
                    &mut run.sent,
                    &self.neighbours,
                    |_, _, mine, theirs| {
                        if let Some(plan) = plan.next() {
                            plan.apply(mine, theirs);
                        }
                        Ok(())
                    },
                )?;
                for omega in &watched {
                    let trace = &mut run.trace;
                    match rule {
                        StudyRule::Ci => trace.omega_ci.push(omega[0]),
                        StudyRule::Nmci => trace.omega_nmci.push(omega.clone()),
                        StudyRule::Ici => trace.omega_ici.push(omega[0]),
                        StudyRule::Naive => {}
                    }
                }
            }
        }
        // Metrics of the headline agent, block by block (the covariance is block-diagonal).
        let covariances =
            std::iter::once(&self.central).chain(self.agents.iter().map(|r| &r[spec.agent]));
        for (s, P) in covariances.enumerate() {
            let factors: Vec<Nees> = P.iter().map(Nees::new).collect();
            let two_sigma = part.two_sigma(P);
            for run in runs.iter_mut() {
                let x = if s == 0 {
                    &run.central
                } else {
                    &run.agents[s - 1][spec.agent]
                };
                let truth = &run.truth;
                let (mut nees_sum, mut se) = (0.0, 0.0);
                // Per target group: squared error, position variance, coordinates.
                let mut group = vec![(0.0, 0.0, 0usize); sc.groups];
                for (k, block) in part.blocks.iter().enumerate() {
                    let err = DVector::from_fn(block.len(), |i, _| truth[block[i]] - x[k][i]);
                    nees_sum += factors[k].of(&err);
                    for (&i, &g) in part.positions[k].iter().zip(&part.position_groups[k]) {
                        se += err[i] * err[i];
                        group[g].0 += err[i] * err[i];
                        group[g].1 += P[k][(i, i)];
                        group[g].2 += 1;
                    }
                }
                let trace = &mut run.trace;
                trace.nees[s].push(nees_sum);
                trace.rmse[s].push((se / sc.targets() as f64).sqrt());
                trace.two_sigma[s].push(two_sigma);
                for (sums, (se, var, count)) in trace.group_sums[s].iter_mut().zip(group) {
                    // `count` coordinates are `count / 2` targets (x and y each).
                    sums[0] += (se / (count / 2).max(1) as f64).sqrt();
                    sums[1] += 2.0 * (var / count.max(1) as f64).sqrt();
                }
            }
        }
        self.done += 1;
        Ok(())
    }
}

/// A filter's prediction and its updates with the measurements of `agents` (all of them for
/// the centralized filter): the covariance once, and each run's mean (with its measurements,
/// `z[agent][measurement]`) with the same gains.
#[allow(non_snake_case)]
fn predict_update<'a>(
    part: &Partition,
    P: &mut BlockCovariance,
    runs: impl Iterator<Item = (&'a mut BlockMeans, &'a Vec<Vec<f64>>)>,
    agents: std::ops::Range<usize>,
) {
    let mut runs: Vec<_> = runs.collect();
    part.predict(P);
    for (x, _) in runs.iter_mut() {
        part.predict_mean(x);
    }
    for a in agents {
        for m in 0..part.measurements[a].len() {
            let K = part.update(P, a, m);
            for (x, z) in runs.iter_mut() {
                part.update_mean(x, a, m, z[a][m], &K);
            }
        }
    }
}

/// One Monte Carlo run in progress, advanced a step at a time ([`RunState::step`]) — what a
/// page needs to plot a run live. [`simulate_run`] is `new` + `step` until `finished`; it is a
/// [`RunBatch`] of one run.
pub struct RunState(RunBatch);

impl RunState {
    /// Draws the truth from the common prior and starts every filter at it.
    pub fn new(model: &Model, spec: &RunSpec) -> Self {
        Self::with_rules(model, spec, &STUDY_RULES)
    }

    /// As [`RunState::new`] for the agents of `rules` only (the trace has `central` and one
    /// series per rule, in the order given).
    pub fn with_rules(model: &Model, spec: &RunSpec, rules: &[StudyRule]) -> Self {
        Self(RunBatch::new(model, spec, [spec.run], rules))
    }

    /// Steps done so far.
    pub fn steps_done(&self) -> usize {
        self.0.steps_done()
    }

    /// Whether all `spec.steps` steps are done.
    pub fn finished(&self) -> bool {
        self.0.finished()
    }

    /// The current error `x − x̂` (truth minus estimate, in state order) of series `series`:
    /// `0` is the centralized filter (`agent` ignored), `1 + r` agent `agent` (0-based) of the
    /// `r`-th rule simulated. `None` for a series or agent that does not exist.
    pub fn error(&self, series: usize, agent: usize) -> Option<DVector<f64>> {
        let run = self.0.runs.first()?;
        let estimate = match series {
            0 => &run.central,
            s => run.agents.get(s - 1)?.get(agent)?,
        };
        let mut err = run.truth.clone();
        for (block, x) in self.0.part.blocks.iter().zip(estimate) {
            for (k, &i) in block.iter().enumerate() {
                err[i] -= x[k];
            }
        }
        Some(err)
    }

    /// The per-step results so far.
    pub fn trace(&self) -> &RunTrace {
        &self.0.runs[0].trace
    }

    /// The per-step results.
    pub fn into_trace(self) -> RunTrace {
        self.0.into_traces().swap_remove(0)
    }

    /// One time step: truth, measurements, every filter's prediction and update, the
    /// exchange and fusion of every rule, and the headline agent's metrics. `model` must be the
    /// one the run was created with.
    pub fn step(&mut self, model: &Model) -> Result<(), SimError> {
        self.0.step(model)
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
