//! A study advanced a few steps at a time, for live plots (the page's Study tab runs it in
//! Web Workers through the wasm bindings).
//!
//! The rules never interact: each rule's agents fuse only with agents of the same rule, and the
//! truth, the measurements and the centralized filter do not depend on the rules. So a study's
//! rules can run on two cores and be put back together, bit for bit: the page runs
//! [`WORKER_RULES`]`[0]` in a [`LiveStudy::with_second_worker`] and [`WORKER_RULES`]`[1]` in a
//! [`LiveRules`] in a second Web Worker, which sends its steps as [`TraceTail`]s; the first
//! absorbs them ([`LiveStudy::absorb`]) and its views and charts are those of one
//! [`LiveStudy::new`] running every rule (tested). The two advance in lock step: the first
//! starts a chunk of steps only once it has the second's steps up to where it is (the group
//! sums behind the per-group means are sums over the steps so far, so both halves must be
//! summed over the same steps).

use serde::{Deserialize, Serialize};

use super::trace::assemble_traces;
use super::{
    estimators, summarize, ErrorPropagation, Estimator, Model, RunBatch, RunTrace, SimError,
    Storage, StudyConfig, StudyReport, StudyRule, StudySummary, STUDY_RULES,
};

/// How a page shares a study's rules between two run workers: [`LiveStudy::with_second_worker`]
/// runs the first set, [`LiveRules`] the second. Chosen so that the halves cost about the same
/// (CI and ICI are the expensive rules: docs/benchmarks.md measures them).
pub const WORKER_RULES: [&[StudyRule]; 2] = [
    &[StudyRule::Ci, StudyRule::Naive],
    &[StudyRule::Nmci, StudyRule::Ici],
];

/// The runs of a study, advanced together a step at a time ([`RunBatch`]: the covariance work
/// of a step once, every run's means beside it), in chunks of steps. The numbers are those of
/// [`super::simulate_run`] for each run (same seeds and streams), so a finished live study
/// equals the CLI's — also when its rules are shared with a second worker
/// ([`LiveStudy::with_second_worker`]).
pub struct LiveStudy {
    config: StudyConfig,
    model: Model,
    runs: RunBatch,
    /// With a second worker: the steps of its rules received so far.
    second: Option<Second>,
    /// With `config.coin`: the exact COIN, advanced after the runs (the paper's numbers come
    /// first; a page runs [`LiveCoin`] beside the runs instead).
    coin: Option<LiveCoin>,
}

/// What a [`LiveStudy`] holds of the rules a second worker runs.
struct Second {
    /// Per run: `central`, then [`WORKER_RULES`]`[1]`, for the steps received so far.
    traces: Vec<RunTrace>,
    /// Per run: the group sums of this worker's own rules at the step received so far (taken
    /// when its runs were last there: they advance only from there).
    own_sums: Vec<Vec<Vec<[f64; 2]>>>,
}

/// The runs of a study for some of its rules ([`WORKER_RULES`]`[1]`), advanced a step at a
/// time: what a page's second run worker computes. Its steps leave as [`TraceTail`]s for the
/// [`LiveStudy`] that runs the other rules.
pub struct LiveRules {
    model: Model,
    runs: RunBatch,
    /// Steps already sent.
    sent: usize,
}

/// The steps of a [`LiveRules`] since its previous tail, for [`LiveStudy::absorb`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TraceTail {
    /// The first step in the tail (0-based).
    pub from: usize,
    /// Per run: the steps `from..` of `central` and of the rules' series and ω, and the group
    /// sums up to the tail's last step.
    pub traces: Vec<RunTrace>,
}

impl TraceTail {
    /// The step after the tail's last (`from` plus the steps it holds).
    pub fn end(&self) -> usize {
        self.from + self.traces.first().map_or(0, RunTrace::steps)
    }
}

impl LiveCoinPart {
    /// Validates the configuration and builds the model and the propagations of
    /// [`COIN_WORKER_ESTIMATORS`]`[1]`.
    pub fn new(config: StudyConfig) -> Result<Self, SimError> {
        Ok(Self {
            inner: LiveCoin::propagating(config, |e| COIN_WORKER_ESTIMATORS[1].contains(&e))?,
            sent: vec![0; COIN_WORKER_ESTIMATORS[1].len()],
        })
    }

