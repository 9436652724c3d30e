//! A request's fields and the plan they become.
//!
//! A request is made of parts shared by its two kinds: [`PairInput`] (the two estimates and
//! what is known of `P_ab`) and [`Options`] (criterion, sampler, certificate, time limit), each
//! declared once and flattened into the JSON object of [`FuseRequest`] and
//! [`crate::explore::ExploreRequest`]. [`Options::plan`] validates the options and fills in every
//! default — the settings types' own `Default`s ([`SdpSettings`], [`SamplerSettings`],
//! [`CertifySettings`], [`CutsSettings`]), so a default lives in one place — giving the
//! [`Plan`] that `fuse` and `explore` both run.
//!
//! Unknown fields are rejected. serde's `deny_unknown_fields` does not work together with
//! `flatten`, so each request is read through a private wire struct whose last, flattened
//! map collects whatever none of its parts took; a non-empty map is the error.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};
use serde::de::IgnoredAny;
use serde::{Deserialize, Serialize};

use crate::error::{InputError, RequestError};
use crate::fusion::certify::{CertifySettings, MAX_CONES, MAX_LEVEL, MAX_SECTORS};
use crate::fusion::cuts::CutsSettings;
use crate::fusion::rules::{methods_phrase, Criteria, Method, RequestOption};
use crate::fusion::sample::{SamplerKind, SamplerSettings};
use crate::fusion::sdp::SdpSettings;
use crate::fusion::{Criterion, FusionProblem};
use crate::linalg::matrix_from_rows;
use crate::structure::{independent_blocks, CrossPattern, StructureSettings, DEFAULT_COUPLING_TOL};

use super::{MAX_ESTIMATES, MAX_SAMPLES, MAX_TRIALS};

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
    who: &dyn std::fmt::Display,
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

/// `method "ci"`: how a size error names the rule (written only when one is raised).
struct RuleName(Method);

impl std::fmt::Display for RuleName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "method \"{}\"", self.0.name())
    }
}

/// A square matrix from nested rows, or `Empty` / `NotSquare` naming `name`.
pub(crate) fn matrix(name: &str, rows: &[Vec<f64>]) -> Result<DMatrix<f64>, InputError> {
    if rows.is_empty() {
        return Err(InputError::Empty { name: name.into() });
    }
    matrix_from_rows(rows).map_err(|(_, len)| InputError::NotSquare {
        name: name.into(),
        rows: rows.len(),
        cols: len,
    })
}

/// Two estimates and what is known of their cross-covariance: the fields `pa`, `pb`, `xa`,
/// `xb` and `pab_unknown` of [`FuseRequest`] and [`crate::explore::ExploreRequest`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PairInput {
    /// `P_a`, row-major nested rows (required unless an N-way request gives `estimates`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pa: Vec<Vec<f64>>,
    /// `P_b`, row-major nested rows (required unless an N-way request gives `estimates`).
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
    /// A declared partition of the states into blocks with independent errors
    /// ([`StructureSettings::blocks`]): implies `pab_unknown` when that is absent (unknown
    /// within a block, known zero across), must agree with it when given. Also for N-way.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blocks: Option<Vec<Vec<usize>>>,
    /// The relative size up to which an entry of a covariance between blocks is absorbed
    /// ([`StructureSettings::coupling_tol`]; default [`crate::structure::DEFAULT_COUPLING_TOL`], 0 = exact
    /// zeros only). Also for N-way.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coupling_tol: Option<f64>,
}

impl PairInput {
    /// `P_a` and `P_b` with zero means and a fully unknown `P_ab`.
    pub fn new(pa: Vec<Vec<f64>>, pb: Vec<Vec<f64>>) -> Self {
        Self {
            pa,
            pb,
            ..Self::default()
        }
    }

    /// The validated problem (errors name the field: `P_a`, `x_b`, `pab_unknown`, …).
    pub fn problem(&self) -> Result<FusionProblem, InputError> {
        let (xa, pa, xb, pb, pattern) = self.parts()?;
        FusionProblem::new(xa, pa, xb, pb, pattern)
    }

