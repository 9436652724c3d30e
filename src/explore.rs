//! The explorer's analysis of one state: every rule, the optimal bound, the region of
//! possible true fused covariances and each rule's conservativeness over it — one call, so the
//! page (in a Web Worker) and the native tests compute exactly the same numbers.

use std::collections::BTreeMap;

use nalgebra::DMatrix;
use serde::de::IgnoredAny;
use serde::{Deserialize, Serialize};

use crate::api::{
    certificate_response, check_blocks, check_count, fuse_planned, sdp_response, structured,
    unknown_field, ClosedForm, CovarianceSummary, Details, FuseRequest, FuseResponse, Gains,
    Options, PairInput, StructureDetails, Structured, MAX_SAMPLES,
};
use crate::error::RequestError;
use crate::fusion::bracket::{
    bracket_certificate, trace_upper_bound, Bracket, UpperBounds, BRACKET_CERTIFY_MAX_BLOCK,
    CLOSED_RTOL,
};
use crate::fusion::certify::{CertificateMemo, Certificates};
use crate::fusion::check::{fused_coins, lowest_margin};
use crate::fusion::cuts::CutsStop;
use crate::fusion::known::known_fusion;
use crate::fusion::rules::{Method, RULES};
use crate::fusion::sample::{sample_cross_covariances, AutoChoice};
use crate::fusion::{Fused, FusionProblem};

/// What the explorer asks for: the two estimates, the [`Options`] of `fuse` (the criterion of
/// CI, nmCI and ICI; the SDP's `samples`, `seed`, `max_trials`, `sampler`; the certified
/// rule's `level`, `sectors`; `time_limit`), with their defaults, and the region.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "ExploreRequestWire")]
pub struct ExploreRequest {
    /// The two estimates.
    #[serde(flatten)]
    pub pair: PairInput,
    /// The options, as `fuse` takes them.
    #[serde(flatten)]
    pub options: Options,
    /// Admissible cross-covariances drawn for the region and the margins (default 300; 0 =
    /// none), with the SDP's sampler and an independent stream of its seed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub region_samples: Option<usize>,
}

/// The region's default size.
const REGION_SAMPLES: usize = 300;

/// [`ExploreRequest`] as read: its parts, then whatever none of them took.
#[derive(Deserialize)]
struct ExploreRequestWire {
    #[serde(flatten)]
    pair: PairInput,
    #[serde(flatten)]
    options: Options,
    #[serde(default)]
    region_samples: Option<usize>,
    #[serde(flatten)]
    unknown: BTreeMap<String, IgnoredAny>,
}

impl TryFrom<ExploreRequestWire> for ExploreRequest {
    type Error = String;

    fn try_from(w: ExploreRequestWire) -> Result<Self, String> {
        let every_field = ExploreRequest {
            pair: PairInput::every_field(),
            options: Options::every_field(),
            region_samples: Some(1),
        };
        unknown_field(&w.unknown, &every_field)?;
        Ok(ExploreRequest {
            pair: w.pair,
            options: w.options,
            region_samples: w.region_samples,
        })
    }
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
    pub upper_rule: Method,
    /// `upper − lower`, rounded up.
    pub absolute: f64,
    /// `(upper − lower) / upper`.
    pub relative: f64,
    /// Whether `absolute ≤ 10⁻⁶ · upper` ([`CLOSED_RTOL`], [`Bracket::closed`]): the robust
    /// optimum is proven to that accuracy, and `upper_rule` attains it.
    pub closed: bool,
    /// The certified rule's certificate on each block (when computed; JSON `levels` and
    /// `sectors`).
    #[serde(flatten)]
    pub certificates: Option<Certificates>,
}

impl Gap {
    /// The gap of a proven bracket, with the certified rule's certificates (when computed).
    fn of(b: &Bracket, certificates: Option<Certificates>) -> Gap {
        Gap {
            lower: b.lower,
            upper: b.upper,
            upper_rule: b.upper_rule.into(),
            absolute: b.gap(),
            relative: b.gap_relative(),
            closed: b.closed(CLOSED_RTOL),
            certificates,
        }
    }
}

/// The explorer's second stage ([`prove`]): the cutting-plane SDP's proven bracket.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Proof {
    /// The bracket: the loop's Lagrangian bound below, the best proven rule above (CI, nmCI,
    /// or the certified rule — the loop's own rule when `own_rule_proven`).
    #[serde(flatten)]
    pub gap: Gap,
    /// Whether the upper end is the loop's own rule, proven on cones of directions (then
    /// `levels` is `[1]` and `sectors` the number of cones).
    pub own_rule_proven: bool,
    /// Why the loop stopped (`time_limit`: the bracket is the best one proven by then).
    pub stop: CutsStop,
    /// The loop's outer iterations.
    pub iterations: u32,
    /// Rounds in which the own rule's proof pointed the loop to cuts its search had missed
    /// ([`crate::sdp::CutsResult::proof_rounds`]).
    pub proof_rounds: usize,
    /// The loop's gain with the bound proven for it (`sdp_cuts`' `gain_certified_p`): the
    /// rule to carry on (the page's JSON export holds it); absent when there is none (past the
    /// time limit).
    pub rule: Option<ProvenGain>,
}