    /// Advances by up to `units` estimator-steps; returns whether its estimators are done.
    pub fn advance(&mut self, units: usize) -> Result<bool, SimError> {
        self.inner.advance(units)?;
        Ok(self.inner.own_finished())
    }

    /// The steps since the previous tail.
    pub fn tail(&mut self) -> CoinTail {
        let mut tail = CoinTail {
            from: Vec::new(),
            values: Vec::new(),
        };
        for (e, sent) in COIN_WORKER_ESTIMATORS[1].iter().zip(&mut self.sent) {
            if let Some((_, _, series)) = self.inner.coin.iter().find(|(f, _, _)| f == e) {
                tail.from.push(*sent);
                tail.values.push(series[*sent..].to_vec());
                *sent = series.len();
            }
        }
        tail
    }
}

impl LiveRules {
    /// Validates the configuration and builds the model and the runs of
    /// [`WORKER_RULES`]`[1]` (`config.coin` is not consulted).
    pub fn new(config: StudyConfig) -> Result<Self, SimError> {
        config.validate()?;
        let model = Model::new(&config.scenario)?;
        let runs = RunBatch::new(
            &model,
            &config.run_spec(0, Storage::Blocks),
            0..config.runs as u64,
            WORKER_RULES[1],
        );
        Ok(Self {
            model,
            runs,
            sent: 0,
        })
    }

    /// Advances every run by up to `steps` time steps; returns whether they are done.
    pub fn advance(&mut self, steps: usize) -> Result<bool, SimError> {
        for _ in 0..steps {
            if self.runs.finished() {
                break;
            }
            self.runs.step(&self.model)?;
        }
        Ok(self.runs.finished())
    }

    /// The steps since the previous tail.
    pub fn tail(&mut self) -> TraceTail {
        let tail = TraceTail {
            from: self.sent,
            traces: self.runs.traces_from(self.sent),
        };
        self.sent = self.runs.steps_done();
        tail
    }
}

/// Every estimator's exact COIN for the headline agent ([`ErrorPropagation`]), advanced one
/// estimator-step at a time (the estimator furthest behind first): what [`LiveStudy`] runs
/// after its runs, and what a page runs on its own (a second Web Worker) beside the runs — it
/// does not depend on them. The series are [`super::coin_series`]'s, bit for bit.
pub struct LiveCoin {
    config: StudyConfig,
    model: Model,
    /// In [`estimators`] order: the estimator, its propagation (`None`: a second worker
    /// computes it and its steps come through [`LiveCoin::absorb`]) and its series so far.
    coin: Vec<(Estimator, Option<ErrorPropagation>, Vec<f64>)>,
}

/// How a page shares the exact COIN's estimators between two workers:
/// [`LiveCoin::with_second_worker`] propagates the first set, [`LiveCoinPart`] the second.
/// Chosen so that the halves cost about the same (docs/study.md measures each).
pub const COIN_WORKER_ESTIMATORS: [&[Estimator]; 2] = [
    &[
        Estimator::Decentralized(StudyRule::Ci),
        Estimator::Decentralized(StudyRule::Naive),
    ],
    &[
        Estimator::Central,
        Estimator::Decentralized(StudyRule::Nmci),
        Estimator::Decentralized(StudyRule::Ici),
    ],
];

/// The exact COIN of the estimators of [`COIN_WORKER_ESTIMATORS`]`[1]`, advanced one
/// estimator-step at a time: what a page's second COIN worker computes. Its steps leave as
/// [`CoinTail`]s for the [`LiveCoin`] that propagates the others.
pub struct LiveCoinPart {
    inner: LiveCoin,
    /// Steps already sent, per estimator of [`COIN_WORKER_ESTIMATORS`]`[1]`.
    sent: Vec<usize>,
}

/// The COIN steps of a [`LiveCoinPart`] since its previous tail, for [`LiveCoin::absorb`]: per
/// estimator of [`COIN_WORKER_ESTIMATORS`]`[1]` (in that order), the first step sent and the
/// values from there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoinTail {
    /// Per estimator: the first step in the tail (0-based).
    pub from: Vec<usize>,
    /// Per estimator: the COIN of the steps `from..`.
    pub values: Vec<Vec<f64>>,
}

