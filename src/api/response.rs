//! A response: the fields every rule reports, and each method's own details.
//!
//! In Rust a response is [`FuseResponse`]: the estimate and its bound, the [`Gains`] (two
//! estimates or N-way) and the method's [`Details`] — a type per kind of rule, so a field
//! exists exactly where the method computes it. In JSON it is one flat object (the contract
//! of docs/contract.md, unchanged by this typing): a private wire struct is what serde
//! writes and reads, and the derived fields (`guarantee`, `gap`, `gap_relative`,
//! `upper_bound_rule` of the certified rule) are computed from the typed ones when written.

use serde::{Deserialize, Serialize};

use crate::fusion::bracket::Bracket;
use crate::fusion::certify::Certificates;
use crate::fusion::cuts::CutsStop;
use crate::fusion::rules::{Guarantee, Method};
use crate::fusion::sample::AutoChoice;
use crate::fusion::sdp::SdpStatus;
use crate::fusion::Criterion;

/// Nested rows of a matrix.
pub type Rows = Vec<Vec<f64>>;

/// A fusion response (see docs/contract.md for the JSON form).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(into = "ResponseWire", try_from = "ResponseWire")]
pub struct FuseResponse {
    /// The rule used.
    pub method: Method,
    /// The criterion minimised (the default for rules without a weight).
    pub criterion: Criterion,
    /// Fused estimate.
    pub x: Vec<f64>,
    /// Covariance bound, nested rows.
    pub p: Rows,
    /// `tr P`.
    pub trace: f64,
    /// `det P`.
    pub det: f64,
    /// The gains.
    pub gains: Gains,
    /// What this method reports beyond the estimate.
    pub details: Details,
    /// How the problem's blocks were found, when that is worth saying (near-zero couplings
    /// absorbed, declared blocks, or a weak coupling keeping blocks merged); rules that use
    /// the blocks only (nmCI, the certified rule, the SDPs, N-way nmCI).
    pub structure: Option<StructureDetails>,
}

/// What a response says of the problem's structure (`structure::absorb`'s module docs): the
/// blocks, what was absorbed to keep them and what it cost, and a sentence for a person.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StructureDetails {
    /// The blocks the rule exploited.
    pub blocks: Vec<Vec<usize>>,
    /// How many blocks exact zeros alone give.
    pub exact_blocks: usize,
    /// The coupling tolerance used.
    pub coupling_tol: f64,
    /// Whether the couplings were absorbed: `false` for the cutting planes (`sdp_cuts`), which
    /// stop on a bracket computed on the problem they solve and so solve the covariances as
    /// given. The sampled SDP solves the deflated problem (`structure::absorb`, "A lower
    /// end"), its upper ends the absorbed one.
    pub absorbed: bool,
    /// The couplings absorbed (empty when `absorbed` is false).
    pub couplings: Vec<crate::structure::Coupling>,
    /// `tr P̄_a + tr P̄_b − tr P_a − tr P_b`: what the absorption added to the covariances.
    pub trace_added: f64,
    /// What it cost nmCI: its trace on the absorbed problem minus its trace on the same
    /// covariances with the couplings set to zero (not a bound for the given problem; absent
    /// when those are not positive definite or nothing was absorbed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nmci_trace_cost: Option<f64>,
    /// A sentence for a person (the CLI prints it on stderr, the page beside the numbers).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// The gains of a response.
#[derive(Debug, Clone, PartialEq)]
pub enum Gains {
    /// Two estimates: `x = K_a x_a + K_b x_b` (JSON `ka`, `kb`).
    Pair {
        /// `K_a`.
        ka: Rows,
        /// `K_b`.
        kb: Rows,
    },
    /// N-way: one gain per estimate, `x = Σᵢ Kᵢ xᵢ`, `Σᵢ Kᵢ = I` (JSON `gains`).
    Nway(Vec<Rows>),
}

/// What a method reports beyond the estimate, its bound and the gains.
#[derive(Debug, Clone, PartialEq)]
pub enum Details {
    /// EI and naive fusion: nothing more.
    None,
    /// CI and ICI: the weight `ω` (JSON `omega: [ω]`).
    Omega(f64),
    /// nmCI: the independent blocks (0-based state indices) and one `ω` per block.
    Blocks {
        /// One `ω` per block (JSON `omega`).
        omega: Vec<f64>,
        /// The blocks.
        blocks: Vec<Vec<usize>>,
    },
    /// N-way CI and nmCI.
    Nway {
        /// Per block, the weight `ωᵢ` of each estimate (on the simplex).
        weights: Vec<Vec<f64>>,
        /// The blocks.
        blocks: Vec<Vec<usize>>,
        /// Newton iterations (0 when two estimates went to the exact pairwise CI).
        iterations: u32,
    },
    /// The sampled SDP.
    Sdp(SdpDetails),
    /// The cutting-plane SDP.
    SdpCuts(CutsDetails),
    /// The certified rule.
    Certified(CertifiedDetails),
}

