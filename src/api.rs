//! The JSON request/response contract shared by `nmci fuse` and the wasm export `fuse`.
//!
//! A request names two estimates, the pattern of `P_ab` and a method — or, for N-way CI and
//! nmCI, a list of `estimates` and the patterns of the pairs' cross-covariances; the response
//! carries the fused estimate, the bound, the gains and everything a user needs to judge it.
//! Unknown fields are rejected.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::error::{InputError, RequestError, SolveError};
use crate::fusion::bracket::{
    bracket_certificate, gain_certified_trace, trace_upper_bound, upper_bounds, UpperBounds,
};
use crate::fusion::certify::{
    certified_fusion, CertifiedResult, CertifySettings, MAX_LEVEL, MAX_SECTORS,
};
use crate::fusion::ci::covariance_intersection;
use crate::fusion::cuts::{optimal_fusion_cuts, CutsSettings, CutsStop};
use crate::fusion::ei::ellipsoidal_intersection;
use crate::fusion::ici::inverse_covariance_intersection;
use crate::fusion::known::naive_fusion;
use crate::fusion::nmci::non_monolithic_ci;
use crate::fusion::nway::{
    covariance_intersection_nway, non_monolithic_ci_nway, NwayResult, PairPattern,
};
use crate::fusion::rules::{methods_phrase, Criteria, Guarantee, Method, RequestOption};
use crate::fusion::sample::{AutoChoice, SamplerKind, SamplerSettings};
use crate::fusion::sdp::{optimal_fusion, SdpSettings, SdpStatus};
use crate::fusion::{Criterion, Estimate, Fused, FusionProblem};
use crate::linalg::{matrix_from_rows, matrix_to_rows};
use crate::structure::{independent_blocks, CrossPattern};

/// The longest request text [`fuse_json`] (and so the CLI and Python's `fuse`) reads: two
/// 1000-state covariances written with full precision take about 50 MB. Checked before the
/// text is parsed; the CLI stops reading past it.
pub const MAX_REQUEST_BYTES: usize = 64 << 20;

/// Most samples an `sdp` request (and the explorer's SDP or region) may ask for.
pub const MAX_SAMPLES: usize = 100_000;

/// Largest rejection-sampler budget (`max_trials`) a request may give: 50 times the default.
pub const MAX_TRIALS: u64 = 100_000_000;

/// Most estimates of an N-way request.
pub const MAX_ESTIMATES: usize = 32;

/// `Err` naming `field` when a request's count is 0 or above `max`.
pub(crate) fn check_count<T: PartialOrd + From<u8> + std::fmt::Display>(
    field: &str,
    value: Option<T>,
    max: T,
) -> Result<(), RequestError> {
    match value {
        Some(v) if v < T::from(1) => Err(RequestError::invalid(
            field,
            format!("`{field}` must be at least 1"),
        )),
        Some(v) if v > max => Err(RequestError::invalid(
            field,
            format!("`{field}` must be at most {max} (got {v})"),
        )),
        _ => Ok(()),
    }
}

/// `Err` naming `field` when a nested-rows input has more than `max` rows, or a row more
/// than `max` entries (before any matrix is built from it).
pub(crate) fn check_rows<T>(
    field: &str,
    rows: &[Vec<T>],
    max: usize,
    who: &str,
) -> Result<(), RequestError> {
    let longest = rows.iter().map(Vec::len).max().unwrap_or(0).max(rows.len());
    if longest > max {
        return Err(RequestError::invalid(
            field,
            format!("{who} accepts at most {max} states (`{field}` has {longest})"),
        ));
    }
    Ok(())
}

/// One estimate of an N-way request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NwayEstimate {
    /// Mean (default zeros).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x: Option<Vec<f64>>,
    /// Covariance, nested rows.
    pub p: Vec<Vec<f64>>,
}

/// The pattern of the cross-covariance `P_ij` of two estimates of an N-way request (pairs not
/// listed are fully unknown).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NwayPair {
    /// First estimate (0-based index into `estimates`).
    pub i: usize,
    /// Second estimate (0-based, `≠ i`).
    pub j: usize,
    /// `n × n`, `true` = `P_ij[r][c]` may be non-zero, `false` = known zero.
    pub pab_unknown: Vec<Vec<bool>>,
}

