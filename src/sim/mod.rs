//! The paper's multi-agent tracking study (16 agents, 20 targets, 112 states).
//!
//! [`Scenario`] holds the parameters (every value the paper omits is stated there),
//! [`Model`] the linear-Gaussian model and the independent blocks derived from it, and
//! [`simulate_run`] one Monte Carlo run of the centralized filter and of the decentralized
//! agents fusing with CI, nmCI, naive fusion and ICI; [`RunBatch`] advances many runs together,
//! their covariances (which do not depend on the data) computed once. [`summarize`] averages
//! runs into the study's headline numbers; [`ErrorPropagation`] propagates every estimator's *true* error
//! covariance exactly (no Monte Carlo: all covariances and gains are deterministic), giving
//! each estimator's conservativeness index (COIN) per step next to its NEES;
//! [`LiveStudy`] advances a study a few steps at a time (the page's live Study tab) and
//! [`study_parallel`] runs it on every core (the CLI); [`run_shard`] runs a slice of its runs
//! anywhere and [`merge_shards`] puts slices back together into the one study, bit for bit;
//! [`write_study`] writes a study's files. [`sweep`] searches the networks
//! the paper's text allows for the one its numbers fit (its figure is not in the source).

mod batch;
mod charts;
mod coin;
mod draw;
mod estimators;
mod live;
mod model;
mod partition;
#[cfg(all(feature = "files", not(target_arch = "wasm32")))]
mod report;
mod scenario;
mod shard;
mod sweep;
mod trace;

pub use batch::{simulate_run, simulate_run_for_rule, simulate_runs_for_rule, RunBatch, RunState};
pub use charts::{coin_chart, series_csv, study_charts, STUDY_SVG_SIZE};
pub use coin::{coin_series, ErrorPropagation};
pub use draw::network_svg;
pub use estimators::{Estimator, Storage, StudyRule, STUDY_RULES};
pub use live::{
    CoinReport, CoinTail, CoinView, LiveCoin, LiveCoinPart, LiveRules, LiveStudy, StudyView,
    TraceTail, COIN_WORKER_ESTIMATORS, WORKER_RULES,
};
pub use model::Model;
#[cfg(all(feature = "files", not(target_arch = "wasm32")))]
pub use report::{write_study, write_sweep};
pub use scenario::{ScalarMeasurement, Scenario};
#[cfg(not(target_arch = "wasm32"))]
pub use shard::shard_files;
pub use shard::{carries_coin, merge_shards, MergeError, Study, StudyShard, SHARD_FORMAT};
#[cfg(not(target_arch = "wasm32"))]
pub use sweep::sweep;
pub use sweep::{
    candidate_networks, check_text, covariance_series, Candidate, CovarianceRun, CovarianceSeries,
    NetworkFamily, SweepConfig, SweepReport, TextMismatch, FIGURE_BRIDGES, PAPER_OMEGA_CI,
    PAPER_OMEGA_NMCI_FAR, PAPER_RMSE_REDUCTION, PAPER_TWO_SIGMA_REDUCTION,
};
pub use trace::{merge_rule_traces, nees_bounds, RunSpec, RunTrace};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::error::InputError;

/// A study that could not run.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SimError {
    /// A scenario value out of range.
    #[error("invalid scenario: {0}")]
    InvalidScenario(String),
    /// A fusion received an invalid estimate (e.g. lost positive definiteness).
    #[error("fusion failed: {0}")]
    Fusion(#[from] InputError),
    /// A filter diverged.
    #[error("the simulation diverged: {0}")]
    Diverged(String),
    /// A configuration text that does not parse (syntax, unknown key, wrong type).
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
    /// A study shared between two workers received steps that do not fit
    /// ([`LiveStudy::absorb`]).
    #[error("two-worker study: {0}")]
    Workers(String),
}

/// The most agents a scenario may have (`groups × agents_per_group`; the paper has 16). Each
/// agent keeps covariances of the whole state, so memory and time grow with agents × dim².
pub const MAX_AGENTS: usize = 64;

/// The largest state dimension of a scenario (`4 × targets + 2 × agents`; the paper's is 112).
pub const MAX_DIM: usize = 512;

