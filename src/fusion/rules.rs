//! The fusion rules nmci implements, named once.
//!
//! [`Method`] is the one enum of rules (the JSON contract's `"method"`), and [`RULES`] is the
//! one table of what is known about each: its name and label, its colour (every chart and the
//! page read them), what its bound is guaranteed for ([`Guarantee`]), which criteria and which
//! method-specific request fields it takes, and whether it fuses `k ≥ 2` estimates. The JSON
//! form of [`Method`], the request check ([`crate::contract::fuse`]), the explorer's list of per-rule
//! reports, the study's charts and the page (through the wasm export `rules()`) read this
//! table; adding a rule means a variant, a row and its solver.
//!
//! ## The guarantees
//!
//! For an admissible cross-covariance `P'` (the known zeros respected, the joint covariance
//! positive semidefinite) and a rule's gains `K = [K_a K_b]`, the true fused error covariance
//! is `K [[P_a, P'], [P'ᵀ, P_b]] Kᵀ`; a bound `P` is *conservative* when it dominates that
//! matrix for every admissible `P'`.
//! - [`Guarantee::Conservative`]: CI (Julier & Uhlmann 1997); nmCI (the paper's nmGMD with
//!   Gaussians: CI on each independent block — `P_a`, `P_b` and the pattern of `P_ab` are
//!   block-diagonal in those blocks, so with block-diagonal gains the fused error covariance is
//!   block-diagonal too and each block's CI bound dominates its block for every admissible
//!   `P'`); and the certified rule (a sum-of-squares certificate, proof in `fusion::certify`).
//!   For CI and nmCI this is a theorem about the exact `P`; the reported `P` is its
//!   floating-point evaluation (within `4 ε κ` relative of it, `κ` the condition number of the
//!   pencil, measured against 50-digit references: docs/methods.md; not within rounding at
//!   large `κ`), and the bracket's proven upper traces
//!   (`fusion::bracket`) round it up. The certified rule's `P` is proven as computed, every
//!   rounding included.
//! - [`Guarantee::Relaxation`]: the sampled SDP (the paper's eq. `sampled_sdp`) and the
//!   cutting-plane SDP impose the robust constraint for finitely many `P'` (drawn samples, or
//!   the worst cases found so far), and only to the solver's tolerance, so their optimum is a
//!   lower bound on the robust optimum (up to that tolerance; the bracket's lower end is the
//!   rigorous one) and their `P̄` need not dominate for other `P'`. Their responses carry the
//!   proven bracket and, for blocks of up to four states, `gain_certified_p`: a bound proven
//!   conservative for their own gain (`fusion::bracket`, "A given gain's bound").
//! - [`Guarantee::CommonInformation`]: ICI (Noack et al. 2017) is conservative when the
//!   correlation comes from common information, not for every admissible `P'`.
//! - [`Guarantee::None`]: EI and naive fusion (which assumes `P' = 0`) guarantee nothing.

use serde::{Deserialize, Serialize};

use super::certify::MAX_BLOCK_DIM;
use super::Criterion;

/// Which fusion rule a request asks for. Its JSON form is its [`RuleInfo::name`]; the variants
/// are in [`RULES`] order (checked at compile time).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Covariance intersection, one weight.
    Ci,
    /// Non-monolithic CI, one weight per independent block.
    Nmci,
    /// The tightest bound proven conservative by a sum-of-squares certificate of a chosen level
    /// (`certified_fusion`): its trace never above that of CI's (nmCI's) bound made a proven
    /// dominating matrix — within `10⁻¹⁴` of their traces on well-conditioned blocks, not on
    /// near-singular ones (`fusion::certify`, "Never looser than CI in trace") — and tighter on
    /// many non-separable patterns.
    Certified,
    /// Sampled-SDP approximation of the optimal bound.
    Sdp,
    /// The robust SDP by cutting planes: worst-case cross-covariances as constraints.
    SdpCuts,
    /// Inverse covariance intersection: conservative for common-information correlation only.
    Ici,
    /// Ellipsoidal intersection: not guaranteed conservative.
    Ei,
    /// Naive fusion (as if independent): not conservative when the estimates are correlated.
    Naive,
}

impl From<super::bracket::UpperRule> for Method {
    fn from(rule: super::bracket::UpperRule) -> Self {
        use super::bracket::UpperRule;
        match rule {
            UpperRule::Ci => Method::Ci,
            UpperRule::Nmci => Method::Nmci,
            UpperRule::Certified => Method::Certified,
            UpperRule::Sdp => Method::Sdp,
            UpperRule::SdpCuts => Method::SdpCuts,
        }
    }
}