/// A fusion request (see docs/contract.md for the JSON form): two estimates (`pa`, `pb`, …) or,
/// for N-way CI / nmCI, `estimates` and `patterns`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FuseRequest {
    /// `P_a`, row-major nested rows (required unless `estimates` is given).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pa: Vec<Vec<f64>>,
    /// `P_b`, row-major nested rows (required unless `estimates` is given).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pb: Vec<Vec<f64>>,
    /// `x_a` (default zeros).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub xa: Option<Vec<f64>>,
    /// `x_b` (default zeros).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub xb: Option<Vec<f64>>,
    /// `n × n`, `true` = `P_ab[i][j]` may be non-zero, `false` = known zero (default all `true`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pab_unknown: Option<Vec<Vec<bool>>>,
    /// The rule.
    pub method: Method,
    /// `trace` (default) or `logdet`; `sdp` supports `trace` only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub criterion: Option<Criterion>,
    /// `sdp`: number of sampled cross-covariances (default 200).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// `sdp`: sampler seed (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// `sdp`: rejection-sampler trial budget (default 2 000 000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_trials: Option<u64>,
    /// `sdp`: `rejection` (the paper's, default), `hit_and_run` (any dimension) or `auto`
    /// (rejection where its acceptance is workable, hit-and-run otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampler: Option<SamplerKind>,
    /// `sdp`, `sdp_cuts`, `certified`: wall-clock limit in seconds (default none) of the main
    /// solve and, separately, of each certificate in the response (the bracket's and the
    /// own-gain one). Past it `sdp` and `certified` fail with a time-limit error; `sdp_cuts`
    /// returns its best proven bracket so far with `converged: false` and `stop: "time_limit"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_limit: Option<f64>,
    /// `certified`, `sdp`, `sdp_cuts`: the level of the certified rule (`certified` itself,
    /// and the bracket's upper end); default per block size (`CertifySettings::auto_level`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<u32>,
    /// `certified`, `sdp`, `sdp_cuts`: blocks of two states are certified on this many sectors
    /// of directions (`2..=64`), a level-1 certificate each; default 32 unless `level` is set
    /// (`CertifySettings::sectors`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sectors: Option<u32>,
    /// N-way fusion (methods `ci`, `nmci`): `k ≥ 2` estimates, instead of `pa`, `pb`, `xa`,
    /// `xb`, `pab_unknown`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimates: Option<Vec<NwayEstimate>>,
    /// N-way: the patterns of the pairs' cross-covariances (pairs not listed: fully unknown).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patterns: Option<Vec<NwayPair>>,
}