/// The largest `agents × dim` with the exact COIN: [`ErrorPropagation`] carries the joint error
/// covariance of every agent's estimate, `(agents × dim)²` entries (2.1 GB at the limit; the
/// paper's 16 × 112 is 0.03 GB).
pub const MAX_COIN_SIZE: usize = 16_384;

/// The most run-steps (`runs × steps`) one call of the study keeps: every run's per-step trace
/// is held until the summary (about 0.7 kB per run and step on the paper's scenario, so about
/// 3 GB at the limit; the default study is 6 000). Shards ([`run_shard`]) split a study's
/// time across machines; their merge holds every trace too.
pub const MAX_RUN_STEPS: usize = 4_000_000;

impl Scenario {
    /// Checks every value.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |m: String| Err(SimError::InvalidScenario(m));
        // Sizes first, with overflow-free products: everything below allocates by them.
        let agents = self.groups.checked_mul(self.agents_per_group);
        let targets = self.groups.checked_mul(self.targets_per_group);
        let dim = agents.zip(targets).and_then(|(a, t)| {
            t.checked_mul(4)
                .and_then(|t4| a.checked_mul(2).and_then(|a2| t4.checked_add(a2)))
        });
        match (agents, dim) {
            (Some(a), _) if a > MAX_AGENTS => {
                return bad(format!(
                    "groups × agents_per_group = {a} agents, above the limit of {MAX_AGENTS}"
                ))
            }
            (Some(_), Some(d)) if d > MAX_DIM => {
                return bad(format!(
                    "the state has 4 × targets + 2 × agents = {d} dimensions, above the limit of {MAX_DIM}"
                ))
            }
            (None, _) | (_, None) => {
                return bad(format!(
                    "groups × agents_per_group and groups × targets_per_group must stay within {MAX_AGENTS} agents and {MAX_DIM} state dimensions"
                ))
            }
            _ => {}
        }
        if self.groups == 0 || self.agents_per_group == 0 {
            return bad("groups and agents_per_group must be at least 1".into());
        }
        if self.targets_per_group < self.agents_per_group + 1 {
            return bad(format!(
                "targets_per_group must be at least agents_per_group + 1 = {} (the k-th agent measures targets k and k+1)",
                self.agents_per_group + 1
            ));
        }
        for (name, v) in [
            ("dt", self.dt),
            ("q", self.q),
            ("landmark_variance", self.landmark_variance),
            ("prior_position_variance", self.prior_position_variance),
            ("prior_velocity_variance", self.prior_velocity_variance),
            ("prior_bias_variance", self.prior_bias_variance),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return bad(format!("{name} must be positive and finite (got {v})"));
            }
        }
        for &(a, b) in &self.bridges {
            if a == 0 || b == 0 || a > self.agents() || b > self.agents() || a == b {
                return bad(format!(
                    "bridge {a}–{b} must join two different agents among 1..={}",
                    self.agents()
                ));
            }
        }
        if !self.edges.is_empty() {
            if !self.bridges.is_empty() {
                return bad("give either `bridges` (with a ring in each group) or `edges` (the whole network), not both: set `bridges = []` with `edges`".into());
            }
            let n = self.agents();
            let mut seen = std::collections::BTreeSet::new();
            for &(a, b) in &self.edges {
                if a == 0 || b == 0 || a > n || b > n {
                    return bad(format!("edge {a}–{b} names an agent outside 1..={n}"));
                }
                if a == b {
                    return bad(format!("edge {a}–{b} links an agent to itself"));
                }
                if !seen.insert((a.min(b), a.max(b))) {
                    return bad(format!("edge {a}–{b} is listed twice"));
                }
            }
        }
        // Connected (whatever form the network is given in): every agent reachable from 1.
        let n = self.agents();
        let mut reached = vec![false; n];
        let mut stack = vec![0];
        reached[0] = true;
        let links = self.links();
        while let Some(v) = stack.pop() {
            for &(a, b) in &links {
                for (x, y) in [(a, b), (b, a)] {
                    if x == v && !reached[y] {
                        reached[y] = true;
                        stack.push(y);
                    }
                }
            }
        }
        if let Some(lost) = reached.iter().position(|r| !r) {
            return bad(format!(
                "the network is not connected: agent {} cannot be reached from agent 1",
                lost + 1
            ));
        }
        if !self.targets.is_empty() {
            if self.targets.len() != self.agents() {
                return bad(format!(
                    "`targets` has {} entries; give one pair per agent ({})",
                    self.targets.len(),
                    self.agents()
                ));
            }
            for (a, pair) in self.targets.iter().enumerate() {
                if pair.iter().any(|&t| t == 0 || t > self.targets()) || pair[0] == pair[1] {
                    return bad(format!(
                        "`targets` of agent {}: {pair:?} must be two different targets among 1..={}",
                        a + 1,
                        self.targets()
                    ));
                }
            }
        }
        Ok(())
    }
}