/// A gain `K = [K_a K_b]` with a bound `P̄` proven to dominate `K J Kᵀ` for every admissible
/// joint covariance `J`, rounding included (`fusion::bracket`, "A given gain's bound").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProvenGain {
    /// `K_a`, nested rows.
    pub ka: Vec<Vec<f64>>,
    /// `K_b = I − K_a`, nested rows.
    pub kb: Vec<Vec<f64>>,
    /// `P̄`, nested rows.
    pub p: Vec<Vec<f64>>,
    /// `tr P̄`, rounded up.
    pub trace: f64,
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

/// One rule's part of an [`Exploration`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RuleReport {
    /// The rule (its label, colour and guarantee: [`Method::info`]).
    pub method: Method,
    /// Its response, as `fuse` gives it (absent when it could not be computed).
    pub response: Option<FuseResponse>,
    /// Why it could not be computed (a block above the certified rule's limit, the sampler's
    /// budget, the solver's status).
    pub error: Option<String>,
    /// The worst `λ_min(P̄ − K P' Kᵀ)` over the region's cross-covariances (negative: not
    /// conservative for some drawn `P'`); absent without a region or a response.
    pub margin: Option<f64>,
    /// Its COIN over the region's cross-covariances.
    pub coin: Option<CoinStats>,
}

/// Everything the explorer shows for one state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Exploration {
    /// State dimension.
    pub n: usize,
    /// The two estimates' covariances summarised as the rules' responses are (`trace`,
    /// `det`): `P_a`, then `P_b`.
    pub estimates: [CovarianceSummary; 2],
    /// Every rule the explorer computes ([`crate::rules::RuleInfo::explorer`]), in
    /// [`crate::rules::RULES`] order. CI, nmCI and ICI use the request's criterion; the SDP and the
    /// certified rule (blocks of at most [`BRACKET_CERTIFY_MAX_BLOCK`] states) minimise the
    /// trace.
    pub rules: Vec<RuleReport>,
    /// SDP lower bound vs the best certified upper bound (CI, nmCI or the certified rule).
    pub gap: Option<Gap>,
    /// Region samples drawn.
    pub region_count: usize,
    /// Their acceptance rate.
    pub region_acceptance_rate: Option<f64>,
    /// With `sampler: "auto"`: the sampler that drew the region and why.
    pub region_sampler_choice: Option<AutoChoice>,
    /// Why the region could not be drawn.
    pub region_error: Option<String>,
    /// How the problem's blocks were found, when that is worth saying (nmCI's and the
    /// certified rule's `structure`: near-zero couplings absorbed, declared blocks, or a weak
    /// coupling keeping blocks merged); the page shows its note beside the numbers.
    pub structure: Option<StructureDetails>,
    /// The region: `region_count` optimal known-correlation covariances `P*`, each `n × n`
    /// row-major, concatenated (the wasm layer hands it over as a `Float64Array`).
    #[serde(skip)]
    pub region: Vec<f64>,
}

impl Exploration {
    /// The report of `method` (absent when the explorer does not compute it).
    pub fn rule(&self, method: Method) -> Option<&RuleReport> {
        self.rules.iter().find(|r| r.method == method)
    }

    /// The response of `method`, when it was computed.
    pub fn response(&self, method: Method) -> Option<&FuseResponse> {
        self.rule(method).and_then(|r| r.response.as_ref())
    }
}

/// A rule's response and fused result, or why it could not be computed.
type Outcome = Result<(FuseResponse, Fused), String>;

/// Mixes the SDP seed into an independent stream for the region samples.
fn region_seed(seed: u64) -> u64 {
    seed ^ 0x9E37_79B9_7F4A_7C15
}

/// Analyses one explorer state.
///
/// ```
/// let req: nmci::explore::ExploreRequest = serde_json::from_str(r#"{"pa": [[3,0],[0,1]],
///     "pb": [[1,0],[0,4]], "pab_unknown": [[true,false],[false,true]], "samples": 50}"#).unwrap();
/// let a = nmci::explore::explore(&req).unwrap();
/// assert_eq!(a.response(nmci::rules::Method::Nmci).unwrap().trace, 2.0);
/// assert!(a.gap.unwrap().absolute.abs() < 1e-6);
/// assert_eq!(a.region.len(), 300 * 4);
/// ```
pub fn explore(request: &ExploreRequest) -> Result<Exploration, RequestError> {
    analyse(request, None)
}