/// A fusion response.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FuseResponse {
    /// The rule used.
    pub method: Method,
    /// The criterion minimised.
    pub criterion: Criterion,
    /// Fused estimate.
    pub x: Vec<f64>,
    /// Covariance bound, nested rows.
    pub p: Vec<Vec<f64>>,
    /// Gain on `x_a` (two-estimate requests).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ka: Option<Vec<Vec<f64>>>,
    /// Gain on `x_b` (two-estimate requests).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kb: Option<Vec<Vec<f64>>>,
    /// N-way: the gain on each estimate (`x = Σᵢ Kᵢ xᵢ`, `Σᵢ Kᵢ = I`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gains: Option<Vec<Vec<Vec<f64>>>>,
    /// N-way: per block, the weight `ωᵢ` of each estimate (on the simplex).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights: Option<Vec<Vec<f64>>>,
    /// `tr P`.
    pub trace: f64,
    /// `det P`.
    pub det: f64,
    /// CI: `[ω]`; nmCI: one `ω` per block; absent for `sdp`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub omega: Option<Vec<f64>>,
    /// nmCI and sdp: the independent blocks (0-based state indices); the SDP is solved per block.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blocks: Option<Vec<Vec<usize>>>,
    /// `sdp`: number of samples.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// `sdp`, `sdp_cuts`: Clarabel's status, `Solved` or `AlmostSolved`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub status: Option<SdpStatus>,
    /// `sdp`: interior-point iterations (all working-set rounds); `sdp_cuts`: outer iterations;
    /// N-way: Newton iterations (0 when two estimates went to the exact pairwise CI).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iterations: Option<u32>,
    /// `sdp`: rejection-sampler acceptance rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acceptance_rate: Option<f64>,
    /// `sdp` with `sampler: "auto"`: the sampler chosen (`kind`) and the pilot it was chosen by
    /// (`pilot_trials`, `pilot_accepted`, `fell_back`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampler_choice: Option<AutoChoice>,
    /// `sdp`: LMIs in the final working set; `sdp_cuts`: constraints (starting samples and cuts).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lmis: Option<usize>,
    /// `sdp`: smallest `λ_min(P̄ − K P'_i Kᵀ)` over the samples.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_sample_margin: Option<f64>,
    /// `sdp`, `sdp_cuts`: a proven lower bound on the robust optimum of `tr P̄`: the solver's
    /// dual matrices turned into a Lagrangian bound checked in exact arithmetic
    /// (`fusion::bracket`; summed over blocks, rounded down). It holds whatever the solver's
    /// accuracy.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lower_bound: Option<f64>,
    /// `sdp`, `sdp_cuts`, `certified`: a proven upper bound on the robust optimum — the
    /// rounded-up trace of the best conservative rule: CI, nmCI (recomputed with Young's
    /// inequality in exact arithmetic) or the certified rule (proven by its certificate; in the
    /// bracket when every independent block has at most [`crate::BRACKET_CERTIFY_MAX_BLOCK`] states).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upper_bound: Option<f64>,
    /// Which rule gives `upper_bound` (`ci`, `nmci` or `certified`; ties go to CI / nmCI).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upper_bound_rule: Option<Method>,
    /// `sdp`, `sdp_cuts`: `upper_bound − lower_bound`, rounded up (never negative: both ends
    /// are proven).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap: Option<f64>,
    /// `sdp`: `gap / upper_bound`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap_relative: Option<f64>,
    /// `certified`: the trace its floating-point repair added to the solver's (the
    /// certificate is made exact and proven; see `certified_fusion`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repair: Option<f64>,
    /// `sdp`, `sdp_cuts`: `tr P̄` of the tightest bound *proven* for this method's own gain
    /// (`certify_gain`): what the optimal gain costs when the bound must hold for every
    /// admissible `P_ab` (blocks of at most [`crate::BRACKET_CERTIFY_MAX_BLOCK`] states).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain_certified_trace: Option<f64>,
    /// `certified`: the certificate level used on each block; `sdp`, `sdp_cuts`: those of the
    /// certified rule in the bracket.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub levels: Option<Vec<u32>>,
    /// With `levels`: the number of sectors on each block (0: one certificate for every
    /// direction).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sectors: Option<Vec<u32>>,
    /// `sdp_cuts`: why the loop stopped: `tolerance`, `gap_closed`, `max_iterations` or
    /// `time_limit`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop: Option<CutsStop>,
    /// `sdp_cuts`: the worst `λ_max(K P' Kᵀ − P̄)` the last worst-case search found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub violation: Option<f64>,
    /// `sdp_cuts`: whether that violation is below the tolerance or the gap closed (otherwise
    /// the iteration limit stopped the loop).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub converged: Option<bool>,
    /// `sdp_cuts`: whether the loop stopped because its proven lower bound reached the
    /// certified rule's proven trace within the loop's tolerance: the robust optimum is then
    /// proven to that relative accuracy (and attained to it by method `certified`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap_closed: Option<bool>,
    /// What the bound is guaranteed for (`fusion::rules`): `conservative` (CI, nmCI, the
    /// certified rule: every admissible `P_ab`; for CI and nmCI the exact bound, the reported
    /// `P` being within rounding of it), `relaxation` (`sdp`, `sdp_cuts`: imposed for the drawn
    /// or found `P_ab` only, to the solver's tolerance; see the bracket),
    /// `common_information` (ICI) or `none` (EI, naive).
    pub guarantee: Guarantee,
}

fn matrix(name: &str, rows: &[Vec<f64>]) -> Result<DMatrix<f64>, InputError> {
    if rows.is_empty() {
        return Err(InputError::Empty { name: name.into() });
    }
    let m = matrix_from_rows(rows).map_err(|(_, len)| InputError::NotSquare {
        name: name.into(),
        rows: rows.len(),
        cols: len,
    })?;
    Ok(m)
}