/// A whole study: the scenario and how it is run. Every field has a default
/// (`configs/paper.toml` lists them) and can be overridden by a TOML file or the CLI.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StudyConfig {
    /// Time steps per run.
    pub steps: usize,
    /// Monte Carlo runs.
    pub runs: usize,
    /// Seed (run `r` uses stream `r`).
    pub seed: u64,
    /// Headline agent, 1-based.
    pub agent: usize,
    /// Neighbour whose fusion into `agent` is watched for ω, 1-based.
    pub watched: usize,
    /// Compute every estimator's exact COIN per step ([`ErrorPropagation`]; once per study,
    /// it does not depend on the run).
    pub coin: bool,
    /// The scenario.
    pub scenario: Scenario,
}

impl Default for StudyConfig {
    fn default() -> Self {
        Self {
            steps: 400,
            runs: 15,
            seed: 1,
            agent: 7,
            watched: 11,
            coin: true,
            scenario: Scenario::default(),
        }
    }
}

impl StudyConfig {
    /// Checks every value.
    pub fn validate(&self) -> Result<(), SimError> {
        self.scenario.validate()?;
        let agents = self.scenario.agents();
        if self.steps < 2 || self.runs == 0 {
            return Err(SimError::InvalidScenario(
                "steps must be at least 2 and runs at least 1".into(),
            ));
        }
        if self.coin {
            self.validate_coin()?;
        }
        if self.agent == 0 || self.agent > agents || self.watched == 0 || self.watched > agents {
            return Err(SimError::InvalidScenario(format!(
                "agent and watched must be agent ids in 1..={agents}"
            )));
        }
        if !self.scenario.neighbours()[self.agent - 1].contains(&(self.watched - 1)) {
            return Err(SimError::InvalidScenario(format!(
                "agent {} has no link to agent {}",
                self.agent, self.watched
            )));
        }
        Ok(())
    }

    /// Checks that the exact COIN of this study fits [`MAX_COIN_SIZE`] (its scenario already
    /// checked): what [`StudyConfig::validate`] asks when `coin` is set, and every computation
    /// of the COIN asks whatever `coin` says.
    pub fn validate_coin(&self) -> Result<(), SimError> {
        let (agents, dim) = (self.scenario.agents(), self.scenario.dim());
        if agents * dim > MAX_COIN_SIZE {
            return Err(SimError::InvalidScenario(format!(
                "the exact COIN propagates agents × dim = {agents} × {dim} = {} error states, above the limit of {MAX_COIN_SIZE}: set coin = false (or --no-coin) for this scenario",
                agents * dim
            )));
        }
        Ok(())
    }

    /// Checks that `runs × steps` fits [`MAX_RUN_STEPS`], the traces one call keeps.
    pub fn validate_run_steps(&self) -> Result<(), SimError> {
        match self.runs.checked_mul(self.steps) {
            Some(n) if n <= MAX_RUN_STEPS => Ok(()),
            _ => Err(SimError::InvalidScenario(format!(
                "runs × steps = {} × {} is above the limit of {MAX_RUN_STEPS} run-steps one study holds in memory (every run's per-step trace)",
                self.runs, self.steps
            ))),
        }
    }

    /// A configuration from TOML text (the form of `configs/paper.toml`; missing keys take
    /// their defaults, unknown keys are refused). Not validated: see [`StudyConfig::validate`].
    #[cfg(all(feature = "files", not(target_arch = "wasm32")))]
    pub fn from_toml(text: &str) -> Result<Self, SimError> {
        toml::from_str(text).map_err(|e| SimError::InvalidConfig(e.message().to_string()))
    }

    /// The specification of run `run`.
    pub fn run_spec(&self, run: u64, storage: Storage) -> RunSpec {
        RunSpec {
            steps: self.steps,
            seed: self.seed,
            run,
            agent: self.agent - 1,
            watched: self.watched - 1,
            storage,
        }
    }
}

