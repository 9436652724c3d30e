//! Studies split across processes and machines: shards of runs, and their merge.
//!
//! Run `r` of a study draws from stream `r` of `ChaCha8Rng::seed_from_u64(seed)`
//! ([`RunSpec`](super::RunSpec)) and shares nothing with any other run, so runs `a..a+m`
//! computed anywhere are, bit for bit, runs `a..a+m` of one big study. A [`StudyShard`] is such
//! a slice: the configuration, the index of its first run and its runs' traces — plus, in the
//! shard that holds run 0 of a study that asks for it, the exact COIN, which does not depend on
//! the runs (it is computed once, not once per shard).
//!
//! [`merge_shards`] checks that the shards belong to one study (the same configuration apart
//! from `runs`, the same format), that together they hold runs `0..N` exactly once and that
//! the COIN is there when the configuration asks for it; it then orders the traces by run and
//! calls [`summarize`] — the same function on the same traces in the same order as one `N`-run
//! study, so the merged summary, series and report *are* that study's (tested bit for bit,
//! through the library, the CLI's `track --first-run` / `merge`, and a Python process pool).
//!
//! A shard stores every run's per-step trace: enough to merge exactly, and to analyse runs
//! one by one. On disk it is `shard-FIRST-END.json` ([`StudyShard::file_name`]; zero-padded, so
//! names sort by run), and a folder of them is read by [`shard_files`].

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::{summarize, RunTrace, SimError, StudyConfig, StudyReport, StudySummary};

/// The `format` of a shard this version writes and reads.
pub const SHARD_FORMAT: &str = "nmci-study-shard/1";

/// Runs `first_run..first_run + config.runs` of a study (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyShard {
    /// [`SHARD_FORMAT`].
    pub format: String,
    /// The study's configuration; `runs` is the number of runs in this shard.
    pub config: StudyConfig,
    /// Index of the shard's first run (run `r` uses stream `r` of the seed).
    pub first_run: usize,
    /// One trace per run, in run order.
    pub traces: Vec<RunTrace>,
    /// Every estimator's exact COIN per step: in the shard holding run 0 when `config.coin`,
    /// absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coin: Option<Vec<Vec<f64>>>,
}

/// Whether the shard of `config.runs` runs from `first_run` carries the exact COIN: it does
/// when it holds run 0 of a study that asks for it (the COIN does not depend on the runs).
pub fn carries_coin(config: &StudyConfig, first_run: usize) -> bool {
    config.coin && first_run == 0 && config.runs > 0
}

impl StudyShard {
    /// Its file name: `shard-FIRST-END.json`, zero-padded to six digits.
    pub fn file_name(&self) -> String {
        format!(
            "shard-{:06}-{:06}.json",
            self.first_run,
            self.first_run.saturating_add(self.config.runs)
        )
    }
}

/// The shard files of a folder (`shard-*.json`), sorted by name. Native only.
#[cfg(not(target_arch = "wasm32"))]
pub fn shard_files(dir: &std::path::Path) -> std::io::Result<Vec<std::path::PathBuf>> {
    let mut files: Vec<std::path::PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("shard-") && n.ends_with(".json"))
        })
        .collect();
    files.sort();
    Ok(files)
}

/// A whole study: its configuration (`runs` = all runs), every run's trace in run order and
/// the summary ([`summarize`], with the COIN attached when computed).
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    /// The configuration.
    pub config: StudyConfig,
    /// Run `r`'s trace at index `r`.
    pub traces: Vec<RunTrace>,
    /// Means over the runs and the headline numbers.
    pub summary: StudySummary,
}

impl Study {
    /// `summary.json`: the headline numbers.
    pub fn report(&self) -> StudyReport {
        StudyReport::new(&self.config, &self.summary)
    }
}

