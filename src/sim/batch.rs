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

use super::estimators::{StudyRule, STUDY_RULES};
use super::model::Model;
use super::partition::{exchange, fuse, BlockCovariance, BlockMeans, Partition};
use super::trace::{RunSpec, RunTrace};
use super::SimError;
use crate::linalg::cholesky;

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
/// `central` and the rule's; [`merge_rule_traces`](super::trace::merge_rule_traces) puts the rules back together, bit for bit
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
pub(super) struct RunMeans {
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
pub(super) enum Nees {
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
pub(super) fn predict_update<'a>(
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