/// The sampled SDP's report.
#[derive(Debug, Clone, PartialEq)]
pub struct SdpDetails {
    /// The independent blocks; one SDP is solved per block.
    pub blocks: Vec<Vec<usize>>,
    /// Number of samples.
    pub samples: usize,
    /// Clarabel's status.
    pub status: SdpStatus,
    /// Interior-point iterations (all working-set rounds).
    pub iterations: u32,
    /// Rejection-sampler acceptance rate.
    pub acceptance_rate: f64,
    /// With `sampler: "auto"`: the sampler chosen and the pilot it was chosen by.
    pub sampler_choice: Option<AutoChoice>,
    /// LMIs in the final working set.
    pub lmis: usize,
    /// Smallest `λ_min(P̄ − K P'_i Kᵀ)` over the samples.
    pub worst_sample_margin: f64,
    /// The proven bracket on the robust optimum of `tr P̄` (`fusion::bracket`, with the
    /// argument; JSON `lower_bound`, `upper_bound`, `upper_bound_rule`, `gap` — rounded up,
    /// never negative — and `gap_relative`). Lower end: the solver's dual matrices turned into
    /// a Lagrangian bound checked in exact arithmetic (summed over blocks, rounded down), which
    /// holds whatever the solver's accuracy. Upper end: the rounded-up trace of the best
    /// conservative rule — CI, nmCI (recomputed with Young's inequality in exact arithmetic)
    /// or the certified rule (when every independent block has at most
    /// [`crate::bounds::BRACKET_CERTIFY_MAX_BLOCK`] states); ties go to CI / nmCI.
    pub bracket: Option<Bracket>,
    /// The certified rule in the bracket (blocks of at most
    /// [`crate::bounds::BRACKET_CERTIFY_MAX_BLOCK`] states; absent when the caller gave the upper ends).
    pub certificates: Option<Certificates>,
    /// The trace, rounded up, of a bound proven to hold for this method's own gain and every
    /// admissible `P_ab`: an upper bound on what that gain costs when the bound must hold for
    /// all of them. The certified rule's bound carried over to the gain where that closes the
    /// gain's bracket, else the smaller of it and the gain's own certificate (`certify_gain`;
    /// whichever exists alone; `None` when neither does); see `fusion::bracket`, "A given
    /// gain's bound".
    pub gain_certified_trace: Option<f64>,
    /// That bound (nested rows, symmetric): `P̄ ⪰ K P' Kᵀ` for this method's own gain and
    /// every admissible `P_ab`, proven with rounding accounted for, so `(x, gain_certified_p)`
    /// is a conservative estimate to use in a filter where `p` (the relaxation's) is not;
    /// `gain_certified_trace` is its trace rounded up.
    pub gain_certified_p: Option<Rows>,
}

/// The cutting-plane SDP's report.
#[derive(Debug, Clone, PartialEq)]
pub struct CutsDetails {
    /// Clarabel's status of the last program.
    pub status: SdpStatus,
    /// Outer iterations.
    pub iterations: u32,
    /// Constraints (starting samples and cuts; JSON `lmis`).
    pub lmis: usize,
    /// The worst `λ_max(K P' Kᵀ − P̄)` the last worst-case search found.
    pub violation: f64,
    /// Whether that violation is below the tolerance or the gap closed.
    pub converged: bool,
    /// Why the loop stopped.
    pub stop: CutsStop,
    /// Whether the loop stopped because its proven lower bound reached the certified rule's
    /// proven trace within the loop's tolerance: the robust optimum is then proven to that
    /// relative accuracy (and attained to it by method `certified`).
    pub gap_closed: bool,
    /// The proven bracket, as [`SdpDetails::bracket`].
    pub bracket: Option<Bracket>,
    /// The certified rule in the loop (blocks of at most 6 states).
    pub certificates: Option<Certificates>,
    /// As [`SdpDetails::gain_certified_trace`] (absent past the time limit).
    pub gain_certified_trace: Option<f64>,
    /// As [`SdpDetails::gain_certified_p`] (absent past the time limit). Where
    /// `own_rule_proven` it is the bound the proof of the loop's own rule gave (the gain is the
    /// same, so nothing is carried over), unless its trace leaves the gain's bracket open and
    /// the gain's own certificate gives a smaller one.
    pub gain_certified_p: Option<Rows>,
    /// Whether the bracket's certified upper end is the loop's own rule proven on cones of
    /// directions (`CutsResult::own_rule_proven`; then `certificates` gives level 1 and the
    /// number of cones).
    pub own_rule_proven: bool,
    /// Rounds in which the own rule's proof pointed the search to violations it had missed and
    /// the loop went on (`CutsResult::proof_rounds`, at most 2).
    pub proof_rounds: usize,
}