/// A snapshot of a [`LiveCoin`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoinView {
    /// Steps per run.
    pub steps: usize,
    /// Steps every estimator's COIN has reached.
    pub coin_len: usize,
    /// Estimator-steps done so far, over every estimator (with a second worker: its steps
    /// received too); `5 × steps` when finished.
    pub units_done: usize,
    /// Whether every estimator reached `steps`.
    pub finished: bool,
    /// Per estimator (in [`estimators`] order): its name, and the mean and largest COIN over
    /// the steps so far (as in `summary.json`; absent before the first step).
    pub estimators: Vec<CoinReport>,
    /// Exact COIN per step, `5 × coin_len` row-major.
    #[serde(skip)]
    pub coin: Vec<f64>,
}

/// One estimator's COIN so far.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoinReport {
    /// The estimator's name (`central`, then the rules').
    pub name: &'static str,
    /// Mean over the steps so far.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coin_mean: Option<f64>,
    /// Largest over the steps so far.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coin_max: Option<f64>,
}

impl LiveCoin {
    /// Validates the configuration and builds the model and one propagation per estimator
    /// (`config.coin` is not consulted: this is the COIN).
    pub fn new(config: StudyConfig) -> Result<Self, SimError> {
        Self::propagating(config, |_| true)
    }

    /// As [`LiveCoin::new`], propagating the estimators of [`COIN_WORKER_ESTIMATORS`]`[0]`
    /// here; those of [`COIN_WORKER_ESTIMATORS`]`[1]` come from a [`LiveCoinPart`] with the
    /// same configuration, through [`LiveCoin::absorb`]. Its views and charts are those of
    /// [`LiveCoin::new`] at the steps every estimator reached, bit for bit.
    pub fn with_second_worker(config: StudyConfig) -> Result<Self, SimError> {
        Self::propagating(config, |e| COIN_WORKER_ESTIMATORS[0].contains(&e))
    }

    /// Propagations for the estimators `here` picks; the others' series come from elsewhere.
    fn propagating(
        config: StudyConfig,
        here: impl Fn(Estimator) -> bool,
    ) -> Result<Self, SimError> {
        config.validate()?;
        config.validate_coin()?;
        let model = Model::new(&config.scenario)?;
        let coin = estimators()
            .map(|e| {
                (
                    e,
                    here(e).then(|| ErrorPropagation::new(&model, e)),
                    Vec::new(),
                )
            })
            .collect();
        Ok(Self {
            config,
            model,
            coin,
        })
    }

    /// Whether every estimator reached the configured steps (with a second worker: its
    /// estimators' steps received too).
    pub fn finished(&self) -> bool {
        self.coin
            .iter()
            .all(|(_, _, s)| s.len() >= self.config.steps)
    }

    /// Whether its own estimators are done and it waits for a second worker's steps (then
    /// [`LiveCoin::advance`] does nothing).
    pub fn waiting(&self) -> bool {
        self.own_finished() && !self.finished()
    }

    /// Whether the estimators propagated here reached the configured steps.
    fn own_finished(&self) -> bool {
        self.coin
            .iter()
            .all(|(_, p, s)| p.is_none() || s.len() >= self.config.steps)
    }

    /// Advances by up to `units` estimator-steps of the estimators propagated here; returns
    /// whether it is finished ([`LiveCoin::finished`]).
    pub fn advance(&mut self, units: usize) -> Result<bool, SimError> {
        let agent = self.config.agent - 1;
        for _ in 0..units {
            if self.own_finished() {
                break;
            }
            let behind = self
                .coin
                .iter_mut()
                .filter_map(|(_, p, s)| Some((p.as_mut()?, s)))
                .min_by_key(|(p, _)| p.steps_done());
            if let Some((propagation, series)) = behind {
                propagation.step(&self.model)?;
                let filter = if propagation.is_central() { 0 } else { agent };
                series.push(propagation.coin(filter));
            }
        }
        Ok(self.finished())
    }