/// `summary.json`: the headline numbers of a study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyReport {
    /// Centralized Kalman filter.
    pub central: EstimatorSummary,
    /// Decentralized, monolithic CI.
    pub ci: EstimatorSummary,
    /// Decentralized, nmCI.
    pub nmci: EstimatorSummary,
    /// Decentralized, naive fusion.
    pub naive: EstimatorSummary,
    /// Decentralized, ICI (not in the paper).
    pub ici: EstimatorSummary,
    /// 95 % bounds of the run-averaged NEES.
    pub nees_bounds: [f64; 2],
    /// Steady-state ω of the watched fusion (mean over the last half of the steps).
    pub omega_7_11: OmegaReport,
    /// Steps per run.
    pub steps: usize,
    /// Runs.
    pub runs: usize,
    /// Seed.
    pub seed: u64,
    /// Headline agent (1-based).
    pub agent: usize,
}

/// Steady-state weights of the watched fusion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OmegaReport {
    /// CI's one ω.
    pub ci: f64,
    /// nmCI's ω per block (G1x, G1y, G2x, G2y, …).
    pub nmci: Vec<f64>,
    /// ICI's one ω (`0` keeps the agent's estimate).
    pub ici: f64,
}

impl StudyReport {
    /// The report of a summary.
    pub fn new(config: &StudyConfig, summary: &StudySummary) -> Self {
        // Absent before any step has run (a live study's first view): zeros.
        let pick = |k: usize| {
            summary
                .estimators
                .get(k)
                .map(|e| e.1.clone())
                .unwrap_or_default()
        };
        Self {
            central: pick(0),
            ci: pick(1),
            nmci: pick(2),
            naive: pick(3),
            ici: pick(4),
            nees_bounds: [summary.nees_bounds.0, summary.nees_bounds.1],
            omega_7_11: OmegaReport {
                ci: summary.omega_ci,
                nmci: summary.omega_nmci.clone(),
                ici: summary.omega_ici,
            },
            steps: config.steps,
            runs: config.runs,
            seed: config.seed,
            agent: config.agent,
        }
    }
}

/// The runs of a study, in parallel (rayon) over rules × slices of runs, each piece a
/// [`RunBatch`] ([`simulate_runs_for_rule`]: the covariances once per piece, every run's means
/// beside them), calling `on_piece` after each piece (a progress bar of
/// [`run_pieces`]`(config.runs, STUDY_RULES.len())`). The traces are bit for bit those of
/// [`simulate_run`] whatever the number of threads or pieces.
#[cfg(not(target_arch = "wasm32"))]
pub fn simulate_runs_parallel(
    config: &StudyConfig,
    model: &Model,
    on_piece: impl Fn() + Sync,
) -> Result<Vec<RunTrace>, SimError> {
    simulate_rules_parallel(config, model, &STUDY_RULES, 0, on_piece)
}

/// How many slices the runs of a study are cut into per rule: each slice repeats the
/// covariance work once, so as few as keep every core busy — two per rule while the rules
/// alone are fewer than twice the threads (their costs differ: naive fusion is cheap), at most
/// one per run.
#[cfg(not(target_arch = "wasm32"))]
fn run_slices(runs: usize, rules: usize) -> usize {
    let threads = rayon::current_num_threads();
    (threads.div_ceil(rules.max(1)) * 2).clamp(1, runs.max(1))
}

/// The pieces [`simulate_rules_parallel`] cuts `runs` runs of `rules` rules into (rules ×
/// slices).
#[cfg(not(target_arch = "wasm32"))]
pub fn run_pieces(runs: usize, rules: usize) -> usize {
    rules * run_slices(runs, rules)
}