/// Builds and validates a problem from the nested-array form of the JSON contract.
pub(crate) fn problem_from_parts(
    pa: &[Vec<f64>],
    pb: &[Vec<f64>],
    xa: Option<&[f64]>,
    xb: Option<&[f64]>,
    pab_unknown: Option<&[Vec<bool>]>,
) -> Result<FusionProblem, InputError> {
    let pa = matrix("P_a", pa)?;
    let pb = matrix("P_b", pb)?;
    let n = pa.nrows();
    let vector = |v: Option<&[f64]>| match v {
        Some(v) => DVector::from_row_slice(v),
        None => DVector::zeros(n),
    };
    let pattern = match pab_unknown {
        Some(rows) => CrossPattern::from_rows(rows)?,
        None => CrossPattern::fully_unknown(n),
    };
    FusionProblem::new(vector(xa), pa, vector(xb), pb, pattern)
}

impl FuseRequest {
    /// A two-estimate request for `method` with every optional field absent (zero means, a
    /// fully unknown `P_ab`, the defaults), to be completed with struct-update syntax.
    ///
    /// ```
    /// let req = nmci::FuseRequest {
    ///     pab_unknown: Some(vec![vec![true, false], vec![false, true]]),
    ///     ..nmci::FuseRequest::new(nmci::Method::Nmci, vec![vec![3.0, 0.0], vec![0.0, 1.0]],
    ///                              vec![vec![1.0, 0.0], vec![0.0, 4.0]])
    /// };
    /// assert_eq!(nmci::fuse(&req).unwrap().trace, 2.0);
    /// ```
    pub fn new(method: Method, pa: Vec<Vec<f64>>, pb: Vec<Vec<f64>>) -> Self {
        Self {
            pa,
            pb,
            xa: None,
            xb: None,
            pab_unknown: None,
            method,
            criterion: None,
            samples: None,
            seed: None,
            max_trials: None,
            sampler: None,
            time_limit: None,
            level: None,
            sectors: None,
            estimates: None,
            patterns: None,
        }
    }

    /// The validated problem this request describes.
    pub fn problem(&self) -> Result<FusionProblem, RequestError> {
        Ok(problem_from_parts(
            &self.pa,
            &self.pb,
            self.xa.as_deref(),
            self.xb.as_deref(),
            self.pab_unknown.as_deref(),
        )?)
    }

    /// The certified rule's settings this request asks for.
    fn certify_settings(&self) -> CertifySettings {
        CertifySettings {
            level: self.level,
            sectors: self.sectors,
            time_limit: self.time_limit,
            ..CertifySettings::default()
        }
    }

    /// The method-specific fields this request sets.
    fn options(&self) -> [(RequestOption, bool); 7] {
        RequestOption::ALL.map(|o| {
            let set = match o {
                RequestOption::Samples => self.samples.is_some(),
                RequestOption::MaxTrials => self.max_trials.is_some(),
                RequestOption::Sampler => self.sampler.is_some(),
                RequestOption::Seed => self.seed.is_some(),
                RequestOption::TimeLimit => self.time_limit.is_some(),
                RequestOption::Level => self.level.is_some(),
                RequestOption::Sectors => self.sectors.is_some(),
            };
            (o, set)
        })
    }

