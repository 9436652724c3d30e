//! The explorer's analysis of one state: every rule, the optimal bound, the region of
//! possible true fused covariances and each rule's conservativeness over it — one call, so the
//! page (in a Web Worker) and the native tests compute exactly the same numbers.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::api::{
    bracket_certificate, certificate_response, ci_response, ei_response, ici_response,
    naive_response, nmci_response, problem_from_parts, sdp_response, upper_bounds, FuseResponse,
    BRACKET_CERTIFY_MAX_BLOCK,
};
use crate::error::RequestError;
use crate::fusion::bracket::CLOSED_RTOL;
use crate::fusion::certify::CertifySettings;
use crate::fusion::check::{fused_coin, worst_margin};
use crate::fusion::known::known_correlation_fusion;
use crate::fusion::sample::{sample_cross_covariances, SamplerKind, SamplerSettings};
use crate::fusion::sdp::SdpSettings;
use crate::fusion::Criterion;
use crate::fusion::{Fused, FusionProblem};

/// What the explorer asks for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExploreRequest {
    /// `P_a`, nested rows.
    pub pa: Vec<Vec<f64>>,
    /// `P_b`, nested rows.
    pub pb: Vec<Vec<f64>>,
    /// `x_a` (default zeros).
    #[serde(default)]
    pub xa: Option<Vec<f64>>,
    /// `x_b` (default zeros).
    #[serde(default)]
    pub xb: Option<Vec<f64>>,
    /// Pattern of `P_ab` (`true` = may be non-zero; default all `true`).
    #[serde(default)]
    pub pab_unknown: Option<Vec<Vec<bool>>>,
    /// Criterion of CI and nmCI (default `trace`; the SDP always minimises the trace).
    #[serde(default)]
    pub criterion: Option<Criterion>,
    /// Samples of the optimal bound's SDP (default 200).
    #[serde(default)]
    pub samples: Option<usize>,
    /// Seed of the SDP's samples (default 0); the region uses an independent stream.
    #[serde(default)]
    pub seed: Option<u64>,
    /// Admissible cross-covariances drawn for the region and the margins (default 300; 0 = none).
    #[serde(default)]
    pub region_samples: Option<usize>,
    /// Rejection-sampler budget per sample set (default 200 000: interactive use).
    #[serde(default)]
    pub max_trials: Option<u64>,
    /// `rejection` (the paper's sampler, default) or `hit_and_run` (any dimension), for the
    /// SDP's samples and the region's.
    #[serde(default)]
    pub sampler: Option<SamplerKind>,
}

/// Proven bounds on the robust optimum of `tr P̄` (`fusion::bracket`): the sampled SDP's
/// Lagrangian bound below, the best conservative rule above (the `lower_bound` /
/// `upper_bound` of the SDP response).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gap {
    /// A proven lower bound on the robust optimum.
    pub lower: f64,
    /// The rounded-up trace of the best conservative rule (a proven upper bound).
    pub upper: f64,
    /// Which rule gives `upper` (`ci`, `nmci` or `certified`).
    pub upper_rule: crate::api::Method,
    /// `upper − lower`, rounded up.
    pub absolute: f64,
    /// `(upper − lower) / upper`.
    pub relative: f64,
    /// Whether `relative ≤ 10⁻⁶` ([`CLOSED_RTOL`]): the robust optimum is proven to that
    /// accuracy, and `upper_rule` attains it.
    pub closed: bool,
    /// The certified rule's level on each block (when computed).
    pub levels: Option<Vec<u32>>,
}

/// Worst `λ_min(P̄ − K P' Kᵀ)` of each rule over the region's cross-covariances.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Margins {
    /// CI.
    pub ci: f64,
    /// nmCI.
    pub nmci: f64,
    /// Sampled SDP (absent when it failed). Negative = not conservative for some drawn `P'`.
    pub sdp: Option<f64>,
    /// The certified rule (absent when not computed).
    pub certified: Option<f64>,
    /// ICI (conservative for common-information correlation only).
    pub ici: f64,
    /// EI (not guaranteed conservative).
    pub ei: f64,
    /// Naive fusion (not conservative for correlated estimates).
    pub naive: f64,
}

/// The conservativeness index of one rule over the region's cross-covariances:
/// `COIN = λ_max(L⁻¹ E L⁻ᵀ)` with `P = L Lᵀ` the rule's bound and `E = K P' Kᵀ` the true
/// fused error covariance for each drawn `P'` (`≤ 1` conservative; closer to 1 = tighter).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CoinStats {
    /// The largest COIN over the drawn `P'` (`> 1`: not conservative for some `P'`).
    pub max: f64,
    /// The median COIN over the drawn `P'`.
    pub median: f64,
}