/// Runs `first_run..first_run + config.runs` of a study for the agents of `rules` (with the
/// centralized filter), as [`simulate_runs_parallel`] runs `0..runs` for all of [`STUDY_RULES`]: the
/// traces have `central` and one series per rule, in the order given.
#[cfg(not(target_arch = "wasm32"))]
pub fn simulate_rules_parallel(
    config: &StudyConfig,
    model: &Model,
    rules: &[StudyRule],
    first_run: usize,
    on_piece: impl Fn() + Sync,
) -> Result<Vec<RunTrace>, SimError> {
    use rayon::prelude::*;
    config.validate()?;
    config.validate_run_steps()?;
    let slices = run_slices(config.runs, rules.len());
    let (first, runs) = (first_run as u64, config.runs as u64);
    let bounds = |s: usize| first + runs * s as u64 / slices as u64;
    let pieces: Vec<(StudyRule, std::ops::Range<u64>)> = rules
        .iter()
        .flat_map(|&rule| (0..slices).map(move |s| (rule, bounds(s)..bounds(s + 1))))
        .collect();
    let spec = config.run_spec(first, Storage::Blocks);
    let traces = pieces
        .par_iter()
        .map(|(rule, runs)| {
            let traces = simulate_runs_for_rule(model, &spec, runs.clone(), *rule);
            on_piece();
            traces
        })
        .collect::<Result<Vec<_>, _>>()?;
    // Per rule, its slices' traces in run order (moved, not copied).
    let mut pieces = traces.into_iter();
    let mut by_rule: Vec<std::vec::IntoIter<RunTrace>> = (0..rules.len())
        .map(|_| {
            let rule: Vec<RunTrace> = pieces.by_ref().take(slices).flatten().collect();
            rule.into_iter()
        })
        .collect();
    Ok((0..config.runs)
        .map(|_| merge_rule_traces(by_rule.iter_mut().filter_map(Iterator::next).collect()))
        .collect())
}

/// The estimators of the study in report order: the centralized filter, then [`STUDY_RULES`]
/// (series `0..` of a [`RunTrace`]).
pub fn estimators() -> impl Iterator<Item = Estimator> {
    std::iter::once(Estimator::Central)
        .chain(STUDY_RULES.iter().copied().map(Estimator::Decentralized))
}

/// Every estimator's exact COIN per step for the headline agent ([`coin_series`]), in
/// [`estimators`] order, in parallel (rayon); `on_piece` is called after each estimator.
#[cfg(not(target_arch = "wasm32"))]
pub fn coin_parallel(
    config: &StudyConfig,
    model: &Model,
    on_piece: impl Fn() + Sync,
) -> Result<Vec<Vec<f64>>, SimError> {
    use rayon::prelude::*;
    config.validate_coin()?;
    let pieces: Vec<Estimator> = estimators().collect();
    pieces
        .par_iter()
        .map(|&e| {
            let series = coin_series(model, config.steps, config.agent - 1, e);
            on_piece();
            series
        })
        .collect()
}

/// Runs `first_run..first_run + config.runs` of a study on every core as a [`StudyShard`]
/// (see [`merge_shards`]): the Monte Carlo runs and — in the shard holding run 0, when
/// `config.coin` — every estimator's exact COIN ([`coin_parallel`]) side by side; `on_piece`
/// is called after each piece ([`run_pieces`] run pieces, plus one per estimator with
/// COIN).
#[cfg(not(target_arch = "wasm32"))]
pub fn run_shard(
    config: &StudyConfig,
    model: &Model,
    first_run: usize,
    on_piece: impl Fn() + Sync,
) -> Result<StudyShard, SimError> {
    config.validate()?;
    config.validate_run_steps()?;
    if first_run.checked_add(config.runs).is_none() {
        return Err(SimError::InvalidScenario(format!(
            "first_run {first_run} + runs {} is past the last run index",
            config.runs
        )));
    }
    let (traces, coin) = rayon::join(
        || simulate_rules_parallel(config, model, &STUDY_RULES, first_run, &on_piece),
        || {
            carries_coin(config, first_run)
                .then(|| coin_parallel(config, model, &on_piece))
                .transpose()
        },
    );
    Ok(StudyShard {
        format: SHARD_FORMAT.into(),
        config: config.clone(),
        first_run,
        traces: traces?,
        coin: coin?,
    })
}

/// A whole study on every core, as `nmci track` runs it: [`run_shard`] from run 0, summarized.
#[cfg(not(target_arch = "wasm32"))]
pub fn study_parallel(
    config: &StudyConfig,
    model: &Model,
    on_piece: impl Fn() + Sync,
) -> Result<Study, SimError> {
    let shard = run_shard(config, model, 0, on_piece)?;
    Ok(shard::study_of(config.clone(), shard.traces, shard.coin))
}