    /// The request's `x_a`, `P_a`, `x_b`, `P_b` and pattern, read but not yet validated as a
    /// problem (the pseudo-inverse form, `fusion::semidefinite`, takes them where
    /// [`PairInput::problem`] refuses a semi-definite covariance).
    #[allow(clippy::type_complexity)]
    pub(crate) fn parts(
        &self,
    ) -> Result<
        (
            DVector<f64>,
            DMatrix<f64>,
            DVector<f64>,
            DMatrix<f64>,
            CrossPattern,
        ),
        InputError,
    > {
        let pa = matrix("P_a", &self.pa)?;
        let pb = matrix("P_b", &self.pb)?;
        let n = pa.nrows();
        let vector = |v: &Option<Vec<f64>>| match v {
            Some(v) => DVector::from_row_slice(v),
            None => DVector::zeros(n),
        };
        let pattern = match (&self.pab_unknown, &self.blocks) {
            (Some(rows), _) => CrossPattern::from_rows(rows)?,
            (None, Some(blocks)) => CrossPattern::within_blocks(n, blocks)?,
            (None, None) => CrossPattern::fully_unknown(n),
        };
        Ok((vector(&self.xa), pa, vector(&self.xb), pb, pattern))
    }

    /// The structure settings of `blocks` and `coupling_tol` (checked when applied).
    pub fn structure_settings(&self) -> StructureSettings {
        StructureSettings {
            blocks: self.blocks.clone(),
            coupling_tol: self.coupling_tol.unwrap_or(DEFAULT_COUPLING_TOL),
        }
    }

    /// Every field set (the names in an unknown-field error).
    pub(crate) fn every_field() -> Self {
        Self {
            pa: vec![vec![1.0]],
            pb: vec![vec![1.0]],
            xa: Some(vec![0.0]),
            xb: Some(vec![0.0]),
            pab_unknown: Some(vec![vec![true]]),
            blocks: Some(vec![vec![0]]),
            coupling_tol: Some(0.0),
        }
    }

    /// The fields set, by name (for the N-way exclusivity check; `blocks` and
    /// `coupling_tol` apply to both kinds).
    fn set_fields(&self) -> [(&'static str, bool); 5] {
        [
            ("pa", !self.pa.is_empty()),
            ("pb", !self.pb.is_empty()),
            ("xa", self.xa.is_some()),
            ("xb", self.xb.is_some()),
            ("pab_unknown", self.pab_unknown.is_some()),
        ]
    }

    /// Every field against a size limit of `max` states, before any matrix is built.
    pub(crate) fn check_sizes(
        &self,
        max: usize,
        who: &dyn std::fmt::Display,
    ) -> Result<(), RequestError> {
        check_rows("pa", &self.pa, max, who)?;
        check_rows("pb", &self.pb, max, who)?;
        for (field, v) in [("xa", &self.xa), ("xb", &self.xb)] {
            if let Some(v) = v {
                check_rows(field, std::slice::from_ref(v), max, who)?;
            }
        }
        if let Some(p) = &self.pab_unknown {
            check_rows("pab_unknown", p, max, who)?;
        }
        if let Some(b) = &self.blocks {
            check_rows("blocks", b, max, who)?;
        }
        Ok(())
    }
}

/// The options of [`FuseRequest`] and [`crate::explore::ExploreRequest`]: every field absent means the
/// default, which [`Options::plan`] takes from the settings types.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Options {
    /// `trace` (default) or `logdet`; the SDP and the certified rule minimise the trace.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub criterion: Option<Criterion>,
    /// The sampled SDP's number of cross-covariances ([`SdpSettings::samples`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// The sampler's seed ([`SdpSettings::seed`]; `sdp_cuts`: [`CutsSettings::seed`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// The rejection sampler's trial budget ([`SamplerSettings::max_trials`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_trials: Option<u64>,
    /// `rejection` (the paper's, default), `hit_and_run` (any dimension) or `auto`
    /// (rejection where its acceptance is workable, hit-and-run otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampler: Option<SamplerKind>,
    /// Wall-clock limit in seconds (default none) of the main solve and, separately, of each
    /// certificate in the response (the bracket's and the own-gain one). Past it `sdp` and
    /// `certified` fail with a time-limit error; `sdp_cuts` returns its best proven bracket so
    /// far with `converged: false` and `stop: "time_limit"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_limit: Option<f64>,
    /// The certified rule's level ([`CertifySettings::level`]): for `certified` itself and the
    /// brackets' upper end.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<u32>,
    /// Two-state blocks certified on this many sectors of directions
    /// ([`CertifySettings::sectors`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sectors: Option<u32>,
    /// Three-state blocks certified on this many cones of directions, 4, 16 or 64
    /// ([`CertifySettings::cones`]; default none: one certificate of the block's level).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cones: Option<u32>,
    /// Three-state blocks certified on cones of directions cut where the bound is tight, at
    /// most this many, `4..=256` ([`CertifySettings::max_cones`]; default none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_cones: Option<u32>,
    /// The cutting planes stop when the worst violation found is below this times
    /// `max(tr P̄, 1)`, positive ([`CutsSettings::tolerance`]; default `10⁻⁷`): smaller
    /// costs more iterations and leaves less for the own rule's proof to add back.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cuts_tolerance: Option<f64>,
}