impl Method {
    /// The bracket's name for this rule, when its proven trace can be a bracket's upper end.
    pub fn upper_rule(self) -> Option<super::bracket::UpperRule> {
        use super::bracket::UpperRule;
        match self {
            Method::Ci => Some(UpperRule::Ci),
            Method::Nmci => Some(UpperRule::Nmci),
            Method::Certified => Some(UpperRule::Certified),
            Method::Sdp => Some(UpperRule::Sdp),
            Method::SdpCuts => Some(UpperRule::SdpCuts),
            _ => None,
        }
    }
}

/// What a rule's bound is guaranteed for (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Guarantee {
    /// Conservative for every admissible cross-covariance.
    Conservative,
    /// A relaxation of the robust program: its bound is imposed, to the solver's tolerance, for
    /// the cross-covariances it was given only; the response's proven bracket says how far
    /// from the robust optimum it is.
    Relaxation,
    /// Conservative when the correlation comes from common information only.
    CommonInformation,
    /// Not guaranteed conservative.
    None,
}

impl Guarantee {
    /// Whether the bound holds for every admissible cross-covariance.
    pub fn for_every_cross_covariance(self) -> bool {
        self == Guarantee::Conservative
    }

    /// Whether the bound is guaranteed only for one kind of correlation (ICI) or not at all
    /// (EI, naive): the explorer draws these dotted and leaves them off by default.
    pub fn unguaranteed(self) -> bool {
        matches!(self, Guarantee::CommonInformation | Guarantee::None)
    }

    /// A short phrase for tables and legends.
    pub fn phrase(self) -> &'static str {
        match self {
            Guarantee::Conservative => "conservative",
            Guarantee::Relaxation => "a relaxation",
            Guarantee::CommonInformation => "common information only",
            Guarantee::None => "not guaranteed conservative",
        }
    }
}

/// Which criteria a rule can minimise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Criteria {
    /// `trace` and `logdet`.
    Both,
    /// `trace` only.
    TraceOnly,
    /// No weight to optimise: `criterion` does not apply.
    NoWeight,
}

impl Criteria {
    /// Whether `criterion` may be requested.
    pub fn allows(self, criterion: Criterion) -> bool {
        match self {
            Criteria::Both => true,
            Criteria::TraceOnly => criterion == Criterion::Trace,
            Criteria::NoWeight => false,
        }
    }
}

/// A method-specific field of a [`crate::contract::FuseRequest`] (serialised as its [`field`](Self::field)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RequestOption {
    /// `samples`.
    Samples,
    /// `max_trials`.
    MaxTrials,
    /// `sampler`.
    Sampler,
    /// `seed`.
    Seed,
    /// `time_limit`.
    TimeLimit,
    /// `level`.
    Level,
    /// `sectors`.
    Sectors,
    /// `cones`.
    Cones,
    /// `max_cones`.
    MaxCones,
    /// `cuts_tolerance`.
    CutsTolerance,
}

impl RequestOption {
    /// Every option, in the order the request check reports them.
    pub const ALL: [RequestOption; 10] = [
        RequestOption::Samples,
        RequestOption::MaxTrials,
        RequestOption::Sampler,
        RequestOption::Seed,
        RequestOption::TimeLimit,
        RequestOption::Level,
        RequestOption::Sectors,
        RequestOption::Cones,
        RequestOption::MaxCones,
        RequestOption::CutsTolerance,
    ];

    /// The request field's name.
    pub fn field(self) -> &'static str {
        match self {
            RequestOption::Samples => "samples",
            RequestOption::MaxTrials => "max_trials",
            RequestOption::Sampler => "sampler",
            RequestOption::Seed => "seed",
            RequestOption::TimeLimit => "time_limit",
            RequestOption::Level => "level",
            RequestOption::Sectors => "sectors",
            RequestOption::Cones => "cones",
            RequestOption::MaxCones => "max_cones",
            RequestOption::CutsTolerance => "cuts_tolerance",
        }
    }
}

impl Serialize for RequestOption {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.field())
    }
}

/// The methods whose row satisfies `pick`, as `method "a"` or `methods "a", "b" and "c"`.
pub(crate) fn methods_phrase(pick: impl Fn(&RuleInfo) -> bool) -> String {
    let names: Vec<String> = RULES
        .iter()
        .filter(|r| pick(r))
        .map(|r| format!("\"{}\"", r.name))
        .collect();
    match names.split_last() {
        None => "no method".into(),
        Some((last, [])) => format!("method {last}"),
        Some((last, rest)) => format!("methods {} and {last}", rest.join(", ")),
    }
}