/// [`explore`] with the certified rule's blocks certified before taken from `memo` (and the
/// new ones added): the same analysis, bit for bit; an edit inside one independent block then
/// solves that block's certificate alone (the page keeps one memo per worker).
///
/// ```
/// let req: nmci::explore::ExploreRequest = serde_json::from_str(r#"{"pa": [[3,0],[0,1]],
///     "pb": [[1,0],[0,4]], "pab_unknown": [[true,false],[false,true]], "samples": 50}"#).unwrap();
/// let mut memo = nmci::certify::CertificateMemo::new();
/// let first = nmci::explore::explore_with_memo(&req, &mut memo).unwrap();
/// assert_eq!(first, nmci::explore::explore(&req).unwrap());
/// assert_eq!(nmci::explore::explore_with_memo(&req, &mut memo).unwrap(), first);
/// assert!(memo.hits() > 0);
/// ```
pub fn explore_with_memo(
    request: &ExploreRequest,
    memo: &mut CertificateMemo,
) -> Result<Exploration, RequestError> {
    analyse(request, Some(memo))
}

/// The explorer's second stage: the cutting-plane SDP (`sdp_cuts`, as `fuse` runs it, with the
/// request's options that apply to it: `seed`, `time_limit`, the certificate's) on the same
/// state, for its proven bracket, stopped as soon as that is closed to [`CLOSED_RTOL`]
/// ([`crate::fusion::cuts::CutsSettings::bracket_rtol`]: the page wants the bracket, not the
/// loop's `P̄`). Its
/// lower end is the Lagrangian bound of the loop's constraints (worst cases found, not drawn
/// at random); on one block of three states its
/// upper end is the loop's own rule, proven on cones of directions
/// ([`crate::certify::certify_rule`]). The page runs it after [`explore`] when the bracket is
/// open at `n ≤ 4` (`www/prove-client.js`, `PROVE_MAX_N`), where it can close it. `None` when
/// the loop has no bracket.
///
/// ```
/// let req: nmci::explore::ExploreRequest = serde_json::from_str(r#"{"pa": [[3,0],[0,1]],
///     "pb": [[1,0],[0,4]], "pab_unknown": [[true,true],[true,false]]}"#).unwrap();
/// let proof = nmci::explore::prove(&req).unwrap().unwrap();
/// assert!(proof.gap.closed && proof.gap.lower <= proof.gap.upper);
/// ```
pub fn prove(request: &ExploreRequest) -> Result<Option<Proof>, RequestError> {
    let fuse_request = FuseRequest {
        pair: request.pair.clone(),
        method: Method::SdpCuts,
        options: request.options.for_method(Method::SdpCuts),
        estimates: None,
        patterns: None,
    };
    // The page wants the bracket closed: the loop stops as soon as it is, to `CLOSED_RTOL`.
    let mut plan = fuse_request.plan()?;
    plan.cuts.bracket_rtol = Some(CLOSED_RTOL);
    let response = fuse_planned(&fuse_request, &plan)?;
    let (Details::SdpCuts(d), Gains::Pair { ka, kb }) = (response.details, response.gains) else {
        unreachable!("method sdp_cuts answers with its details and a pair of gains")
    };
    let rule = d
        .gain_certified_p
        .zip(d.gain_certified_trace)
        .map(|(p, trace)| ProvenGain { ka, kb, p, trace });
    Ok(d.bracket.as_ref().map(|b| Proof {
        gap: Gap::of(b, d.certificates.clone()),
        own_rule_proven: d.own_rule_proven,
        stop: d.stop,
        iterations: d.iterations,
        proof_rounds: d.proof_rounds,
        rule,
    }))
}