/// Runs a whole study on one thread, its runs as one [`RunBatch`] (the CLI runs the same runs
/// in parallel).
pub fn run_study(config: &StudyConfig) -> Result<(StudySummary, StudyReport), SimError> {
    config.validate()?;
    config.validate_run_steps()?;
    let model = Model::new(&config.scenario)?;
    let spec = config.run_spec(0, Storage::Blocks);
    let mut batch = RunBatch::new(&model, &spec, 0..config.runs as u64, &STUDY_RULES);
    while !batch.finished() {
        batch.step(&model)?;
    }
    let traces = batch.into_traces();
    let mut summary = summarize(&traces, model.dim());
    if config.coin {
        let coin = estimators()
            .map(|e| coin_series(&model, config.steps, config.agent - 1, e))
            .collect::<Result<Vec<_>, _>>()?;
        summary.attach_coin(coin);
    }
    let report = StudyReport::new(config, &summary);
    Ok((summary, report))
}

/// Headline numbers of one estimator for the headline agent (means over runs and steps).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EstimatorSummary {
    /// Mean position RMSE.
    pub rmse_mean: f64,
    /// Mean 2σ of the position coordinates.
    pub two_sigma_mean: f64,
    /// Mean NEES.
    pub nees_mean: f64,
    /// Fraction of steps whose run-averaged NEES is above the upper 95 % bound.
    pub nees_frac_above_upper: f64,
    /// Mean over the steps of the exact COIN (`λ_max(P^{-1/2} E P^{-1/2})`, `E` the true error
    /// covariance): `≤ 1` conservative, `1` exact, `> 1` overconfident. Absent when the study
    /// ran without COIN.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coin_mean: Option<f64>,
    /// The largest COIN over the steps (`≤ 1` = conservative at every step).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coin_max: Option<f64>,
    /// Mean position RMSE of each target group's targets (group 1 first).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rmse_by_group: Vec<f64>,
    /// Mean 2σ of each target group's position coordinates.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub two_sigma_by_group: Vec<f64>,
}

/// Per-step means over runs and the headline numbers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudySummary {
    /// `central`, `ci`, `nmci`, `naive`, `ici`.
    pub estimators: Vec<(String, EstimatorSummary)>,
    /// 95 % bounds of the run-averaged NEES.
    pub nees_bounds: (f64, f64),
    /// CI's steady-state ω (mean over the last half of the steps).
    pub omega_ci: f64,
    /// nmCI's steady-state ω per block.
    pub omega_nmci: Vec<f64>,
    /// ICI's steady-state ω.
    pub omega_ici: f64,
    /// Run-averaged NEES per step, same order as `estimators`.
    pub nees_series: Vec<Vec<f64>>,
    /// Run-averaged position RMSE per step.
    pub rmse_series: Vec<Vec<f64>>,
    /// Run-averaged 2σ per step.
    pub two_sigma_series: Vec<Vec<f64>>,
    /// CI's ω of the watched fusion per step, averaged over runs.
    pub omega_ci_series: Vec<f64>,
    /// nmCI's ω per block (outer) and step (inner), averaged over runs.
    pub omega_nmci_series: Vec<Vec<f64>>,
    /// ICI's ω of the watched fusion per step, averaged over runs.
    pub omega_ici_series: Vec<f64>,
    /// Exact COIN per estimator (same order as `estimators`) and step; empty without COIN.
    pub coin_series: Vec<Vec<f64>>,
}

impl StudySummary {
    /// Adds the exact COIN series (one per estimator, [`estimators`] order; a live study's
    /// may be shorter than the runs) and their mean and maximum to the estimators' numbers.
    pub fn attach_coin(&mut self, coin: Vec<Vec<f64>>) {
        for ((_, e), series) in self.estimators.iter_mut().zip(&coin) {
            if let Some((mean, max)) = coin_stats(series) {
                (e.coin_mean, e.coin_max) = (Some(mean), Some(max));
            }
        }
        self.coin_series = coin;
    }
}