/// Everything nmci knows about a rule apart from its solver. Serialised (for the page's
/// `rules()` and Python's `nmci.rules()`) with three derived fields: `legend`
/// ([`RuleInfo::legend`]), `phrase` ([`Guarantee::phrase`]) and `unguaranteed`
/// ([`Guarantee::unguaranteed`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RuleInfo {
    /// The rule.
    pub method: Method,
    /// Its name in the JSON contract, on the CLI and in file columns (`"sdp_cuts"`).
    pub name: &'static str,
    /// Its label in charts, tables and the page (`"nmCI"`).
    pub label: &'static str,
    /// What its bound is guaranteed for.
    pub guarantee: Guarantee,
    /// Its colour in every chart and in the page (`#rrggbb`).
    pub colour: &'static str,
    /// Which criteria it minimises.
    pub criteria: Criteria,
    /// The method-specific request fields it takes.
    pub options: &'static [RequestOption],
    /// Whether it fuses `k ≥ 2` estimates (`estimates` in a request).
    pub nway: bool,
    /// Whether the explorer computes it for every state.
    pub explorer: bool,
    /// The largest problem it accepts through the request contract.
    pub limits: Limits,
}

/// The largest problem a rule accepts through the request contract ([`crate::contract::fuse`], and so
/// the CLI, the page and Python), checked before any matrix is built; a larger request is
/// refused with an error naming the field and the limit. The library's functions take any
/// size (their settings' `time_limit` bounds the solvers). The limits keep every accepted
/// request to seconds and at most a few hundred MB on a small machine (docs/contract.md, "Limits",
/// has the measurements they come from).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Limits {
    /// Largest state dimension `n` (each estimate's, for N-way fusion).
    pub max_dim: usize,
    /// Largest independent block (states linked through `P_a`, `P_b` or the pattern of
    /// `P_ab`, [`crate::structure::independent_blocks`]): the size of the programs an SDP rule solves.
    pub max_block: usize,
}

/// The closed-form rules (CI, nmCI, ICI, EI, naive): one `n × n` eigendecomposition or
/// factorization per block, `O(n³)`.
const CLOSED_FORM: Limits = Limits {
    max_dim: 1000,
    max_block: 1000,
};

impl RuleInfo {
    /// The label, with the guarantee's phrase for the unguaranteed rules
    /// (`"ICI (common information only)"`).
    pub fn legend(&self) -> String {
        if self.guarantee.unguaranteed() {
            format!("{} ({})", self.label, self.guarantee.phrase())
        } else {
            self.label.into()
        }
    }
}

impl Serialize for RuleInfo {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut s = serializer.serialize_struct("RuleInfo", 12)?;
        s.serialize_field("method", &self.method)?;
        s.serialize_field("name", self.name)?;
        s.serialize_field("label", self.label)?;
        s.serialize_field("legend", &self.legend())?;
        s.serialize_field("guarantee", &self.guarantee)?;
        s.serialize_field("phrase", self.guarantee.phrase())?;
        s.serialize_field("unguaranteed", &self.guarantee.unguaranteed())?;
        s.serialize_field("colour", self.colour)?;
        s.serialize_field("criteria", &self.criteria)?;
        s.serialize_field("options", self.options)?;
        s.serialize_field("nway", &self.nway)?;
        s.serialize_field("explorer", &self.explorer)?;
        s.serialize_field("limits", &self.limits)?;
        s.end()
    }
}