    /// Checks the fields against each other and against the method's row of
    /// [`crate::fusion::rules::RULES`] (which options and criteria it takes).
    fn check_fields(&self) -> Result<(), RequestError> {
        let rule = self.method.info();
        if self.estimates.is_some() {
            if let Some(field) = [
                ("pa", !self.pa.is_empty()),
                ("pb", !self.pb.is_empty()),
                ("xa", self.xa.is_some()),
                ("xb", self.xb.is_some()),
                ("pab_unknown", self.pab_unknown.is_some()),
            ]
            .into_iter()
            .find_map(|(f, set)| set.then_some(f))
            {
                return Err(RequestError::invalid(field, "give either two estimates (`pa`, `pb`, `xa`, `xb`, `pab_unknown`) or `estimates` for N-way fusion, not both"));
            }
            if !rule.nway {
                return Err(RequestError::invalid(
                    "method",
                    format!(
                        "N-way fusion (`estimates`) supports {}",
                        methods_phrase(|r| r.nway)
                    ),
                ));
            }
        } else {
            if self.patterns.is_some() {
                return Err(RequestError::invalid("patterns", "`patterns` applies to N-way fusion only (with `estimates`); two estimates take `pab_unknown`"));
            }
            // Both missing: say what a request needs; one empty: the problem builder names it.
            if self.pa.is_empty() && self.pb.is_empty() {
                return Err(RequestError::invalid(
                    "pa",
                    "`pa` and `pb` are required (or `estimates` for N-way fusion)",
                ));
            }
        }
        for (option, set) in self.options() {
            if set && !rule.options.contains(&option) {
                let field = option.field();
                return Err(RequestError::invalid(
                    field,
                    format!(
                        "`{field}` applies to {} only",
                        methods_phrase(|r| r.options.contains(&option))
                    ),
                ));
            }
        }
        if let Some(t) = self.time_limit {
            if !(t > 0.0 && t.is_finite()) {
                return Err(RequestError::invalid(
                    "time_limit",
                    format!("`time_limit` must be a positive number of seconds (got {t})"),
                ));
            }
        }
        if let Some(l) = self.level {
            if !(1..=MAX_LEVEL).contains(&l) {
                return Err(RequestError::invalid(
                    "level",
                    format!("`level` must be in 1..={MAX_LEVEL} (got {l})"),
                ));
            }
        }
        if let Some(count) = self.sectors {
            if !(2..=MAX_SECTORS).contains(&count) {
                return Err(RequestError::invalid(
                    "sectors",
                    format!("`sectors` must be in 2..={MAX_SECTORS} (got {count})"),
                ));
            }
        }
        if let Some(c) = self.criterion {
            if !rule.criteria.allows(c) {
                let message = if rule.criteria == Criteria::NoWeight {
                    format!(
                        "{} have no weight to optimise; `criterion` does not apply",
                        methods_phrase(|r| r.criteria == Criteria::NoWeight)
                    )
                } else {
                    format!(
                        "{} minimise the trace; criterion {} is not available for them",
                        methods_phrase(|r| r.criteria == Criteria::TraceOnly),
                        serde_json::to_string(&c).expect("a criterion serialises")
                    )
                };
                return Err(RequestError::invalid("criterion", message));
            }
        }
        check_count("samples", self.samples, MAX_SAMPLES)?;
        check_count("max_trials", self.max_trials, MAX_TRIALS)?;
        self.check_sizes()
    }

    /// The sizes against the method's [`crate::Limits`] and [`MAX_ESTIMATES`], before any
    /// matrix is built (the block limit needs the problem: [`check_blocks`]).
    fn check_sizes(&self) -> Result<(), RequestError> {
        let max = self.method.info().limits.max_dim;
        let who = format!("method \"{}\"", self.method.name());
        check_rows("pa", &self.pa, max, &who)?;
        check_rows("pb", &self.pb, max, &who)?;
        for (field, v) in [("xa", &self.xa), ("xb", &self.xb)] {
            if let Some(v) = v {
                check_rows(field, std::slice::from_ref(v), max, &who)?;
            }
        }
        if let Some(p) = &self.pab_unknown {
            check_rows("pab_unknown", p, max, &who)?;
        }
        if let Some(estimates) = &self.estimates {
            if estimates.len() > MAX_ESTIMATES {
                return Err(RequestError::invalid(
                    "estimates",
                    format!(
                        "N-way fusion takes at most {MAX_ESTIMATES} estimates (got {})",
                        estimates.len()
                    ),
                ));
            }
            for (i, e) in estimates.iter().enumerate() {
                check_rows(&format!("estimates[{i}].p"), &e.p, max, &who)?;
                if let Some(x) = &e.x {
                    check_rows(
                        &format!("estimates[{i}].x"),
                        std::slice::from_ref(x),
                        max,
                        &who,
                    )?;
                }
            }
        }
        for pair in self.patterns.iter().flatten() {
            check_rows("patterns", &pair.pab_unknown, max, &who)?;
        }
        Ok(())
    }
}

/// `Err` naming `pab_unknown` when an independent block of `problem` is larger than
/// `method`'s [`crate::Limits::max_block`].
pub(crate) fn check_blocks(method: Method, problem: &FusionProblem) -> Result<(), RequestError> {
    let max = method.info().limits.max_block;
    if problem.dim() <= max {
        return Ok(());
    }
    let blocks = independent_blocks(&problem.P_a, &problem.P_b, &problem.cross_pattern);
    match blocks.iter().find(|b| b.len() > max) {
        Some(block) => Err(RequestError::invalid(
            "pab_unknown",
            format!(
                "method \"{}\" solves each independent block as one program, of at most {max} states; states {block:?} form one block of {} (linked through P_a, P_b or unknown entries of P_ab)",
                method.name(),
                block.len()
            ),
        )),
        None => Ok(()),
    }
}