    /// Takes the next COIN steps of a second worker's estimators ([`LiveCoinPart::tail`]).
    /// Each estimator's steps must continue where its previous ones ended.
    pub fn absorb(&mut self, tail: CoinTail) -> Result<(), SimError> {
        let bad = |m: String| Err(SimError::Workers(m));
        let expected = COIN_WORKER_ESTIMATORS[1];
        if tail.from.len() != expected.len() || tail.values.len() != expected.len() {
            return bad(format!(
                "the second COIN worker sent {} estimators, not {}",
                tail.values.len(),
                expected.len()
            ));
        }
        for (k, e) in expected.iter().enumerate() {
            let Some((_, propagation, series)) = self.coin.iter().find(|(f, _, _)| f == e) else {
                return bad(format!("the study has no estimator {}", e.name()));
            };
            if propagation.is_some() {
                return bad(format!(
                    "the COIN of {} is computed here, not by a second worker",
                    e.name()
                ));
            }
            if tail.from[k] != series.len() {
                return bad(format!(
                    "the second COIN worker's steps of {} start at step {} but step {} is next",
                    e.name(),
                    tail.from[k],
                    series.len()
                ));
            }
        }
        for (e, values) in expected.iter().zip(tail.values) {
            if let Some((_, _, series)) = self.coin.iter_mut().find(|(f, _, _)| f == e) {
                series.extend(values);
            }
        }
        Ok(())
    }

    /// Every estimator's series up to the step all of them reached.
    pub fn series(&self) -> Vec<Vec<f64>> {
        let len = self.coin.iter().map(|(_, _, s)| s.len()).min().unwrap_or(0);
        self.coin
            .iter()
            .map(|(_, _, s)| s[..len].to_vec())
            .collect()
    }

    /// The current snapshot.
    pub fn view(&self) -> CoinView {
        let series = self.series();
        CoinView {
            steps: self.config.steps,
            coin_len: series.first().map_or(0, Vec::len),
            units_done: self.coin.iter().map(|(_, _, s)| s.len()).sum(),
            finished: self.finished(),
            estimators: estimators()
                .zip(&series)
                .map(|(e, s)| {
                    let (coin_mean, coin_max) = super::coin_stats(s).unzip();
                    CoinReport {
                        name: e.name(),
                        coin_mean,
                        coin_max,
                    }
                })
                .collect(),
            coin: series.concat(),
        }
    }

    /// The COIN chart so far ([`super::coin_chart`], as `coin.svg`).
    pub fn chart(&self) -> crate::chart::Chart {
        super::coin_chart(&self.config, &self.series())
    }
}

/// A snapshot of a [`LiveStudy`]: progress, the headline numbers over the runs (which advance
/// together: every run counts for the steps reached) and the run-averaged series.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyView {
    /// Finished runs (the runs advance together: `0`, then all of them).
    pub runs_done: usize,
    /// Runs in the study.
    pub runs: usize,
    /// Steps done by every run (`steps` once finished).
    pub step: usize,
    /// Steps per run.
    pub steps: usize,
    /// Time step of the scenario (s): step `k` (0-based) is at `(k + 1)·dt`.
    pub dt: f64,
    /// Whether every run is done.
    pub finished: bool,
    /// Headline numbers so far; `report.runs` counts the runs they average.
    pub report: StudyReport,
    /// Length of every series below (steps reached by the furthest run).
    pub series_len: usize,
    /// nmCI blocks of the watched fusion.
    pub blocks: usize,
    /// Run-averaged NEES, `5 × series_len` row-major (`central`, `ci`, `nmci`, `naive`, `ici`).
    #[serde(skip)]
    pub nees: Vec<f64>,
    /// Run-averaged position RMSE, same layout.
    #[serde(skip)]
    pub rmse: Vec<f64>,
    /// Run-averaged 2σ, same layout.
    #[serde(skip)]
    pub two_sigma: Vec<f64>,
    /// Run-averaged ω of the watched fusion, `(2 + blocks) × series_len` row-major: CI's,
    /// nmCI's per block, then ICI's.
    #[serde(skip)]
    pub omega: Vec<f64>,
    /// Steps of the exact COIN computed so far for every estimator (0 without COIN; it is
    /// computed after the runs).
    pub coin_len: usize,
    /// Whether the exact COIN is part of the study.
    pub coin_enabled: bool,
    /// Exact COIN per step, `5 × coin_len` row-major (estimators as `nees`).
    #[serde(skip)]
    pub coin: Vec<f64>,
}