/// [`CoinStats`] of each rule over the region.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Coins {
    /// CI.
    pub ci: CoinStats,
    /// nmCI.
    pub nmci: CoinStats,
    /// Sampled SDP (absent when it failed).
    pub sdp: Option<CoinStats>,
    /// The certified rule (absent when not computed).
    pub certified: Option<CoinStats>,
    /// ICI.
    pub ici: CoinStats,
    /// EI.
    pub ei: CoinStats,
    /// Naive fusion.
    pub naive: CoinStats,
}

/// Everything the explorer shows for one state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Exploration {
    /// State dimension.
    pub n: usize,
    /// CI.
    pub ci: FuseResponse,
    /// nmCI.
    pub nmci: FuseResponse,
    /// ICI (same criterion as CI; `conservative_for` says for what).
    pub ici: FuseResponse,
    /// Ellipsoidal intersection (not guaranteed conservative).
    pub ei: FuseResponse,
    /// Naive fusion (not guaranteed conservative).
    pub naive: FuseResponse,
    /// The sampled-SDP bound, when it could be computed.
    pub sdp: Option<FuseResponse>,
    /// Why it could not (sampler budget, solver status).
    pub sdp_error: Option<String>,
    /// The certified rule (proven conservative; blocks of at most
    /// [`BRACKET_CERTIFY_MAX_BLOCK`] states).
    pub certified: Option<FuseResponse>,
    /// Why it was not computed (a larger block, or the solver).
    pub certified_error: Option<String>,
    /// SDP lower bound vs the best certified upper bound (CI, nmCI or the certified rule).
    pub gap: Option<Gap>,
    /// Region samples drawn.
    pub region_count: usize,
    /// Their acceptance rate.
    pub region_acceptance_rate: Option<f64>,
    /// Why the region could not be drawn.
    pub region_error: Option<String>,
    /// Conservativeness of each rule over the region's cross-covariances.
    pub margins: Option<Margins>,
    /// Each rule's conservativeness index over the region's cross-covariances.
    pub coin: Option<Coins>,
    /// The region: `region_count` optimal known-correlation covariances `P*`, each `n × n`
    /// row-major, concatenated (the wasm layer hands it over as a `Float64Array`).
    #[serde(skip)]
    pub region: Vec<f64>,
}

/// Mixes the SDP seed into an independent stream for the region samples.
fn region_seed(seed: u64) -> u64 {
    seed ^ 0x9E37_79B9_7F4A_7C15
}

