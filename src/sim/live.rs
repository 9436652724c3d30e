//! A study advanced a few steps at a time, for live plots (the page's Study tab runs it in a
//! Web Worker through the wasm bindings).

use serde::Serialize;

use super::{
    estimators, summarize, ErrorPropagation, Model, RunBatch, SimError, Storage, StudyConfig,
    StudyReport, StudySummary, RULES,
};

/// The runs of a study, advanced together a step at a time ([`RunBatch`]: the covariance work
/// of a step once, every run's means beside it), in chunks of steps. The numbers are those of
/// [`super::simulate_run`] for each run (same seeds and streams), so a finished live study
/// equals the CLI's.
pub struct LiveStudy {
    config: StudyConfig,
    model: Model,
    runs: RunBatch,
    /// With `config.coin`: the exact COIN, advanced after the runs (the paper's numbers come
    /// first; a page runs [`LiveCoin`] beside the runs instead).
    coin: Option<LiveCoin>,
}

/// Every estimator's exact COIN for the headline agent ([`ErrorPropagation`]), advanced one
/// estimator-step at a time (the estimator furthest behind first): what [`LiveStudy`] runs
/// after its runs, and what a page runs on its own (a second Web Worker) beside the runs — it
/// does not depend on them. The series are [`super::coin_series`]'s, bit for bit.
pub struct LiveCoin {
    config: StudyConfig,
    model: Model,
    coin: Vec<(ErrorPropagation, Vec<f64>)>,
}

/// A snapshot of a [`LiveCoin`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoinView {
    /// Steps per run.
    pub steps: usize,
    /// Steps every estimator's COIN has reached.
    pub coin_len: usize,
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
        config.validate()?;
        let model = Model::new(&config.scenario)?;
        let coin = estimators()
            .map(|e| (ErrorPropagation::new(&model, e), Vec::new()))
            .collect();
        Ok(Self {
            config,
            model,
            coin,
        })
    }

    /// Whether every estimator reached the configured steps.
    pub fn finished(&self) -> bool {
        self.coin
            .iter()
            .all(|(p, _)| p.steps_done() >= self.config.steps)
    }

    /// Advances by up to `units` estimator-steps; returns whether it is finished.
    pub fn advance(&mut self, units: usize) -> Result<bool, SimError> {
        let agent = self.config.agent - 1;
        for _ in 0..units {
            if self.finished() {
                break;
            }
            let behind = self.coin.iter_mut().min_by_key(|(p, _)| p.steps_done());
            if let Some((propagation, series)) = behind {
                propagation.step(&self.model)?;
                let filter = if propagation.is_central() { 0 } else { agent };
                series.push(propagation.coin(filter));
            }
        }
        Ok(self.finished())
    }

    /// Every estimator's series up to the step all of them reached.
    pub fn series(&self) -> Vec<Vec<f64>> {
        let len = self.coin.iter().map(|(_, s)| s.len()).min().unwrap_or(0);
        self.coin.iter().map(|(_, s)| s[..len].to_vec()).collect()
    }

    /// The current snapshot.
    pub fn view(&self) -> CoinView {
        let series = self.series();
        CoinView {
            steps: self.config.steps,
            coin_len: series.first().map_or(0, Vec::len),
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

    /// The COIN chart so far ([`crate::chart::coin_chart`], as `coin.svg`).
    pub fn chart(&self) -> crate::Chart {
        crate::chart::coin_chart(&self.config, &self.series())
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
            &RULES,
        );
        Ok(Self {
            config,
            model,
            runs,
            coin,
        })
    }

    /// Whether every run is done, and then the COIN series.
    pub fn finished(&self) -> bool {
        self.runs.finished() && self.coin_finished()
    }

    fn coin_finished(&self) -> bool {
        self.coin.as_ref().is_none_or(LiveCoin::finished)
    }

    /// Advances by up to `steps` units of work: a time step of every run or, once the runs are
    /// done, a time step of one estimator's exact COIN (the one furthest behind); returns
    /// whether the study is finished.
    pub fn advance(&mut self, steps: usize) -> Result<bool, SimError> {
        for _ in 0..steps {
            if self.finished() {
                break;
            }
            if self.runs.finished() {
                if let Some(coin) = &mut self.coin {
                    coin.advance(1)?;
                }
                continue;
            }
            self.runs.step(&self.model)?;
        }
        Ok(self.finished())
    }

    /// The summary of the runs so far (every run, up to the step they reached) and how many
    /// runs it averages, with every estimator's COIN up to the step all of them reached.
    fn summary(&self) -> (StudySummary, usize) {
        let traces = self.runs.traces();
        let mut summary = summarize(&traces, self.model.dim());
        if let Some(coin) = &self.coin {
            summary.attach_coin(coin.series());
        }
        (summary, traces.len())
    }

    /// The study's charts so far ([`crate::study_charts`]: what `nmci track` writes as SVG).
    pub fn charts(&self) -> Vec<(&'static str, crate::Chart)> {
        let (summary, runs) = self.summary();
        crate::study_charts(&self.config, &summary, runs)
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
            runs_done: if self.runs.finished() {
                self.config.runs
            } else {
                0
            },
            runs: self.config.runs,
            step: self.runs.steps_done(),
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