/// What a request runs: its [`Options`] validated, every default filled in.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The criterion of the rules with a weight (CI, nmCI, ICI).
    pub criterion: Criterion,
    /// The sampled SDP's settings (also the explorer's region sampler: `sampler`, `seed`).
    pub sdp: SdpSettings,
    /// The certified rule's settings (`certified`, and every bracket's upper end).
    pub certify: CertifySettings,
    /// The cutting-plane loop's settings.
    pub cuts: CutsSettings,
}

impl Options {
    /// Whether each method-specific option is set.
    fn set(&self) -> [(RequestOption, bool); 10] {
        RequestOption::ALL.map(|o| {
            let set = match o {
                RequestOption::Samples => self.samples.is_some(),
                RequestOption::MaxTrials => self.max_trials.is_some(),
                RequestOption::Sampler => self.sampler.is_some(),
                RequestOption::Seed => self.seed.is_some(),
                RequestOption::TimeLimit => self.time_limit.is_some(),
                RequestOption::Level => self.level.is_some(),
                RequestOption::Sectors => self.sectors.is_some(),
                RequestOption::Cones => self.cones.is_some(),
                RequestOption::MaxCones => self.max_cones.is_some(),
                RequestOption::CutsTolerance => self.cuts_tolerance.is_some(),
            };
            (o, set)
        })
    }

    /// The options `method` takes ([`crate::rules::RuleInfo::options`], and the criterion
    /// where it allows it), the others left out: the explorer's options for a second method
    /// (`crate::explore::prove`).
    pub fn for_method(&self, method: Method) -> Options {
        let rule = method.info();
        let mut o = self.clone();
        for option in RequestOption::ALL {
            if !rule.options.contains(&option) {
                match option {
                    RequestOption::Samples => o.samples = None,
                    RequestOption::MaxTrials => o.max_trials = None,
                    RequestOption::Sampler => o.sampler = None,
                    RequestOption::Seed => o.seed = None,
                    RequestOption::TimeLimit => o.time_limit = None,
                    RequestOption::Level => o.level = None,
                    RequestOption::Sectors => o.sectors = None,
                    RequestOption::Cones => o.cones = None,
                    RequestOption::MaxCones => o.max_cones = None,
                    RequestOption::CutsTolerance => o.cuts_tolerance = None,
                }
            }
        }
        o.criterion = o.criterion.filter(|&c| rule.criteria.allows(c));
        o
    }