impl LiveStudy {
    /// Validates the configuration and builds the model.
    pub fn new(config: StudyConfig) -> Result<Self, SimError> {
        Self::running(config, &STUDY_RULES)
    }

    /// Validates the configuration and builds the model and the runs of `rules`.
    fn running(config: StudyConfig, rules: &[StudyRule]) -> Result<Self, SimError> {
        config.validate()?;
        let model = Model::new(&config.scenario)?;
        let coin = config
            .coin
            .then(|| LiveCoin::new(config.clone()))
            .transpose()?;
        let runs = RunBatch::new(
            &model,
            &config.run_spec(0, Storage::Blocks),
            0..config.runs as u64,
            rules,
        );
        Ok(Self {
            config,
            model,
            runs,
            second: None,
            coin,
        })
    }

    /// As [`LiveStudy::new`], running the rules of [`WORKER_RULES`]`[0]` here; those of
    /// [`WORKER_RULES`]`[1]` come from a [`LiveRules`] with the same configuration, through
    /// [`LiveStudy::absorb`]. Its views and charts are those of [`LiveStudy::new`], bit for bit.
    pub fn with_second_worker(config: StudyConfig) -> Result<Self, SimError> {
        let mut study = Self::running(config, WORKER_RULES[0])?;
        // Before the first tail: every run's second series empty, their group sums zero.
        let (series, groups) = (1 + WORKER_RULES[1].len(), study.config.scenario.groups);
        let empty = RunTrace {
            nees: vec![Vec::new(); series],
            rmse: vec![Vec::new(); series],
            two_sigma: vec![Vec::new(); series],
            omega_ci: Vec::new(),
            omega_nmci: Vec::new(),
            omega_ici: Vec::new(),
            group_sums: vec![vec![[0.0; 2]; groups]; series],
        };
        study.second = Some(Second {
            traces: vec![empty; study.config.runs],
            own_sums: study.runs.group_sums(),
        });
        Ok(study)
    }

    /// Steps of the second worker's rules received so far (the runs' own steps without a
    /// second worker).
    fn received(&self) -> usize {
        match &self.second {
            Some(second) => second.traces.first().map_or(0, RunTrace::steps),
            None => self.runs.steps_done(),
        }
    }

    /// Whether it waits for the second worker's steps up to where its own runs are (then
    /// [`LiveStudy::advance`] does nothing and the view stays at the steps both reached).
    pub fn waiting(&self) -> bool {
        self.received() < self.runs.steps_done()
    }

    /// Takes the next steps of the second worker's rules ([`LiveRules::tail`]). A tail must
    /// continue where the previous one ended, hold every run, and not pass the steps this
    /// worker's own runs have done.
    pub fn absorb(&mut self, tail: TraceTail) -> Result<(), SimError> {
        let (own, received, runs) = (self.runs.steps_done(), self.received(), self.runs.runs());
        let second = self.second.as_mut().ok_or_else(|| {
            SimError::Workers(
                "this study runs every rule itself: it takes no second worker's steps".into(),
            )
        })?;
        let bad = |m: String| Err(SimError::Workers(m));
        if tail.from != received {
            return bad(format!(
                "the second worker's steps start at step {} but step {received} is next",
                tail.from
            ));
        }
        if tail.traces.len() != runs {
            return bad(format!(
                "the second worker sent {} runs, the study has {runs}",
                tail.traces.len()
            ));
        }
        let series = 1 + WORKER_RULES[1].len();
        let groups = self.config.scenario.groups;
        let steps = tail.traces.first().map_or(0, RunTrace::steps);
        for t in &tail.traces {
            let lengths_ok = [&t.nees, &t.rmse, &t.two_sigma]
                .iter()
                .all(|s| s.len() == series && s.iter().all(|v| v.len() == steps));
            if !lengths_ok
                || t.group_sums.len() != series
                || t.group_sums.iter().any(|g| g.len() != groups)
            {
                return bad(format!(
                    "a run of the second worker's steps does not have {series} series of {steps} steps and {groups} groups"
                ));
            }
        }
        if tail.end() > own {
            return bad(format!(
                "the second worker's steps reach step {} but this worker's runs are at step {own}",
                tail.end()
            ));
        }
        for (mine, theirs) in second.traces.iter_mut().zip(tail.traces) {
            mine.append(theirs);
        }
        Ok(())
    }