/// A covariance's size: a response's `trace` and `det` ([`FuseResponse`]), and the explorer's
/// row of each estimate ([`crate::Exploration::estimates`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CovarianceSummary {
    /// The field it comes from (`pa`, `pb`; `p` for a response).
    pub name: String,
    /// `tr P`.
    pub trace: f64,
    /// `det P`.
    pub det: f64,
}

impl CovarianceSummary {
    /// `field`'s covariance `P`.
    #[allow(non_snake_case)]
    pub fn of(field: &str, P: &DMatrix<f64>) -> Self {
        Self {
            name: field.into(),
            trace: P.trace(),
            det: P.determinant(),
        }
    }
}

/// A response with the estimate and its bound only (every optional field absent).
#[allow(non_snake_case)]
fn bare_response(
    method: Method,
    criterion: Criterion,
    x: &DVector<f64>,
    P: &DMatrix<f64>,
) -> FuseResponse {
    let summary = CovarianceSummary::of("p", P);
    FuseResponse {
        method,
        criterion,
        x: x.iter().copied().collect(),
        p: matrix_to_rows(P),
        ka: None,
        kb: None,
        gains: None,
        weights: None,
        trace: summary.trace,
        det: summary.det,
        omega: None,
        blocks: None,
        samples: None,
        status: None,
        iterations: None,
        acceptance_rate: None,
        sampler_choice: None,
        lmis: None,
        worst_sample_margin: None,
        lower_bound: None,
        upper_bound: None,
        upper_bound_rule: None,
        gap: None,
        gap_relative: None,
        repair: None,
        levels: None,
        sectors: None,
        stop: None,
        gain_certified_trace: None,
        violation: None,
        converged: None,
        gap_closed: None,
        guarantee: method.guarantee(),
    }
}

/// The response of a two-estimate rule: estimate, bound and both gains.
pub(crate) fn response(method: Method, criterion: Criterion, fused: &Fused) -> FuseResponse {
    FuseResponse {
        ka: Some(matrix_to_rows(&fused.K_a)),
        kb: Some(matrix_to_rows(&fused.K_b)),
        ..bare_response(method, criterion, &fused.x, &fused.P)
    }
}

/// Runs a request.
///
/// ```
/// let req: nmci::FuseRequest = serde_json::from_str(
///     r#"{"pa": [[3,0],[0,1]], "pb": [[1,0],[0,4]],
///         "pab_unknown": [[true,false],[false,true]], "method": "nmci"}"#).unwrap();
/// let res = nmci::fuse(&req).unwrap();
/// assert_eq!(res.omega, Some(vec![0.0, 1.0]));
/// assert_eq!(res.trace, 2.0);
/// ```
pub fn fuse(request: &FuseRequest) -> Result<FuseResponse, RequestError> {
    request.check_fields()?;
    let criterion = request.criterion.unwrap_or_default();
    if let Some(estimates) = &request.estimates {
        return fuse_nway(
            estimates,
            request.patterns.as_deref().unwrap_or_default(),
            request.method,
            criterion,
        );
    }
    let problem = request.problem()?;
    check_blocks(request.method, &problem)?;
    match request.method {
        Method::Ci => Ok(ci_response(&problem, criterion)?.0),
        Method::Nmci => Ok(nmci_response(&problem, criterion)?.0),
        Method::Ici => Ok(ici_response(&problem, criterion)?.0),
        Method::Ei => Ok(ei_response(&problem)?.0),
        Method::Naive => Ok(naive_response(&problem).0),
        Method::Certified => Ok(certified_response(&problem, &request.certify_settings())?.0),
        Method::Sdp => {
            let defaults = SdpSettings::default();
            let settings = SdpSettings {
                samples: request.samples.unwrap_or(defaults.samples),
                seed: request.seed.unwrap_or(defaults.seed),
                sampler: SamplerSettings {
                    kind: request.sampler.unwrap_or_default(),
                    max_trials: request.max_trials.unwrap_or(defaults.sampler.max_trials),
                    ..defaults.sampler
                },
                time_limit: request.time_limit,
                ..defaults
            };
            Ok(sdp_response(&problem, &settings, &request.certify_settings(), None, true)?.0)
        }
        Method::SdpCuts => {
            let settings = CutsSettings {
                seed: request.seed.unwrap_or(0),
                time_limit: request.time_limit,
                certify_settings: request.certify_settings(),
                ..CutsSettings::default()
            };
            let cuts = optimal_fusion_cuts(&problem, &settings)?;
            let mut r = response(Method::SdpCuts, Criterion::Trace, &cuts.fused);
            r.status = Some(cuts.status);
            r.iterations = Some(cuts.iterations as u32);
            r.lmis = Some(cuts.constraints);
            r.violation = Some(cuts.violation);
            r.converged = Some(cuts.converged);
            r.stop = Some(cuts.stop);
            // Past the time limit the own-gain certificate is left out, not an error (the loop
            // has its bracket).
            r.gain_certified_trace =
                match gain_certified_trace(&problem, &cuts.fused.K_a, &settings.certify_settings) {
                    Ok(t) => t,
                    Err(SolveError::TimeLimit { .. }) => None,
                    Err(e) => return Err(e.into()),
                };
            r.gap_closed = Some(cuts.gap_closed);
            r.levels = cuts.certified_levels.clone();
            r.sectors = cuts.certified_sectors.clone();
            // The loop computed the certified rule already (blocks of up to 6 states).
            let uppers = UpperBounds::of(&problem, cuts.certified_trace)?;
            fill_bracket(cuts.lower_bound, &uppers, &mut r);
            Ok(r)
        }
    }
}