/// The certified rule's report.
#[derive(Debug, Clone, PartialEq)]
pub struct CertifiedDetails {
    /// How the (last) solve ended.
    pub status: SdpStatus,
    /// Interior-point iterations.
    pub iterations: u32,
    /// The independent blocks.
    pub blocks: Vec<Vec<usize>>,
    /// The trace its floating-point repair added to the solver's (the certificate is made
    /// exact and proven; see `certified_fusion`).
    pub repair: f64,
    /// The certificate on each block.
    pub certificates: Certificates,
    /// The trace rounded up: a proven upper bound on the robust optimum (JSON `upper_bound`,
    /// with `upper_bound_rule: "certified"`).
    pub upper_bound: f64,
}

impl FuseResponse {
    /// What the bound is guaranteed for ([`Method::guarantee`]; JSON `guarantee`):
    /// `conservative` (CI, nmCI, the certified rule: every admissible `P_ab`; for CI and nmCI
    /// the exact bound, the reported `P` within `4 ε κ` relative of it, `κ` the larger
    /// condition number of `P_a`, `P_b`, on the pairs measured against 50-digit references), `relaxation` (`sdp`,
    /// `sdp_cuts`: imposed for the drawn or found `P_ab` only, to the solver's tolerance; see
    /// the bracket), `common_information` (ICI) or `none` (EI, naive).
    pub fn guarantee(&self) -> Guarantee {
        self.method.guarantee()
    }

    /// `K_a` and `K_b` of a two-estimate response.
    pub fn pair_gains(&self) -> Option<(&Rows, &Rows)> {
        match &self.gains {
            Gains::Pair { ka, kb } => Some((ka, kb)),
            Gains::Nway(_) => None,
        }
    }

    /// The weights `ω`: CI and ICI one, nmCI one per block.
    pub fn omega(&self) -> Option<Vec<f64>> {
        match &self.details {
            Details::Omega(w) => Some(vec![*w]),
            Details::Blocks { omega, .. } => Some(omega.clone()),
            _ => None,
        }
    }

    /// The independent blocks (nmCI, N-way, the SDP, the certified rule).
    pub fn blocks(&self) -> Option<&Vec<Vec<usize>>> {
        match &self.details {
            Details::Blocks { blocks, .. } | Details::Nway { blocks, .. } => Some(blocks),
            Details::Sdp(d) => Some(&d.blocks),
            Details::Certified(d) => Some(&d.blocks),
            _ => None,
        }
    }

    /// The proven bracket of `sdp` and `sdp_cuts`.
    pub fn bracket(&self) -> Option<&Bracket> {
        match &self.details {
            Details::Sdp(d) => d.bracket.as_ref(),
            Details::SdpCuts(d) => d.bracket.as_ref(),
            _ => None,
        }
    }

    /// The proven upper bound on the robust optimum this response gives: the bracket's upper
    /// end, or the certified rule's own trace rounded up.
    pub fn upper_bound(&self) -> Option<f64> {
        match &self.details {
            Details::Certified(d) => Some(d.upper_bound),
            _ => self.bracket().map(|b| b.upper),
        }
    }

    /// The certified rule's certificates (its own, or the bracket's).
    pub fn certificates(&self) -> Option<&Certificates> {
        match &self.details {
            Details::Sdp(d) => d.certificates.as_ref(),
            Details::SdpCuts(d) => d.certificates.as_ref(),
            Details::Certified(d) => Some(&d.certificates),
            _ => None,
        }
    }
}