/// Shards that do not make one study.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MergeError {
    /// Nothing to merge.
    #[error("no shards to merge")]
    NoShards,
    /// A shard written by another format (or not a shard at all).
    #[error("shard {index}: format {found:?}, expected {SHARD_FORMAT:?}")]
    Format {
        /// Position of the shard in the input (0-based).
        index: usize,
        /// Its `format`.
        found: String,
    },
    /// A shard whose configuration differs from the first shard's in more than `runs`.
    #[error("shard {index} (first run {first_run}) is of another study: its `{field}` differs from that of shard 0")]
    ConfigMismatch {
        /// Position of the shard in the input.
        index: usize,
        /// Its first run.
        first_run: usize,
        /// The first configuration field that differs (`seed`, `steps`, `scenario`, …).
        field: String,
    },
    /// A shard whose number of traces is not its `config.runs`.
    #[error(
        "shard {index} (first run {first_run}) holds {found} traces but says runs = {expected}"
    )]
    TraceCount {
        /// Position of the shard in the input.
        index: usize,
        /// Its first run.
        first_run: usize,
        /// `config.runs`.
        expected: usize,
        /// Traces found.
        found: usize,
    },
    /// A run held by two shards.
    #[error("run {run} is in more than one shard")]
    Overlap {
        /// The run.
        run: usize,
    },
    /// Runs between 0 and the last run that no shard holds.
    #[error("runs {first}..{end} are in no shard (a merged study holds runs 0..N, each once)")]
    Missing {
        /// First missing run.
        first: usize,
        /// One past the last missing run.
        end: usize,
    },
    /// The COIN is asked for (`coin = true`) but the shard holding run 0 does not carry it, or a
    /// shard carries it where it does not belong.
    #[error("{0}")]
    Coin(String),
    /// The merged configuration is not a valid study.
    #[error(transparent)]
    Invalid(#[from] SimError),
}

/// The first top-level field in which two configurations differ, `runs` aside.
fn differing_field(a: &StudyConfig, b: &StudyConfig) -> Option<String> {
    let (a, b) = (
        serde_json::to_value(a).unwrap_or_default(),
        serde_json::to_value(b).unwrap_or_default(),
    );
    let (Some(a), Some(b)) = (a.as_object(), b.as_object()) else {
        return Some("configuration".into());
    };
    a.iter()
        .find(|(k, v)| *k != "runs" && b.get(*k) != Some(*v))
        .map(|(k, _)| k.clone())
}

/// Merges shards into the study they are slices of (see the module docs); the shards may come
/// in any order.
pub fn merge_shards(shards: Vec<StudyShard>) -> Result<Study, MergeError> {
    let first = shards.first().ok_or(MergeError::NoShards)?;
    let base = first.config.clone();
    for (index, s) in shards.iter().enumerate() {
        if s.format != SHARD_FORMAT {
            return Err(MergeError::Format {
                index,
                found: s.format.clone(),
            });
        }
        if let Some(field) = differing_field(&base, &s.config) {
            return Err(MergeError::ConfigMismatch {
                index,
                first_run: s.first_run,
                field,
            });
        }
        if s.traces.len() != s.config.runs {
            return Err(MergeError::TraceCount {
                index,
                first_run: s.first_run,
                expected: s.config.runs,
                found: s.traces.len(),
            });
        }
        match (&s.coin, carries_coin(&s.config, s.first_run)) {
            (None, true) => {
                return Err(MergeError::Coin(format!(
                    "shard {index} holds run 0 of a study with coin = true but carries no COIN"
                )))
            }
            (Some(_), false) => {
                return Err(MergeError::Coin(format!(
                    "shard {index} (first run {}) carries a COIN, which belongs only to the shard holding run 0 of a study with coin = true",
                    s.first_run
                )))
            }
            _ => {}
        }
    }
    let mut order: Vec<usize> = (0..shards.len()).collect();
    order.sort_by_key(|&i| shards[i].first_run);
    let mut next = 0;
    for &i in &order {
        let s = &shards[i];
        if s.config.runs == 0 {
            continue;
        }
        if s.first_run < next {
            return Err(MergeError::Overlap { run: s.first_run });
        }
        if s.first_run > next {
            return Err(MergeError::Missing {
                first: next,
                end: s.first_run,
            });
        }
        next = s.first_run.saturating_add(s.config.runs);
    }
    let mut slots: Vec<Option<StudyShard>> = shards.into_iter().map(Some).collect();
    let mut traces = Vec::with_capacity(next);
    let mut coin = None;
    for i in order {
        let s = slots[i].take().expect("each shard is taken once");
        traces.extend(s.traces);
        coin = coin.or(s.coin);
    }
    let config = StudyConfig { runs: next, ..base };
    config.validate()?;
    Ok(study_of(config, traces, coin))
}

/// The study of complete traces (run order) and, when computed, the COIN.
pub(super) fn study_of(
    config: StudyConfig,
    traces: Vec<RunTrace>,
    coin: Option<Vec<Vec<f64>>>,
) -> Study {
    let mut summary = summarize(&traces, config.scenario.dim());
    if let Some(coin) = coin {
        summary.attach_coin(coin);
    }
    Study {
        config,
        traces,
        summary,
    }
}
