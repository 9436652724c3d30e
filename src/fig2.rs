//! The paper's fig. 2 study: how the sampled-SDP bound approaches nmCI on the 2-D example as
//! the sample set grows, and when it is non-conservative.
//!
//! `P_a = diag(3, 1)`, `P_b = diag(1, 4)`, diagonal `P_ab`. For each run, a "true" `P_ab` is
//! drawn with the sampler; for each sample-set size `N`, a sample set is drawn and the sampled
//! SDP (paper eq. (sampled_sdp), solved exactly with the working set) gives `P_opt`, `K_opt`.
//! Recorded: `‖P_nmCI − P_opt‖₂`, and for each rule `λ_min(P − K P_true Kᵀ)` (negative =
//! not conservative for the true cross-covariance) and its conservativeness index
//! `COIN = λ_max(L⁻¹ K P_true Kᵀ L⁻ᵀ)`, `P = L Lᵀ` (`> 1` = not conservative; a scale-free
//! "how much": `1.1` means 10 % too small along the worst direction). Runs are independent (run `r` uses seeds
//! derived from `(seed, r)`), so any subset of runs can be computed anywhere, in any order.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use serde::{Deserialize, Serialize};

use crate::chart::{Axis, Band, Chart, Line};
#[cfg(all(feature = "files", not(target_arch = "wasm32")))]
use crate::error::ReportError;
use crate::error::RequestError;
use crate::fusion::check::{fused_coin, margin};
use crate::fusion::nmci::non_monolithic_ci;
use crate::fusion::sample::{sample_cross_covariances, SamplerSettings};
use crate::fusion::sdp::{optimal_fusion_for_samples, SdpSettings};
use crate::fusion::{Criterion, FusionProblem};
use crate::structure::CrossPattern;

/// The study's settings (every key optional in JSON; unknown keys are rejected).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Fig2Config {
    /// Monte Carlo runs (default 1000).
    pub runs: usize,
    /// Sample-set sizes (default 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000).
    pub sizes: Vec<usize>,
    /// Seed.
    pub seed: u64,
}

impl Default for Fig2Config {
    fn default() -> Self {
        Self {
            runs: 1000,
            sizes: vec![1, 2, 5, 10, 20, 50, 100, 200, 500, 1000],
            seed: 0,
        }
    }
}

/// The most runs of one fig. 2 study: every run's records are kept until the summary, and a
/// run solves one sampled SDP per size (the paper's 1000 runs take seconds here).
pub const MAX_FIG2_RUNS: usize = 100_000;

/// The most sample-set sizes of one fig. 2 study.
pub const MAX_FIG2_SIZES: usize = 64;

impl Fig2Config {
    /// Checks the settings: at least one run and at most [`MAX_FIG2_RUNS`]; one to
    /// [`MAX_FIG2_SIZES`] sizes, each from 1 to the sampled SDP's
    /// [`MAX_SAMPLES`](crate::contract::MAX_SAMPLES).
    pub fn validate(&self) -> Result<(), RequestError> {
        if self.runs == 0 {
            return Err(RequestError::invalid("runs", "fig2 needs at least one run"));
        }
        if self.runs > MAX_FIG2_RUNS {
            return Err(RequestError::invalid(
                "runs",
                format!(
                    "fig2 takes at most {MAX_FIG2_RUNS} runs (got {})",
                    self.runs
                ),
            ));
        }
        if self.sizes.is_empty() || self.sizes.contains(&0) {
            return Err(RequestError::invalid(
                "sizes",
                "fig2 needs sample-set sizes of at least 1",
            ));
        }
        if self.sizes.len() > MAX_FIG2_SIZES {
            return Err(RequestError::invalid(
                "sizes",
                format!(
                    "fig2 takes at most {MAX_FIG2_SIZES} sample-set sizes (got {})",
                    self.sizes.len()
                ),
            ));
        }
        if let Some(&n) = self
            .sizes
            .iter()
            .find(|&&n| n > crate::contract::MAX_SAMPLES)
        {
            return Err(RequestError::invalid(
                "sizes",
                format!(
                    "a sample-set size of {n} is above the sampled SDP's limit of {} samples",
                    crate::contract::MAX_SAMPLES
                ),
            ));
        }
        Ok(())
    }
}