    /// The options validated (errors name the field) and completed with the settings'
    /// defaults.
    ///
    /// ```
    /// let plan = nmci::contract::Options { samples: Some(50), ..Default::default() }.plan().unwrap();
    /// assert_eq!(plan.sdp.samples, 50);
    /// assert_eq!(plan.sdp.sampler, nmci::sample::SamplerSettings::default());
    /// let bad = nmci::contract::Options { level: Some(0), ..Default::default() }.plan().unwrap_err();
    /// assert_eq!(bad.field().as_deref(), Some("level"));
    /// ```
    pub fn plan(&self) -> Result<Plan, RequestError> {
        if let Some(t) = self.time_limit {
            if !(t > 0.0 && t.is_finite()) {
                return Err(RequestError::invalid(
                    "time_limit",
                    format!("`time_limit` must be a positive number of seconds (got {t})"),
                ));
            }
        }
        if let Some(t) = self.cuts_tolerance {
            if !(t > 0.0 && t.is_finite()) {
                return Err(RequestError::invalid(
                    "cuts_tolerance",
                    format!("`cuts_tolerance` must be positive and finite (got {t})"),
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
        if let Some(count) = self.cones {
            if ![4, 16, 64].contains(&count) {
                return Err(RequestError::invalid(
                    "cones",
                    format!("`cones` must be 4, 16 or 64 (got {count})"),
                ));
            }
        }
        if let Some(budget) = self.max_cones {
            if !(4..=MAX_CONES).contains(&budget) {
                return Err(RequestError::invalid(
                    "max_cones",
                    format!("`max_cones` must be in 4..={MAX_CONES} (got {budget})"),
                ));
            }
            if self.cones.is_some() {
                return Err(RequestError::invalid(
                    "max_cones",
                    "give `cones` (that many cones, uniform) or `max_cones` (cones cut where the bound is tight), not both",
                ));
            }
        }
        check_count("samples", self.samples, MAX_SAMPLES)?;
        check_count("max_trials", self.max_trials, MAX_TRIALS)?;
        let sdp_defaults = SdpSettings::default();
        let sdp = SdpSettings {
            samples: self.samples.unwrap_or(sdp_defaults.samples),
            seed: self.seed.unwrap_or(sdp_defaults.seed),
            sampler: SamplerSettings {
                kind: self.sampler.unwrap_or(sdp_defaults.sampler.kind),
                max_trials: self.max_trials.unwrap_or(sdp_defaults.sampler.max_trials),
                ..sdp_defaults.sampler
            },
            time_limit: self.time_limit,
            ..sdp_defaults
        };
        let certify = CertifySettings {
            level: self.level,
            sectors: self.sectors,
            cones: self.cones,
            max_cones: self.max_cones,
            time_limit: self.time_limit,
            ..CertifySettings::default()
        };
        let cuts_defaults = CutsSettings::default();
        let cuts = CutsSettings {
            seed: self.seed.unwrap_or(cuts_defaults.seed),
            tolerance: self.cuts_tolerance.unwrap_or(cuts_defaults.tolerance),
            time_limit: self.time_limit,
            certify_settings: certify,
            ..cuts_defaults
        };
        Ok(Plan {
            criterion: self.criterion.unwrap_or_default(),
            sdp,
            certify,
            cuts,
        })
    }
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

/// A fusion request (see docs/contract.md for the JSON form, one flat object): two estimates
/// ([`PairInput`]) or, for N-way CI / nmCI, `estimates` and `patterns`; the method; its
/// [`Options`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "FuseRequestWire")]
pub struct FuseRequest {
    /// The two estimates (empty for an N-way request).
    #[serde(flatten)]
    pub pair: PairInput,
    /// The rule.
    pub method: Method,
    /// The options (which apply to which method: [`crate::rules::RuleInfo::options`]).
    #[serde(flatten)]
    pub options: Options,
    /// N-way fusion (methods `ci`, `nmci`): `k ≥ 2` estimates, instead of `pa`, `pb`, `xa`,
    /// `xb`, `pab_unknown`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimates: Option<Vec<NwayEstimate>>,
    /// N-way: the patterns of the pairs' cross-covariances (pairs not listed: fully unknown).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patterns: Option<Vec<NwayPair>>,
}

/// [`FuseRequest`] as read: its parts, then whatever none of them took.
#[derive(Deserialize)]
struct FuseRequestWire {
    #[serde(flatten)]
    pair: PairInput,
    method: Method,
    #[serde(flatten)]
    options: Options,
    #[serde(default)]
    estimates: Option<Vec<NwayEstimate>>,
    #[serde(default)]
    patterns: Option<Vec<NwayPair>>,
    #[serde(flatten)]
    unknown: BTreeMap<String, IgnoredAny>,
}

/// The error of a field no part of a request took: `unknown field `name`` (the prefix
/// [`RequestError::field`] reads), and the fields a request of this kind has.
pub(crate) fn unknown_field<T: Serialize>(
    unknown: &BTreeMap<String, IgnoredAny>,
    full: &T,
) -> Result<(), String> {
    let Some(name) = unknown.keys().next() else {
        return Ok(());
    };
    // The field names, read from a request with every field set (so they cannot drift).
    let fields = match serde_json::to_value(full) {
        Ok(serde_json::Value::Object(map)) => map
            .keys()
            .map(|k| format!("`{k}`"))
            .collect::<Vec<_>>()
            .join(", "),
        _ => String::new(),
    };
    Err(format!("unknown field `{name}`, expected one of {fields}"))
}

impl FuseRequest {
    /// A two-estimate request for `method` with every optional field absent (zero means, a
    /// fully unknown `P_ab`, the defaults), to be completed through its `pair` and `options`.
    ///
    /// ```
    /// let mut req = nmci::contract::FuseRequest::new(nmci::rules::Method::Nmci, vec![vec![3.0, 0.0], vec![0.0, 1.0]],
    ///                                      vec![vec![1.0, 0.0], vec![0.0, 4.0]]);
    /// req.pair.pab_unknown = Some(vec![vec![true, false], vec![false, true]]);
    /// assert_eq!(nmci::contract::fuse(&req).unwrap().trace, 2.0);
    /// ```
    pub fn new(method: Method, pa: Vec<Vec<f64>>, pb: Vec<Vec<f64>>) -> Self {
        Self {
            pair: PairInput::new(pa, pb),
            method,
            options: Options::default(),
            estimates: None,
            patterns: None,
        }
    }

    /// The validated problem of a two-estimate request.
    pub fn problem(&self) -> Result<FusionProblem, RequestError> {
        Ok(self.pair.problem()?)
    }

    /// Checks the fields against each other and against the method's row of
    /// [`crate::fusion::rules::RULES`] (which options and criteria it takes), and returns the
    /// plan.
    pub fn plan(&self) -> Result<Plan, RequestError> {
        let rule = self.method.info();
        if self.estimates.is_some() {
            if let Some(field) = self
                .pair
                .set_fields()
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
            if self.pair.pa.is_empty() && self.pair.pb.is_empty() {
                return Err(RequestError::invalid(
                    "pa",
                    "`pa` and `pb` are missing or empty: two non-empty covariances are required (or `estimates` for N-way fusion)",
                ));
            }
        }
        for (option, set) in self.options.set() {
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
        let plan = self.options.plan()?;
        if let Some(c) = self.options.criterion {
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
        self.check_sizes()?;
        Ok(plan)
    }

    /// The sizes against the method's [`crate::rules::Limits`] and [`MAX_ESTIMATES`], before any
    /// matrix is built (the block limit needs the problem: [`check_blocks`]).
    fn check_sizes(&self) -> Result<(), RequestError> {
        let max = self.method.info().limits.max_dim;
        let who = RuleName(self.method);
        self.pair.check_sizes(max, &who)?;
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

    /// A request with every field set (the names in an unknown-field error).
    pub(crate) fn every_field() -> Self {
        Self {
            pair: PairInput::every_field(),
            method: Method::Ci,
            options: Options::every_field(),
            estimates: Some(vec![]),
            patterns: Some(vec![]),
        }
    }
}

impl Options {
    /// Options with every field set (the names in an unknown-field error).
    pub(crate) fn every_field() -> Self {
        Self {
            criterion: Some(Criterion::Trace),
            samples: Some(1),
            seed: Some(0),
            max_trials: Some(1),
            sampler: Some(SamplerKind::Rejection),
            time_limit: Some(1.0),
            level: Some(1),
            sectors: Some(2),
            cones: Some(4),
            max_cones: Some(4),
            cuts_tolerance: Some(1e-7),
        }
    }
}

impl TryFrom<FuseRequestWire> for FuseRequest {
    type Error = String;

    fn try_from(w: FuseRequestWire) -> Result<Self, String> {
        unknown_field(&w.unknown, &FuseRequest::every_field())?;
        Ok(FuseRequest {
            pair: w.pair,
            method: w.method,
            options: w.options,
            estimates: w.estimates,
            patterns: w.patterns,
        })
    }
}

/// `Err` naming `pab_unknown` when an independent block of `problem` is larger than
/// `method`'s [`crate::rules::Limits::max_block`].
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