/// The JSON object of a response (docs/contract.md): every field of every method, flat.
#[derive(Serialize, Deserialize)]
struct ResponseWire {
    method: Method,
    criterion: Criterion,
    x: Vec<f64>,
    p: Rows,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    ka: Option<Rows>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    kb: Option<Rows>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gains: Option<Vec<Rows>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    weights: Option<Vec<Vec<f64>>>,
    trace: f64,
    det: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    omega: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    blocks: Option<Vec<Vec<usize>>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    samples: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    status: Option<SdpStatus>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    iterations: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    acceptance_rate: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sampler_choice: Option<AutoChoice>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    lmis: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    worst_sample_margin: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    lower_bound: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    upper_bound: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    upper_bound_rule: Option<Method>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gap: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gap_relative: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    repair: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gain_certified_trace: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gain_certified_p: Option<Rows>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    levels: Option<Vec<u32>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sectors: Option<Vec<u32>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    stop: Option<CutsStop>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    violation: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    converged: Option<bool>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gap_closed: Option<bool>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    own_rule_proven: Option<bool>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    proof_rounds: Option<usize>,
    guarantee: Guarantee,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    structure: Option<StructureDetails>,
}

impl ResponseWire {
    /// The bracket's five fields.
    fn set_bracket(&mut self, b: Option<&Bracket>) {
        if let Some(b) = b {
            self.lower_bound = Some(b.lower);
            self.upper_bound = Some(b.upper);
            self.upper_bound_rule = Some(b.upper_rule.into());
            self.gap = Some(b.gap());
            self.gap_relative = Some(b.gap_relative());
        }
    }

    fn set_certificates(&mut self, c: Option<&Certificates>) {
        if let Some(c) = c {
            self.levels = Some(c.levels.clone());
            self.sectors = Some(c.sectors.clone());
        }
    }

    /// The bracket, when the JSON has one.
    fn bracket(&self) -> Option<Bracket> {
        Some(Bracket {
            lower: self.lower_bound?,
            upper: self.upper_bound?,
            upper_rule: self.upper_bound_rule?.upper_rule()?,
        })
    }

    fn certificates(&mut self) -> Option<Certificates> {
        Some(Certificates {
            levels: self.levels.take()?,
            sectors: self.sectors.take()?,
        })
    }
}

impl From<FuseResponse> for ResponseWire {
    fn from(r: FuseResponse) -> Self {
        let guarantee = r.guarantee();
        let mut w = ResponseWire {
            method: r.method,
            criterion: r.criterion,
            x: r.x,
            p: r.p,
            ka: None,
            kb: None,
            gains: None,
            weights: None,
            trace: r.trace,
            det: r.det,
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
            gain_certified_trace: None,
            gain_certified_p: None,
            levels: None,
            sectors: None,
            stop: None,
            violation: None,
            converged: None,
            gap_closed: None,
            own_rule_proven: None,
            proof_rounds: None,
            guarantee,
            structure: r.structure,
        };
        match r.gains {
            Gains::Pair { ka, kb } => (w.ka, w.kb) = (Some(ka), Some(kb)),
            Gains::Nway(gains) => w.gains = Some(gains),
        }
        match r.details {
            Details::None => {}
            Details::Omega(omega) => w.omega = Some(vec![omega]),
            Details::Blocks { omega, blocks } => (w.omega, w.blocks) = (Some(omega), Some(blocks)),
            Details::Nway {
                weights,
                blocks,
                iterations,
            } => {
                w.weights = Some(weights);
                w.blocks = Some(blocks);
                w.iterations = Some(iterations);
            }
            Details::Sdp(d) => {
                w.samples = Some(d.samples);
                w.status = Some(d.status);
                w.iterations = Some(d.iterations);
                w.acceptance_rate = Some(d.acceptance_rate);
                w.sampler_choice = d.sampler_choice;
                w.lmis = Some(d.lmis);
                w.worst_sample_margin = Some(d.worst_sample_margin);
                w.blocks = Some(d.blocks);
                w.gain_certified_trace = d.gain_certified_trace;
                w.gain_certified_p = d.gain_certified_p;
                w.set_certificates(d.certificates.as_ref());
                w.set_bracket(d.bracket.as_ref());
            }
            Details::SdpCuts(d) => {
                w.status = Some(d.status);
                w.iterations = Some(d.iterations);
                w.lmis = Some(d.lmis);
                w.violation = Some(d.violation);
                w.converged = Some(d.converged);
                w.stop = Some(d.stop);
                w.gain_certified_trace = d.gain_certified_trace;
                w.gain_certified_p = d.gain_certified_p;
                w.gap_closed = Some(d.gap_closed);
                w.own_rule_proven = Some(d.own_rule_proven);
                w.proof_rounds = Some(d.proof_rounds);
                w.set_certificates(d.certificates.as_ref());
                w.set_bracket(d.bracket.as_ref());
            }
            Details::Certified(d) => {
                w.status = Some(d.status);
                w.iterations = Some(d.iterations);
                w.blocks = Some(d.blocks);
                w.repair = Some(d.repair);
                w.set_certificates(Some(&d.certificates));
                w.upper_bound = Some(d.upper_bound);
                w.upper_bound_rule = Some(Method::Certified);
            }
        }
        w
    }
}