/// N-way CI (`method` `ci`) or nmCI (`nmci`) of a request's `estimates` and `patterns`.
#[allow(non_snake_case)]
fn fuse_nway(
    estimates: &[NwayEstimate],
    patterns: &[NwayPair],
    method: Method,
    criterion: Criterion,
) -> Result<FuseResponse, RequestError> {
    let estimates = estimates
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let name = format!("estimates[{i}]");
            let P = matrix(&format!("{name}.p"), &e.p)?;
            let x = match &e.x {
                Some(x) => DVector::from_row_slice(x),
                None => DVector::zeros(P.nrows()),
            };
            Estimate::new(&name, x, P)
        })
        .collect::<Result<Vec<_>, InputError>>()?;
    let result: NwayResult = if method == Method::Ci {
        covariance_intersection_nway(&estimates, criterion)?
    } else {
        let pairs = patterns
            .iter()
            .map(|p| {
                Ok(PairPattern {
                    i: p.i,
                    j: p.j,
                    pattern: CrossPattern::from_rows(&p.pab_unknown)?,
                })
            })
            .collect::<Result<Vec<_>, InputError>>()?;
        non_monolithic_ci_nway(&estimates, &pairs, criterion)?
    };
    Ok(FuseResponse {
        gains: Some(result.gains.iter().map(matrix_to_rows).collect()),
        weights: Some(result.omega.clone()),
        blocks: Some(result.blocks.clone()),
        iterations: Some(result.iterations as u32),
        ..bare_response(method, criterion, &result.x, &result.P)
    })
}

/// Fills `lower_bound` and `upper_bound` (both proven: `fusion::bracket`), the rule of the
/// upper end and the gap.
fn fill_bracket(lower: f64, uppers: &UpperBounds, r: &mut FuseResponse) {
    if let Some(b) = uppers.bracket(lower) {
        r.lower_bound = Some(b.lower);
        r.upper_bound = Some(b.upper);
        r.upper_bound_rule = Some(b.upper_rule);
        r.gap = Some(b.gap());
        r.gap_relative = Some(b.gap_relative());
    }
}

/// The certified rule's response and the fused result it was made from: its own trace is
/// the upper bound (rule `certified`); there is no lower bound without a relaxation.
pub(crate) fn certified_response(
    problem: &FusionProblem,
    settings: &CertifySettings,
) -> Result<(FuseResponse, Fused), SolveError> {
    let cert = certified_fusion(problem, settings)?;
    Ok((certificate_response(&cert), cert.fused))
}

/// The response of a computed certificate.
pub(crate) fn certificate_response(cert: &CertifiedResult) -> FuseResponse {
    let mut r = response(Method::Certified, Criterion::Trace, &cert.fused);
    r.status = Some(cert.status);
    r.iterations = Some(cert.iterations);
    r.blocks = Some(cert.blocks.clone());
    r.repair = Some(cert.repair);
    r.levels = Some(cert.levels.clone());
    r.sectors = Some(cert.sectors.clone());
    r.upper_bound = Some(trace_upper_bound(&cert.fused.P));
    r.upper_bound_rule = Some(Method::Certified);
    r
}