/// The mean and the largest value of one estimator's COIN series (`None` when empty): the
/// `coin_mean` and `coin_max` of `summary.json` and of the page's table.
pub(crate) fn coin_stats(series: &[f64]) -> Option<(f64, f64)> {
    (!series.is_empty()).then(|| {
        (
            series.iter().sum::<f64>() / series.len() as f64,
            series.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    })
}

/// Averages run traces into the study's numbers (`dof` = state dimension). Traces may be of
/// different lengths (runs in progress, for live plots): step `k` averages the traces that
/// reached it; the NEES bounds are those of `traces.len()` runs.
pub fn summarize(traces: &[RunTrace], dof: usize) -> StudySummary {
    let series = traces.first().map_or(0, |t| t.nees.len());
    let len = |t: &RunTrace| t.nees.first().map_or(0, Vec::len);
    let steps = traces.iter().map(len).max().unwrap_or(0);
    let mean_series = |pick: &dyn Fn(&RunTrace) -> &Vec<Vec<f64>>| -> Vec<Vec<f64>> {
        (0..series)
            .map(|s| {
                (0..steps)
                    .map(|k| {
                        let values = traces.iter().filter_map(|t| pick(t)[s].get(k));
                        let count = traces.iter().filter(|t| len(t) > k).count().max(1);
                        values.sum::<f64>() / count as f64
                    })
                    .collect()
            })
            .collect()
    };
    let nees = mean_series(&|t| &t.nees);
    let rmse = mean_series(&|t| &t.rmse);
    let two_sigma = mean_series(&|t| &t.two_sigma);
    let bounds = nees_bounds(traces.len().max(1), dof);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let names: Vec<&str> = estimators().map(Estimator::name).collect();
    // Per series and group: the sums over every run's steps, over the steps run.
    let steps_run: usize = traces.iter().map(len).sum();
    let by_group = |s: usize, which: usize| -> Vec<f64> {
        let groups = traces.first().map_or(0, |t| t.group_sums[s].len());
        (0..groups)
            .map(|g| {
                traces
                    .iter()
                    .map(|t| t.group_sums[s][g][which])
                    .sum::<f64>()
                    / steps_run.max(1) as f64
            })
            .collect()
    };
    let estimators = (0..series)
        .map(|s| {
            (
                names.get(s).copied().unwrap_or("other").to_string(),
                EstimatorSummary {
                    rmse_mean: mean(&rmse[s]),
                    two_sigma_mean: mean(&two_sigma[s]),
                    nees_mean: mean(&nees[s]),
                    nees_frac_above_upper: nees[s].iter().filter(|v| **v > bounds.1).count() as f64
                        / steps.max(1) as f64,
                    coin_mean: None,
                    coin_max: None,
                    rmse_by_group: by_group(s, 0),
                    two_sigma_by_group: by_group(s, 1),
                },
            )
        })
        .collect();
    let half = steps / 2;
    let omega_ci = mean(
        &traces
            .iter()
            .flat_map(|t| t.omega_ci.iter().skip(half).copied())
            .collect::<Vec<_>>(),
    );
    let blocks = traces
        .first()
        .and_then(|t| t.omega_nmci.first())
        .map_or(0, Vec::len);
    let omega_nmci = (0..blocks)
        .map(|b| {
            mean(
                &traces
                    .iter()
                    .flat_map(|t| {
                        t.omega_nmci
                            .iter()
                            .skip(half)
                            .filter_map(move |w| w.get(b).copied())
                    })
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    let step_mean = |f: &dyn Fn(&RunTrace, usize) -> Option<f64>| -> Vec<f64> {
        (0..steps)
            .map(|k| mean(&traces.iter().filter_map(|t| f(t, k)).collect::<Vec<_>>()))
            .collect()
    };
    let omega_ci_series = step_mean(&|t, k| t.omega_ci.get(k).copied());
    let omega_ici = mean(
        &traces
            .iter()
            .flat_map(|t| t.omega_ici.iter().skip(half).copied())
            .collect::<Vec<_>>(),
    );
    let omega_ici_series = step_mean(&|t, k| t.omega_ici.get(k).copied());
    let omega_nmci_series = (0..blocks)
        .map(|b| step_mean(&|t, k| t.omega_nmci.get(k).and_then(|w| w.get(b)).copied()))
        .collect();
    StudySummary {
        estimators,
        nees_bounds: bounds,
        omega_ci,
        omega_nmci,
        omega_ici,
        omega_ci_series,
        omega_nmci_series,
        omega_ici_series,
        coin_series: Vec::new(),
        nees_series: nees,
        rmse_series: rmse,
        two_sigma_series: two_sigma,
    }
}