/// `Err` "missing field `name` in a `method` response".
fn need<T>(value: Option<T>, name: &str, method: Method) -> Result<T, String> {
    value.ok_or_else(|| format!("missing field `{name}` in a \"{}\" response", method.name()))
}

impl TryFrom<ResponseWire> for FuseResponse {
    type Error = String;

    fn try_from(mut w: ResponseWire) -> Result<Self, String> {
        let m = w.method;
        let gains = match (w.ka.take(), w.kb.take(), w.gains.take()) {
            (Some(ka), Some(kb), None) => Gains::Pair { ka, kb },
            (None, None, Some(gains)) => Gains::Nway(gains),
            _ => return Err("a response has `ka` and `kb`, or `gains` (N-way)".into()),
        };
        let nway = matches!(gains, Gains::Nway(_));
        let details = match m {
            _ if nway => Details::Nway {
                weights: need(w.weights.take(), "weights", m)?,
                blocks: need(w.blocks.take(), "blocks", m)?,
                iterations: need(w.iterations, "iterations", m)?,
            },
            Method::Ci | Method::Ici => match need(w.omega.take(), "omega", m)?.as_slice() {
                [omega] => Details::Omega(*omega),
                _ => return Err(format!("a \"{}\" response has one `omega`", m.name())),
            },
            Method::Nmci => Details::Blocks {
                omega: need(w.omega.take(), "omega", m)?,
                blocks: need(w.blocks.take(), "blocks", m)?,
            },
            Method::Ei | Method::Naive => Details::None,
            Method::Sdp => Details::Sdp(SdpDetails {
                blocks: need(w.blocks.take(), "blocks", m)?,
                samples: need(w.samples, "samples", m)?,
                status: need(w.status, "status", m)?,
                iterations: need(w.iterations, "iterations", m)?,
                acceptance_rate: need(w.acceptance_rate, "acceptance_rate", m)?,
                sampler_choice: w.sampler_choice,
                lmis: need(w.lmis, "lmis", m)?,
                worst_sample_margin: need(w.worst_sample_margin, "worst_sample_margin", m)?,
                bracket: w.bracket(),
                certificates: w.certificates(),
                gain_certified_trace: w.gain_certified_trace,
                gain_certified_p: w.gain_certified_p.take(),
            }),
            Method::SdpCuts => Details::SdpCuts(CutsDetails {
                status: need(w.status, "status", m)?,
                iterations: need(w.iterations, "iterations", m)?,
                lmis: need(w.lmis, "lmis", m)?,
                violation: need(w.violation, "violation", m)?,
                converged: need(w.converged, "converged", m)?,
                stop: need(w.stop, "stop", m)?,
                gap_closed: need(w.gap_closed, "gap_closed", m)?,
                bracket: w.bracket(),
                certificates: w.certificates(),
                gain_certified_trace: w.gain_certified_trace,
                gain_certified_p: w.gain_certified_p.take(),
                own_rule_proven: need(w.own_rule_proven, "own_rule_proven", m)?,
                proof_rounds: need(w.proof_rounds, "proof_rounds", m)?,
            }),
            Method::Certified => Details::Certified(CertifiedDetails {
                status: need(w.status, "status", m)?,
                iterations: need(w.iterations, "iterations", m)?,
                blocks: need(w.blocks.take(), "blocks", m)?,
                repair: need(w.repair, "repair", m)?,
                certificates: need(w.certificates(), "levels", m)?,
                upper_bound: need(w.upper_bound, "upper_bound", m)?,
            }),
        };
        Ok(FuseResponse {
            method: m,
            criterion: w.criterion,
            x: w.x,
            p: w.p,
            trace: w.trace,
            det: w.det,
            gains,
            details,
            structure: w.structure,
        })
    }
}