#[allow(non_snake_case)]
fn analyse(
    request: &ExploreRequest,
    memo: Option<&mut CertificateMemo>,
) -> Result<Exploration, RequestError> {
    // The explorer solves the sampled SDP of every state: its limits apply.
    request
        .pair
        .check_sizes(Method::Sdp.info().limits.max_dim, &"the explorer")?;
    let problem = request.pair.problem()?;
    // nmCI and the certified rule solve the problem with its near-zero couplings absorbed
    // (`structure::absorb`), the SDP the deflated one; the bracket's upper ends (from the
    // absorbed problem) and its lower end (from the deflated one) are proven for the given one.
    let settings = request.pair.structure_settings();
    // `relaxed`: the sampled SDP's problem, the deflated one when couplings were absorbed (its
    // proven lower end holds for the given problem), the given one otherwise.
    let Structured {
        problem: absorbed,
        relaxed,
        details: structure,
        ..
    } = structured(problem.clone(), &settings, Method::Nmci)?;
    let relaxed = relaxed.unwrap_or_else(|| problem.clone());
    check_blocks(Method::Sdp, &relaxed)?;
    let plan = request.options.plan()?;
    check_count(
        "region_samples",
        request.region_samples.filter(|&r| r > 0),
        MAX_SAMPLES,
    )?;
    let n = problem.dim();
    let criterion = plan.criterion;
    let certificate = bracket_certificate(&absorbed, &plan.certify, memo);
    let certified_P = match &certificate {
        Ok(Some(cert)) => Some(&cert.fused.P),
        _ => None,
    };
    // The proven upper ends: CI and nmCI (trace criterion) and the certified rule.
    let uppers = UpperBounds::of_absorbed(&problem, &absorbed, certified_P.map(trace_upper_bound))?;

    let mut computed: Vec<(Method, Outcome)> = Vec::new();
    for rule in RULES.iter().filter(|r| r.explorer) {
        let outcome = match rule.method {
            Method::Ci => Ok(ClosedForm::Ci.response(&problem, criterion)?),
            Method::Nmci => {
                let (mut r, fused) = ClosedForm::Nmci.response(&absorbed, criterion)?;
                r.structure = structure.clone();
                Ok((r, fused))
            }
            Method::Ici => Ok(ClosedForm::Ici.response(&problem, criterion)?),
            Method::Ei => Ok(ClosedForm::Ei.response(&problem, criterion)?),
            Method::Naive => Ok(ClosedForm::Naive.response(&problem, criterion)?),
            Method::Certified => match &certificate {
                Ok(Some(cert)) => {
                    let mut r = certificate_response(cert);
                    r.structure = structure.clone();
                    Ok((r, cert.fused.clone()))
                }
                Ok(None) => Err(format!(
                    "the explorer certifies independent blocks of at most {BRACKET_CERTIFY_MAX_BLOCK} states (the level-1 program grows as (2n² + 1)²); method \"certified\" of the CLI takes up to 6"
                )),
                Err(e) => Err(e.to_string()),
            },
            // The page never shows the SDP's own-gain certificate: not computed here.
            Method::Sdp => {
                sdp_response(&relaxed, &absorbed, &plan, Some(uppers), false)
                    .map_err(|e| e.to_string())
            }
            Method::SdpCuts => Err("the explorer does not run the cutting-plane SDP".into()),
        };
        computed.push((rule.method, outcome));
    }
    let sdp = computed.iter().find_map(|(m, o)| match (m, o) {
        (Method::Sdp, Ok((r, _))) => Some(r),
        _ => None,
    });
    let gap = sdp.and_then(|s| s.bracket()).map(|b| {
        let certificates = match &certificate {
            Ok(Some(cert)) => Some(Certificates::of(cert)),
            _ => None,
        };
        Gap::of(b, certificates)
    });

    let region_samples = request.region_samples.unwrap_or(REGION_SAMPLES);
    let mut region = Vec::new();
    let (mut region_count, mut region_acceptance_rate, mut region_error) = (0, None, None);
    let mut region_sampler_choice = None;
    let mut drawn_cross = None;
    if region_samples > 0 {
        let seed = region_seed(plan.sdp.seed);
        match sample_cross_covariances(&problem, region_samples, seed, plan.sdp.sampler) {
            Ok(drawn) => {
                region.reserve(drawn.len() * n * n);
                for P_ab in &drawn.cross {
                    let best = known_fusion(&problem, P_ab);
                    region.extend(rows_flat(&best.P));
                }
                region_count = drawn.len();
                region_acceptance_rate = Some(drawn.acceptance_rate());
                region_sampler_choice = drawn.auto;
                drawn_cross = Some(drawn.cross);
            }
            Err(e) => region_error = Some(e.to_string()),
        }
    }
    let rules = computed
        .into_iter()
        .map(|(method, outcome)| {
            let (response, fused, error) = match outcome {
                Ok((r, f)) => (Some(r), Some(f), None),
                Err(e) => (None, None, Some(e)),
            };
            let (margin, coin) = match (&fused, &drawn_cross) {
                (Some(f), Some(cross)) => (
                    Some(lowest_margin(&problem, f, cross)),
                    Some(coin_stats(&problem, f, cross)?),
                ),
                _ => (None, None),
            };
            Ok(RuleReport {
                method,
                response,
                error,
                margin,
                coin,
            })
        })
        .collect::<Result<Vec<_>, RequestError>>()?;
    Ok(Exploration {
        n,
        estimates: [
            CovarianceSummary::of("pa", &problem.P_a),
            CovarianceSummary::of("pb", &problem.P_b),
        ],
        rules,
        gap,
        region_count,
        region_acceptance_rate,
        region_sampler_choice,
        region_error,
        structure,
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
    let mut values = fused_coins(problem, fused, cross)?;
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