/// Every rule, in report order (the order of [`Method`]'s variants).
pub const RULES: [RuleInfo; 8] = [
    RuleInfo {
        method: Method::Ci,
        name: "ci",
        label: "CI",
        guarantee: Guarantee::Conservative,
        colour: "#7b3fa0",
        criteria: Criteria::Both,
        options: &[],
        nway: true,
        explorer: true,
        limits: CLOSED_FORM,
    },
    RuleInfo {
        method: Method::Nmci,
        name: "nmci",
        label: "nmCI",
        guarantee: Guarantee::Conservative,
        colour: "#d62728",
        criteria: Criteria::Both,
        options: &[],
        nway: true,
        explorer: true,
        limits: CLOSED_FORM,
    },
    RuleInfo {
        method: Method::Certified,
        name: "certified",
        label: "certified",
        guarantee: Guarantee::Conservative,
        colour: "#000000",
        criteria: Criteria::TraceOnly,
        options: &[
            RequestOption::TimeLimit,
            RequestOption::Level,
            RequestOption::Sectors,
            RequestOption::Cones,
            RequestOption::MaxCones,
        ],
        nway: false,
        explorer: true,
        limits: Limits {
            // One SDP per block, up to seconds each at the default levels.
            max_dim: 60,
            max_block: MAX_BLOCK_DIM,
        },
    },
    RuleInfo {
        method: Method::Sdp,
        name: "sdp",
        label: "optimal (sampled SDP)",
        guarantee: Guarantee::Relaxation,
        colour: "#2a9d3f",
        criteria: Criteria::TraceOnly,
        // Its sampler's options, its seed, the time limit and the bracket's certificate.
        options: &[
            RequestOption::Samples,
            RequestOption::MaxTrials,
            RequestOption::Sampler,
            RequestOption::Seed,
            RequestOption::TimeLimit,
            RequestOption::Level,
            RequestOption::Sectors,
            RequestOption::Cones,
            RequestOption::MaxCones,
        ],
        nway: false,
        explorer: true,
        limits: Limits {
            // The samples are drawn jointly (2n × 2n checks); a fully unknown 10-state block
            // took over 100 s.
            max_dim: 12,
            max_block: 8,
        },
    },
    RuleInfo {
        method: Method::SdpCuts,
        name: "sdp_cuts",
        label: "optimal (cutting planes)",
        guarantee: Guarantee::Relaxation,
        colour: "#6b8e23",
        criteria: Criteria::TraceOnly,
        options: &[
            RequestOption::Seed,
            RequestOption::TimeLimit,
            RequestOption::Level,
            RequestOption::Sectors,
            RequestOption::Cones,
            RequestOption::MaxCones,
            RequestOption::CutsTolerance,
        ],
        nway: false,
        explorer: false,
        limits: Limits {
            // The cuts table of docs/benchmarks.md reaches 6-state blocks; an 8-state one did not
            // finish in 120 s.
            max_dim: 12,
            max_block: 6,
        },
    },
    RuleInfo {
        method: Method::Ici,
        name: "ici",
        label: "ICI",
        guarantee: Guarantee::CommonInformation,
        colour: "#17becf",
        criteria: Criteria::Both,
        options: &[],
        nway: false,
        explorer: true,
        limits: CLOSED_FORM,
    },
    RuleInfo {
        method: Method::Ei,
        name: "ei",
        label: "EI",
        guarantee: Guarantee::None,
        colour: "#8c564b",
        criteria: Criteria::NoWeight,
        options: &[],
        nway: false,
        explorer: true,
        limits: CLOSED_FORM,
    },
    RuleInfo {
        method: Method::Naive,
        name: "naive",
        label: "naive",
        guarantee: Guarantee::None,
        colour: "#999999",
        criteria: Criteria::NoWeight,
        options: &[],
        nway: false,
        explorer: true,
        limits: CLOSED_FORM,
    },
];

// Row `i` of `RULES` describes variant `i`, so `Method::info` is an index.
const _: () = {
    let mut i = 0;
    while i < RULES.len() {
        assert!(RULES[i].method as usize == i);
        i += 1;
    }
};

/// The names of [`RULES`], in order.
const NAMES: [&str; RULES.len()] = {
    let mut names = [""; RULES.len()];
    let mut i = 0;
    while i < RULES.len() {
        names[i] = RULES[i].name;
        i += 1;
    }
    names
};

/// Every rule, in report order.
pub fn rules() -> &'static [RuleInfo] {
    &RULES
}

/// How a rule uses the problem's independent blocks (`structure::absorb`'s module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlockUse {
    /// It does not split the problem into blocks (CI, ICI, EI, naive).
    None,
    /// A conservative rule that solves each block: near-zero couplings are absorbed, since it
    /// stays conservative on a dominating problem (nmCI, the certified rule).
    Absorbs,
    /// The sampled SDP: a relaxation with a proven lower end, which would not hold for the
    /// given problem after an inflation; it solves the *deflated* problem, whose robust optimum
    /// is at most the given one's (its blocks kept, `structure::absorb`, "A lower end"), and
    /// takes its bracket's upper end from the absorbed problem.
    Deflates,
    /// The cutting planes: their loop stops on a bracket computed on the problem they solve,
    /// so they solve the covariances as given.
    AsGiven,
}

impl Method {
    /// How it uses the problem's blocks.
    pub fn block_use(self) -> BlockUse {
        match self {
            Method::Nmci | Method::Certified => BlockUse::Absorbs,
            Method::Sdp => BlockUse::Deflates,
            Method::SdpCuts => BlockUse::AsGiven,
            Method::Ci | Method::Ici | Method::Ei | Method::Naive => BlockUse::None,
        }
    }

    /// Its row of [`RULES`].
    pub fn info(self) -> &'static RuleInfo {
        &RULES[self as usize]
    }

    /// Its name in the JSON contract (`"sdp_cuts"`).
    pub fn name(self) -> &'static str {
        self.info().name
    }

    /// Its chart label (`"nmCI"`).
    pub fn label(self) -> &'static str {
        self.info().label
    }

    /// What its bound is guaranteed for.
    pub fn guarantee(self) -> Guarantee {
        self.info().guarantee
    }

    /// The rule named `name` in the JSON contract.
    pub fn from_name(name: &str) -> Option<Method> {
        RULES.iter().find(|r| r.name == name).map(|r| r.method)
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for Method {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for Method {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = Method;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a method name")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Method, E> {
                Method::from_name(v).ok_or_else(|| E::unknown_variant(v, &NAMES))
            }
        }
        deserializer.deserialize_str(Visitor)
    }
}