/// Analyses one explorer state.
///
/// ```
/// let req: nmci::ExploreRequest = serde_json::from_str(r#"{"pa": [[3,0],[0,1]],
///     "pb": [[1,0],[0,4]], "pab_unknown": [[true,false],[false,true]], "samples": 50}"#).unwrap();
/// let a = nmci::explore(&req).unwrap();
/// assert_eq!(a.nmci.trace, 2.0);
/// assert!(a.gap.unwrap().absolute.abs() < 1e-6);
/// assert_eq!(a.region.len(), 300 * 4);
/// ```
#[allow(non_snake_case)]
pub fn explore(request: &ExploreRequest) -> Result<Exploration, RequestError> {
    let problem = problem_from_parts(
        &request.pa,
        &request.pb,
        request.xa.as_deref(),
        request.xb.as_deref(),
        request.pab_unknown.as_deref(),
    )?;
    let criterion = request.criterion.unwrap_or_default();
    let samples = request.samples.unwrap_or(200);
    if samples == 0 {
        return Err(RequestError::Invalid("`samples` must be at least 1".into()));
    }
    let max_trials = request.max_trials.unwrap_or(200_000);
    if max_trials == 0 {
        return Err(RequestError::Invalid(
            "`max_trials` must be at least 1".into(),
        ));
    }
    let seed = request.seed.unwrap_or(0);
    let n = problem.dim();
    let sampler = SamplerSettings {
        kind: request.sampler.unwrap_or_default(),
        ..SamplerSettings::rejection(max_trials)
    };

    let (ci, ci_fused) = ci_response(&problem, criterion)?;
    let (nmci, nm_fused) = nmci_response(&problem, criterion)?;
    let (ici, ici_fused) = ici_response(&problem, criterion)?;
    let (ei, ei_fused) = ei_response(&problem)?;
    let (naive, naive_fused) = naive_response(&problem);
    let settings = SdpSettings {
        samples,
        seed,
        sampler,
        ..SdpSettings::default()
    };
    let certify = CertifySettings::default();
    let (certified, certified_fused, certified_error) = match bracket_certificate(&problem, &certify) {
        Ok(Some(cert)) => (Some(certificate_response(&cert)), Some(cert.fused), None),
        Ok(None) => (
            None,
            None,
            Some(format!(
                "the explorer certifies independent blocks of at most {BRACKET_CERTIFY_MAX_BLOCK} states (the level-1 program grows as (2n² + 1)²); method \"certified\" of the CLI takes up to 6"
            )),
        ),
        Err(e) => (None, None, Some(e.to_string())),
    };
    // The proven upper ends: CI and nmCI (trace criterion) and the certified rule.
    let uppers = upper_bounds(&problem, certified_fused.as_ref().map(|f| &f.P))?;
    // The page never shows the SDP's own-gain certificate: not computed here.
    let (sdp, sdp_fused, sdp_error) =
        match sdp_response(&problem, &settings, &certify, Some(uppers), false) {
            Ok((r, f)) => (Some(r), Some(f), None),
            Err(e) => (None, None, Some(e.to_string())),
        };
    let gap = sdp.as_ref().and_then(|s| {
        Some(Gap {
            lower: s.lower_bound?,
            upper: s.upper_bound?,
            upper_rule: s.upper_bound_rule?,
            absolute: s.gap?,
            relative: s.gap_relative?,
            closed: s.gap_relative? <= CLOSED_RTOL,
            levels: certified.as_ref().and_then(|c| c.levels.clone()),
        })
    });

    let region_samples = request.region_samples.unwrap_or(300);
    let mut region = Vec::new();
    let (mut region_count, mut region_acceptance_rate, mut region_error, mut margins, mut coin) =
        (0, None, None, None, None);
    if region_samples > 0 {
        match sample_cross_covariances(&problem, region_samples, region_seed(seed), sampler) {
            Ok(drawn) => {
                region.reserve(drawn.len() * n * n);
                for P_ab in &drawn.cross {
                    let best = known_correlation_fusion(&problem, P_ab);
                    region.extend(rows_flat(&best.P));
                }
                let worst = |f: &Fused| worst_margin(&problem, f, &drawn.cross);
                margins = Some(Margins {
                    ci: worst(&ci_fused),
                    nmci: worst(&nm_fused),
                    sdp: sdp_fused.as_ref().map(worst),
                    certified: certified_fused.as_ref().map(worst),
                    ici: worst(&ici_fused),
                    ei: worst(&ei_fused),
                    naive: worst(&naive_fused),
                });
                let stats = |f: &Fused| coin_stats(&problem, f, &drawn.cross);
                coin = Some(Coins {
                    ci: stats(&ci_fused)?,
                    nmci: stats(&nm_fused)?,
                    sdp: sdp_fused.as_ref().map(stats).transpose()?,
                    certified: certified_fused.as_ref().map(stats).transpose()?,
                    ici: stats(&ici_fused)?,
                    ei: stats(&ei_fused)?,
                    naive: stats(&naive_fused)?,
                });
                region_count = drawn.len();
                region_acceptance_rate = Some(drawn.acceptance_rate());
            }
            Err(e) => region_error = Some(e.to_string()),
        }
    }
    Ok(Exploration {
        n,
        ci,
        nmci,
        ici,
        ei,
        naive,
        sdp,
        sdp_error,
        certified,
        certified_error,
        gap,
        region_count,
        region_acceptance_rate,
        region_error,
        margins,
        coin,
        region,
    })
}

/// COIN of `fused` for every drawn cross-covariance: the largest and the median.
#[allow(non_snake_case)]
fn coin_stats(
    problem: &FusionProblem,
    fused: &Fused,
    cross: &[DMatrix<f64>],
) -> Result<CoinStats, RequestError> {
    let mut values = cross
        .iter()
        .map(|P_ab| fused_coin(problem, fused, P_ab))
        .collect::<Result<Vec<f64>, _>>()?;
    values.sort_by(f64::total_cmp);
    let k = values.len();
    let median = match k {
        0 => f64::NAN,
        _ if k % 2 == 1 => values[k / 2],
        _ => 0.5 * (values[k / 2 - 1] + values[k / 2]),
    };
    Ok(CoinStats {
        max: values.last().copied().unwrap_or(f64::NAN),
        median,
    })
}

#[allow(non_snake_case)]
fn rows_flat(P: &DMatrix<f64>) -> impl Iterator<Item = f64> + '_ {
    (0..P.nrows()).flat_map(move |i| (0..P.ncols()).map(move |j| P[(i, j)]))
}