    /// Whether every run is done, and then the COIN series.
    pub fn finished(&self) -> bool {
        self.runs.finished() && !self.waiting() && self.coin_finished()
    }

    fn coin_finished(&self) -> bool {
        self.coin.as_ref().is_none_or(LiveCoin::finished)
    }

    /// Advances by up to `steps` units of work: a time step of every run or, once the runs are
    /// done, a time step of one estimator's exact COIN (the one furthest behind); returns
    /// whether the study is finished. With a second worker it does nothing while
    /// [`LiveStudy::waiting`]: a chunk starts where both workers' steps are.
    pub fn advance(&mut self, steps: usize) -> Result<bool, SimError> {
        if self.waiting() {
            return Ok(false);
        }
        if let Some(second) = &mut self.second {
            second.own_sums = self.runs.group_sums();
        }
        for _ in 0..steps {
            if self.runs.finished() {
                match &mut self.coin {
                    Some(coin) if !coin.finished() => coin.advance(1)?,
                    _ => break,
                };
                continue;
            }
            self.runs.step(&self.model)?;
        }
        Ok(self.finished())
    }

    /// Every run's trace for every rule so far: with a second worker, its rules' steps beside
    /// this worker's, over the steps both reached.
    fn traces(&self) -> Vec<RunTrace> {
        let mut own = self.runs.traces();
        let Some(second) = &self.second else {
            return own;
        };
        let steps = self.received();
        if steps < self.runs.steps_done() {
            for (trace, sums) in own.iter_mut().zip(&second.own_sums) {
                trace.truncate(steps);
                trace.group_sums.clone_from(sums);
            }
        }
        let [first, other] = WORKER_RULES.map(|rules| -> Vec<usize> {
            rules
                .iter()
                .filter_map(|r| STUDY_RULES.iter().position(|q| q == r))
                .collect()
        });
        own.into_iter()
            .zip(&second.traces)
            .map(|(mine, theirs)| {
                assemble_traces([(first.clone(), mine), (other.clone(), theirs.clone())])
            })
            .collect()
    }

    /// The summary of the runs so far (every run, up to the step they reached) and how many
    /// runs it averages, with every estimator's COIN up to the step all of them reached.
    fn summary(&self) -> (StudySummary, usize) {
        let traces = self.traces();
        let mut summary = summarize(&traces, self.model.dim());
        if let Some(coin) = &self.coin {
            summary.attach_coin(coin.series());
        }
        (summary, traces.len())
    }

    /// The study's charts so far ([`crate::study::study_charts`]: what `nmci track` writes as SVG).
    pub fn charts(&self) -> Vec<(&'static str, crate::chart::Chart)> {
        let (summary, runs) = self.summary();
        super::study_charts(&self.config, &summary, runs)
    }

    /// The current snapshot.
    pub fn view(&self) -> StudyView {
        let (summary, runs) = self.summary();
        let coin_len = summary.coin_series.first().map_or(0, Vec::len);
        let coin_flat = summary.coin_series.concat();
        let mut report = StudyReport::new(&self.config, &summary);
        report.runs = runs;
        let series_len = summary.nees_series.first().map_or(0, Vec::len);
        let flat = |series: &[Vec<f64>]| series.concat();
        let mut omega = summary.omega_ci_series.clone();
        omega.extend(flat(&summary.omega_nmci_series));
        omega.extend(&summary.omega_ici_series);
        StudyView {
            runs_done: if self.runs.finished() && !self.waiting() {
                self.config.runs
            } else {
                0
            },
            runs: self.config.runs,
            step: self.received(),
            steps: self.config.steps,
            dt: self.config.scenario.dt,
            finished: self.finished(),
            report,
            series_len,
            blocks: summary.omega_nmci_series.len(),
            nees: flat(&summary.nees_series),
            rmse: flat(&summary.rmse_series),
            two_sigma: flat(&summary.two_sigma_series),
            omega,
            coin_len,
            coin_enabled: self.config.coin,
            coin: coin_flat,
        }
    }
}