/// The CI response and the fused result it was made from.
pub(crate) fn ci_response(
    problem: &FusionProblem,
    criterion: Criterion,
) -> Result<(FuseResponse, Fused), InputError> {
    let ci = covariance_intersection(problem, criterion)?;
    let mut r = response(Method::Ci, criterion, &ci.fused);
    r.omega = Some(vec![ci.omega]);
    Ok((r, ci.fused))
}

/// The nmCI response and the fused result it was made from.
pub(crate) fn nmci_response(
    problem: &FusionProblem,
    criterion: Criterion,
) -> Result<(FuseResponse, Fused), InputError> {
    let nm = non_monolithic_ci(problem, criterion)?;
    let mut r = response(Method::Nmci, criterion, &nm.fused);
    r.omega = Some(nm.omega);
    r.blocks = Some(nm.blocks);
    Ok((r, nm.fused))
}

/// The ICI response and the fused result it was made from.
pub(crate) fn ici_response(
    problem: &FusionProblem,
    criterion: Criterion,
) -> Result<(FuseResponse, Fused), InputError> {
    let ici = inverse_covariance_intersection(problem, criterion)?;
    let mut r = response(Method::Ici, criterion, &ici.fused);
    r.omega = Some(vec![ici.omega]);
    Ok((r, ici.fused))
}

/// The EI response and the fused result it was made from (`criterion` reported as the
/// default: EI has no weight to optimise).
pub(crate) fn ei_response(problem: &FusionProblem) -> Result<(FuseResponse, Fused), InputError> {
    let fused = ellipsoidal_intersection(problem)?;
    Ok((response(Method::Ei, Criterion::default(), &fused), fused))
}

/// The naive-fusion response and the fused result it was made from.
pub(crate) fn naive_response(problem: &FusionProblem) -> (FuseResponse, Fused) {
    let fused = naive_fusion(problem);
    (response(Method::Naive, Criterion::default(), &fused), fused)
}

/// The sampled-SDP response; `uppers` are the certified upper bounds when the caller has
/// already computed them.
pub(crate) fn sdp_response(
    problem: &FusionProblem,
    settings: &SdpSettings,
    certify: &CertifySettings,
    uppers: Option<UpperBounds>,
    own_gain: bool,
) -> Result<(FuseResponse, Fused), SolveError> {
    let opt = optimal_fusion(problem, settings)?;
    let mut r = response(Method::Sdp, Criterion::Trace, &opt.fused);
    r.samples = Some(opt.samples);
    r.status = Some(opt.status);
    r.iterations = Some(opt.iterations);
    r.acceptance_rate = Some(opt.acceptance_rate);
    r.sampler_choice = opt.sampler_choice;
    r.lmis = Some(opt.lmis);
    r.worst_sample_margin = Some(opt.worst_sample_margin);
    r.blocks = Some(opt.blocks.clone());
    if own_gain {
        r.gain_certified_trace = gain_certified_trace(problem, &opt.fused.K_a, certify)?;
    }
    let uppers = match uppers {
        Some(u) => u,
        None => {
            let cert = bracket_certificate(problem, certify)?;
            if let Some(c) = &cert {
                r.levels = Some(c.levels.clone());
                r.sectors = Some(c.sectors.clone());
            }
            upper_bounds(problem, cert.as_ref().map(|c| &c.fused.P))?
        }
    };
    fill_bracket(opt.lower_bound, &uppers, &mut r);
    Ok((r, opt.fused))
}

/// Parses a JSON request, runs it and returns the JSON response.
pub fn fuse_json(request: &str) -> Result<String, RequestError> {
    if request.len() > MAX_REQUEST_BYTES {
        return Err(RequestError::TooLarge {
            bytes: request.len(),
            limit: MAX_REQUEST_BYTES,
        });
    }
    let req: FuseRequest =
        serde_json::from_str(request).map_err(|e| RequestError::Malformed(e.to_string()))?;
    let res = fuse(&req)?;
    serde_json::to_string_pretty(&res).map_err(|e| RequestError::Malformed(e.to_string()))
}