/// One run at one sample-set size: `None` fields when the SDP failed (counted, not dropped).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fig2Record {
    /// Sample-set size `N`.
    pub samples: usize,
    /// `‖P_nmCI − P_opt‖₂` (spectral norm).
    pub deviation: Option<f64>,
    /// `λ_min(P_nmCI − K_nmCI P_true K_nmCIᵀ)`.
    pub eig_nmci: f64,
    /// `λ_min(P_opt − K_opt P_true K_optᵀ)`.
    pub eig_opt: Option<f64>,
    /// nmCI's COIN for the true `P_ab`.
    pub coin_nmci: f64,
    /// The sampled SDP's COIN for the true `P_ab`.
    pub coin_opt: Option<f64>,
    /// The solver's message when the SDP failed.
    pub failure: Option<String>,
}

/// The paper's example.
pub fn fig2_problem() -> FusionProblem {
    let d = |v: [f64; 2]| DMatrix::from_diagonal(&DVector::from_row_slice(&v));
    FusionProblem::new_trusted(
        DVector::zeros(2),
        d([3.0, 1.0]),
        DVector::zeros(2),
        d([1.0, 4.0]),
        CrossPattern::diagonal(2),
    )
}

/// Seeds of run `r`: one for the true `P_ab`, one per size for the sample set.
fn run_seed(seed: u64, run: usize, slot: usize) -> u64 {
    // SplitMix64 of (seed, run, slot): independent, reproducible streams.
    let mut z = seed
        .wrapping_add((run as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add((slot as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Run `run` of the study: one record per size.
#[allow(non_snake_case)]
pub fn fig2_run(config: &Fig2Config, run: usize) -> Result<Vec<Fig2Record>, RequestError> {
    config.validate()?;
    let problem = fig2_problem();
    let sampler = SamplerSettings::default();
    let truth = sample_cross_covariances(&problem, 1, run_seed(config.seed, run, 0), sampler)?;
    let P_true = &truth.cross[0];
    let nm = non_monolithic_ci(&problem, Criterion::Trace)?;
    let eig_nmci = margin(&problem, &nm.fused, P_true);
    let coin_nmci = fused_coin(&problem, &nm.fused, P_true)?;
    let mut records = Vec::with_capacity(config.sizes.len());
    for (k, &samples) in config.sizes.iter().enumerate() {
        let set = sample_cross_covariances(
            &problem,
            samples,
            run_seed(config.seed, run, k + 1),
            sampler,
        )?;
        let settings = SdpSettings {
            samples,
            ..SdpSettings::default()
        };
        let record = match optimal_fusion_for_samples(&problem, &set, &settings) {
            Ok(opt) => Fig2Record {
                samples,
                deviation: Some(spectral_norm(&(&nm.fused.P - &opt.fused.P))),
                eig_nmci,
                eig_opt: Some(margin(&problem, &opt.fused, P_true)),
                coin_nmci,
                coin_opt: Some(fused_coin(&problem, &opt.fused, P_true)?),
                failure: None,
            },
            Err(e) => Fig2Record {
                samples,
                deviation: None,
                eig_nmci,
                eig_opt: None,
                coin_nmci,
                coin_opt: None,
                failure: Some(e.to_string()),
            },
        };
        records.push(record);
    }
    Ok(records)
}

/// `‖A‖₂` of a symmetric matrix (largest absolute eigenvalue).
fn spectral_norm(a: &DMatrix<f64>) -> f64 {
    let sym = (a + a.transpose()) * 0.5;
    SymmetricEigen::new(sym).eigenvalues.amax()
}

/// One row of `fig2.csv`: the distribution over runs at one sample-set size.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fig2Row {
    /// Sample-set size `N`.
    pub samples: usize,
    /// Median, minimum and maximum of `‖P_nmCI − P_opt‖₂` over the runs that solved.
    pub dev: [f64; 3],
    /// The same for `λ_min(P_nmCI − K P_true Kᵀ)`.
    pub eig_nmci: [f64; 3],
    /// The same for `λ_min(P_opt − K P_true Kᵀ)`.
    pub eig_opt: [f64; 3],
    /// The same for nmCI's COIN.
    pub coin_nmci: [f64; 3],
    /// The same for the sampled SDP's COIN.
    pub coin_opt: [f64; 3],
    /// Runs whose SDP failed.
    pub failures: usize,
}

/// Median, minimum, maximum (NaN for no values).
fn median_min_max(mut v: Vec<f64>) -> [f64; 3] {
    if v.is_empty() {
        return [f64::NAN; 3];
    }
    v.sort_by(f64::total_cmp);
    let m = v.len();
    let median = if m % 2 == 1 {
        v[m / 2]
    } else {
        0.5 * (v[m / 2 - 1] + v[m / 2])
    };
    [median, v[0], v[m - 1]]
}

/// Aggregates runs (each the records of [`fig2_run`]) into one row per size.
pub fn fig2_summary(config: &Fig2Config, runs: &[Vec<Fig2Record>]) -> Vec<Fig2Row> {
    config
        .sizes
        .iter()
        .enumerate()
        .map(|(k, &samples)| {
            let at: Vec<&Fig2Record> = runs.iter().filter_map(|r| r.get(k)).collect();
            Fig2Row {
                samples,
                dev: median_min_max(at.iter().filter_map(|r| r.deviation).collect()),
                eig_nmci: median_min_max(at.iter().map(|r| r.eig_nmci).collect()),
                eig_opt: median_min_max(at.iter().filter_map(|r| r.eig_opt).collect()),
                coin_nmci: median_min_max(at.iter().map(|r| r.coin_nmci).collect()),
                coin_opt: median_min_max(at.iter().filter_map(|r| r.coin_opt).collect()),
                failures: at.iter().filter(|r| r.failure.is_some()).count(),
            }
        })
        .collect()
}

/// The size of each of `fig2.svg`'s two panels (`nmci fig2` and the page's export).
pub const FIG2_SVG_SIZE: (u32, u32) = (900, 400);

/// `fig2.csv`: `samples, dev_median, dev_min, dev_max, eig_nmci_median, …, failures` (the
/// issue's columns), then the COIN columns `coin_nmci_median, …, coin_opt_max`.
pub fn fig2_csv(rows: &[Fig2Row]) -> String {
    let mut csv = String::from(
        "samples,dev_median,dev_min,dev_max,eig_nmci_median,eig_nmci_min,eig_nmci_max,eig_opt_median,eig_opt_min,eig_opt_max,failures,coin_nmci_median,coin_nmci_min,coin_nmci_max,coin_opt_median,coin_opt_min,coin_opt_max\n",
    );
    for r in rows {
        let f = |v: &[f64; 3]| format!("{:e},{:e},{:e}", v[0], v[1], v[2]);
        csv += &format!(
            "{},{},{},{},{},{},{}\n",
            r.samples,
            f(&r.dev),
            f(&r.eig_nmci),
            f(&r.eig_opt),
            r.failures,
            f(&r.coin_nmci),
            f(&r.coin_opt)
        );
    }
    csv
}

/// Writes `fig2.csv` ([`fig2_csv`]) and the two-panel `fig2.svg` of `runs` runs into `out`
/// (created if missing): what `nmci fig2` writes. Returns the files. Native only, feature
/// `files`.
#[cfg(all(feature = "files", not(target_arch = "wasm32")))]
pub fn write_fig2(
    rows: &[Fig2Row],
    runs: usize,
    out: &std::path::Path,
) -> Result<Vec<std::path::PathBuf>, ReportError> {
    std::fs::create_dir_all(out).map_err(|e| ReportError::Create {
        path: out.to_path_buf(),
        message: e.to_string(),
    })?;
    let csv = out.join("fig2.csv");
    std::fs::write(&csv, fig2_csv(rows)).map_err(|e| ReportError::Write {
        path: csv.clone(),
        message: e.to_string(),
    })?;
    let svg = out.join("fig2.svg");
    fig2_chart(&svg, rows, runs)?;
    Ok(vec![csv, svg])
}

/// The paper's fig. 2 layout ([`crate::fig2::fig2_charts`], the charts the page draws): top,
/// `‖P_nmCI − P_opt‖₂` against the sample-set size (log–log, median with min and max);
/// bottom, `λ_min(P − K P_true Kᵀ)` of nmCI and of the SDP.
#[cfg(all(feature = "files", not(target_arch = "wasm32")))]
fn fig2_chart(path: &std::path::Path, rows: &[Fig2Row], runs: usize) -> Result<(), ReportError> {
    let [dev, eig] = fig2_charts(rows, runs);
    crate::chart::write_svg(path, &[&dev, &eig], FIG2_SVG_SIZE)
}

/// Fig. 2's two charts from its summary rows over `runs` runs: `‖P_nmCI − P_opt‖₂` against
/// the sample-set size (log–log: median line with dots, min–max band), and
/// `λ_min(P − K P_true Kᵀ)` of nmCI and of the sampled SDP (the zero line dashed: below it,
/// not conservative for the true `P_ab`).
pub fn fig2_charts(rows: &[Fig2Row], runs: usize) -> [Chart; 2] {
    let sizes: Vec<f64> = rows.iter().map(|r| r.samples as f64).collect();
    let (x_lo, x_hi) = sizes
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    // Both charts on the same sample-size axis (the sizes, widened by a factor 1.25).
    let x_range = x_lo.is_finite().then_some((x_lo / 1.25, x_hi * 1.25));
    let x = || Axis {
        label: "samples N".into(),
        log: true,
        range: x_range,
    };
    let median_band = |label: &str, colour: &str, pick: &dyn Fn(&Fig2Row) -> [f64; 3]| {
        let col = |k: usize| rows.iter().map(|r| pick(r)[k]).collect::<Vec<f64>>();
        (
            Band {
                label: None,
                colour: colour.into(),
                opacity: 0.18,
                x: sizes.clone(),
                lower: col(1),
                upper: col(2),
            },
            Line {
                label: Some(label.into()),
                colour: colour.into(),
                width: 2,
                dashed: false,
                dots: true,
                points: sizes.iter().copied().zip(col(0)).collect(),
            },
        )
    };
    let (sdp, nmci) = (
        crate::rules::Method::Sdp.info(),
        crate::rules::Method::Nmci.info(),
    );
    let (dev_band, dev_line) = median_band("sampled SDP vs nmCI", sdp.colour, &|r| r.dev);
    let (opt_band, opt_line) = median_band(sdp.label, sdp.colour, &|r| r.eig_opt);
    let (nm_band, nm_line) = median_band(nmci.label, nmci.colour, &|r| r.eig_nmci);
    let zero = Line {
        label: None,
        colour: "#000000".into(),
        width: 1,
        dashed: true,
        dots: false,
        points: x_range.map_or(Vec::new(), |(lo, hi)| vec![(lo, 0.0), (hi, 0.0)]),
    };
    [
        Chart {
            title: format!("‖P_nmCI − P_opt‖₂ over {runs} runs (median; band: min to max)"),
            x: x(),
            y: Axis {
                label: "deviation".into(),
                log: true,
                range: None,
            },
            bands: vec![dev_band],
            lines: vec![dev_line],
        },
        Chart {
            title: "λ_min(P − K P_true Kᵀ): below 0 = not conservative for the true P_ab".into(),
            x: x(),
            y: Axis {
                label: "λ_min".into(),
                log: false,
                range: None,
            },
            bands: vec![opt_band, nm_band],
            lines: vec![zero, opt_line, nm_line],
        },
    ]
}
