//! The JSON request/response contract shared by `nmci fuse`, the wasm export `fuse`, Python
//! and Rust.
//!
//! A request ([`request`]) names two estimates, the pattern of `P_ab` and a method — or, for
//! N-way CI and nmCI, a list of `estimates` and the patterns of the pairs' cross-covariances —
//! and options that become a validated [`Plan`]; the response ([`response`]) carries the
//! fused estimate, the bound, the gains and the method's own details. Unknown fields are
//! rejected.

mod fields;
pub(crate) mod json;
mod request;
mod response;
mod stack;
mod structure;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::error::{InputError, RequestError, SolveError};
use crate::fusion::bracket::{
    bracket_certificate, gain_certified, trace_upper_bound, upper_bounds, UpperBounds, UpperRule,
};
use crate::fusion::certify::{certified_fusion, Certificates, CertifiedResult, CertifySettings};
use crate::fusion::ci::covariance_intersection;
use crate::fusion::cuts::optimal_fusion_cuts;
use crate::fusion::ei::ellipsoidal_intersection;
use crate::fusion::ici::inverse_covariance_intersection;
use crate::fusion::known::naive_fusion;
use crate::fusion::nmci::non_monolithic_ci;
use crate::fusion::nway::{
    absorb_couplings_nway, covariance_intersection_nway, non_monolithic_ci_nway, NwayResult,
    PairPattern,
};
use crate::fusion::rules::{Guarantee, Method};
use crate::fusion::sdp::optimal_fusion;
use crate::fusion::semidefinite::{self, fuse_semidefinite, SemidefiniteRule};
use crate::fusion::{Criterion, Estimate, Fused, FusionProblem};
use crate::linalg::matrix_to_rows;
use crate::structure::{CrossPattern, StructureSettings};

pub use fields::{field_names, request_fields, response_fields};
pub(crate) use request::{check_blocks, check_count, matrix, unknown_field};
pub use request::{FuseRequest, NwayEstimate, NwayPair, Options, PairInput, Plan};
pub use response::{
    CertifiedDetails, CutsDetails, Details, FuseResponse, Gains, Rows, SdpDetails, StructureDetails,
};
pub(crate) use stack::requests_from;
pub use stack::{fuse_list, fuse_stack, StackRequest, StackResponse};
use structure::details_of;
pub(crate) use structure::{structured, Structured};

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

/// A covariance's size: a response's `trace` and `det` ([`FuseResponse`]), and the explorer's
/// row of each estimate ([`crate::explore::Exploration::estimates`]).
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
        let (trace, det) = Self::trace_det(P);
        Self {
            name: field.into(),
            trace,
            det,
        }
    }

    /// `tr P` and `det P`, as a response reports them.
    #[allow(non_snake_case)]
    pub(crate) fn trace_det(P: &DMatrix<f64>) -> (f64, f64) {
        (P.trace(), crate::linalg::determinant(P))
    }
}

/// A response: the estimate `x`, its bound `P` (with its `trace` and `det`), the gains and the
/// method's details.
#[allow(non_snake_case)]
fn response_of(
    method: Method,
    criterion: Criterion,
    x: &DVector<f64>,
    P: &DMatrix<f64>,
    gains: Gains,
    details: Details,
) -> FuseResponse {
    let summary = CovarianceSummary::of("p", P);
    FuseResponse {
        method,
        criterion,
        x: x.iter().copied().collect(),
        p: matrix_to_rows(P),
        trace: summary.trace,
        det: summary.det,
        gains,
        details,
        structure: None,
    }
}

/// The response of a two-estimate rule: estimate, bound, both gains and `details`.
pub(crate) fn response(
    method: Method,
    criterion: Criterion,
    fused: &Fused,
    details: Details,
) -> FuseResponse {
    let gains = Gains::Pair {
        ka: matrix_to_rows(&fused.K_a),
        kb: matrix_to_rows(&fused.K_b),
    };
    response_of(method, criterion, &fused.x, &fused.P, gains, details)
}

/// Runs a request.
///
/// ```
/// let req: nmci::contract::FuseRequest = serde_json::from_str(
///     r#"{"pa": [[3,0],[0,1]], "pb": [[1,0],[0,4]],
///         "pab_unknown": [[true,false],[false,true]], "method": "nmci"}"#).unwrap();
/// let res = nmci::contract::fuse(&req).unwrap();
/// assert_eq!(res.omega(), Some(vec![0.0, 1.0]));
/// assert_eq!(res.trace, 2.0);
/// ```
pub fn fuse(request: &FuseRequest) -> Result<FuseResponse, RequestError> {
    fuse_planned(request, &request.plan()?)
}

/// [`fuse`] with the request's options already validated into `plan` (the explorer's second
/// stage adjusts its plan: `crate::explore::prove`).
pub(crate) fn fuse_planned(
    request: &FuseRequest,
    plan: &Plan,
) -> Result<FuseResponse, RequestError> {
    if let Some(estimates) = &request.estimates {
        return fuse_nway(
            estimates,
            request.patterns.as_deref().unwrap_or_default(),
            &request.pair.structure_settings(),
            request.method,
            plan.criterion,
        );
    }
    let problem = match request.problem() {
        Ok(problem) => problem,
        Err(RequestError::Input(e)) if semidefinite::definiteness_refusal(&e) => {
            return semidefinite_response(request, plan.criterion, e);
        }
        Err(e) => return Err(e),
    };
    let Structured {
        problem,
        upper,
        details,
        ..
    } = structured(problem, &request.pair.structure_settings(), request.method)?;
    check_blocks(request.method, &problem)?;
    let mut response = match request.method {
        Method::Ci => Ok(ClosedForm::Ci.response(&problem, plan.criterion)?.0),
        Method::Nmci => Ok(ClosedForm::Nmci.response(&problem, plan.criterion)?.0),
        Method::Ici => Ok(ClosedForm::Ici.response(&problem, plan.criterion)?.0),
        Method::Ei => Ok(ClosedForm::Ei.response(&problem, plan.criterion)?.0),
        Method::Naive => Ok(ClosedForm::Naive.response(&problem, plan.criterion)?.0),
        Method::Certified => Ok(certified_response(&problem, &plan.certify)?.0),
        Method::Sdp => {
            let upper = upper.as_ref().unwrap_or(&problem);
            Ok(sdp_response(&problem, upper, plan, None, true)?.0)
        }
        Method::SdpCuts => {
            let cuts = optimal_fusion_cuts(&problem, &plan.cuts)?;
            // Past the time limit the own-gain certificate is left out, not an error (the loop
            // has its bracket).
            // Where the loop proved its own rule, that is the bound for its gain (the least
            // of its proofs); otherwise the certified rule's carried over, or the gain's own.
            let proven = cuts
                .own_rule_proven
                .then(|| cuts.certified.as_ref().map(|c| c.P.clone()))
                .flatten();
            let gain_certified = match proven.map(|p| Ok(Some(p))).unwrap_or_else(|| {
                gain_certified(
                    &problem,
                    &cuts.fused.K_a,
                    &plan.certify,
                    cuts.certified.as_ref(),
                    cuts.lower_bound,
                )
            }) {
                Ok(bound) => bound,
                Err(SolveError::TimeLimit { .. }) => None,
                Err(e) => return Err(e.into()),
            };
            // The loop computed the certified rule already (blocks of up to 6 states); where
            // it proved its own rule, that bound is the own gain's and named so.
            let (certified_upper, own_upper) = if cuts.own_rule_proven {
                (None, cuts.certified_trace)
            } else {
                (cuts.certified_trace, None)
            };
            let own_upper = own_upper
                .into_iter()
                .chain(gain_certified.as_ref().map(trace_upper_bound))
                .reduce(f64::min);
            let uppers = UpperBounds::of(&problem, certified_upper)?;
            let mut gap_closed = cuts.gap_closed;
            if let Some(own) = own_upper {
                gap_closed |= plan.cuts.closes(cuts.lower_bound, own);
            }
            let details = Details::SdpCuts(CutsDetails {
                status: cuts.status,
                iterations: cuts.iterations as u32,
                lmis: cuts.constraints,
                violation: cuts.violation,
                converged: cuts.converged,
                stop: cuts.stop,
                gap_closed,
                // Every proven upper end the response holds: the loop's (the certified rule,
                // or its own rule proven) and the bound for its own gain.
                bracket: uppers.bracket_with_own(cuts.lower_bound, own_upper, UpperRule::SdpCuts),
                certificates: cuts.certificates,
                gain_certified_trace: gain_certified.as_ref().map(trace_upper_bound),
                gain_certified_p: gain_certified.as_ref().map(matrix_to_rows),
                own_rule_proven: cuts.own_rule_proven,
                proof_rounds: cuts.proof_rounds,
            });
            Ok::<_, RequestError>(response(
                Method::SdpCuts,
                Criterion::Trace,
                &cuts.fused,
                details,
            ))
        }
    }?;
    response.structure = details;
    Ok(response)
}

/// A two-estimate request whose covariance `refused` was refused as not positive definite:
/// CI, nmCI, EI and naive fusion in the pseudo-inverse form (`fusion::semidefinite`), ICI by
/// CI's form (its documented fall-back: `method` `ci` in the response), the structure note
/// saying so; the certified rule and the SDPs refuse it as before (their proofs need positive
/// definite covariances).
fn semidefinite_response(
    request: &FuseRequest,
    criterion: Criterion,
    refused: InputError,
) -> Result<FuseResponse, RequestError> {
    let (xa, pa, xb, pb, pattern) = request.pair.parts()?;
    let pair = semidefinite_pair(
        request.method,
        [&xa, &xb],
        [&pa, &pb],
        &pattern,
        criterion,
        refused,
    )?;
    let mut response = response(pair.method, pair.criterion, &pair.fused, pair.details);
    response.structure = Some(pair.structure);
    Ok(response)
}

/// A pair fused in the pseudo-inverse form ([`semidefinite_pair`]).
pub(crate) struct SemidefinitePair {
    /// The rule that fused (`ci` for an `ici` request).
    pub method: Method,
    /// The criterion the response reports.
    pub criterion: Criterion,
    /// The result.
    pub fused: Fused,
    /// The rule's details.
    pub details: Details,
    /// The blocks and the note saying what was done.
    pub structure: StructureDetails,
}

/// The pseudo-inverse form's fusion of a pair whose covariance `refused` was refused as not
/// positive definite, for a request of `method` (see [`semidefinite_response`]; a stack's pairs
/// go through it too, so a stack's pair is the single request's): the refusal itself where the
/// form does not apply.
pub(crate) fn semidefinite_pair(
    method: Method,
    [xa, xb]: [&DVector<f64>; 2],
    [pa, pb]: [&DMatrix<f64>; 2],
    pattern: &CrossPattern,
    criterion: Criterion,
    refused: InputError,
) -> Result<SemidefinitePair, RequestError> {
    let (rule, used) = match method {
        Method::Ci => (SemidefiniteRule::Ci, Method::Ci),
        Method::Nmci => (SemidefiniteRule::Nmci, Method::Nmci),
        Method::Naive => (SemidefiniteRule::Naive, Method::Naive),
        Method::Ei => (SemidefiniteRule::Ei, Method::Ei),
        Method::Ici => (SemidefiniteRule::Ci, Method::Ci),
        Method::Certified | Method::Sdp | Method::SdpCuts => return Err(refused.into()),
    };
    let r = match fuse_semidefinite(rule, xa, pa, xb, pb, pattern, criterion) {
        Ok(r) => r,
        // Not positive semi-definite either: the covariance form's refusal says it best.
        Err(InputError::NotPositiveDefinite { .. }) => return Err(refused.into()),
        Err(e) => return Err(e.into()),
    };
    let details = match rule {
        SemidefiniteRule::Ci => Details::Omega(r.omega[0]),
        SemidefiniteRule::Nmci => Details::Blocks {
            omega: r.omega.clone(),
            blocks: r.blocks.clone(),
        },
        SemidefiniteRule::Naive | SemidefiniteRule::Ei => Details::None,
    };
    let reported = if matches!(rule, SemidefiniteRule::Naive | SemidefiniteRule::Ei) {
        Criterion::default()
    } else {
        criterion
    };
    let how = match method {
        Method::Ici => "ici has no pseudo-inverse form: ci fused it in its pseudo-inverse form instead (conservative for every cross-covariance, so also for the common information ici assumes)".to_string(),
        m => format!("{} fused it in the pseudo-inverse form instead", m.name()),
    };
    let guarantee = match used.guarantee() {
        Guarantee::Conservative => {
            "conservative for every cross-covariance to the rounding of the eigendecomposition"
        }
        _ => "with the rule's own guarantee (none)",
    };
    let note = format!(
        "{refused}: {how}, eigenvalues at most n·ε·λ_max taken as zero and their directions as uninformed; {guarantee} (docs/methods.md, \"Semi-definite covariances\")",
    );
    Ok(SemidefinitePair {
        method: used,
        criterion: reported,
        structure: StructureDetails {
            blocks: r.blocks.clone(),
            exact_blocks: r.blocks.len(),
            coupling_tol: 0.0,
            absorbed: false,
            couplings: Vec::new(),
            trace_added: 0.0,
            nmci_trace_cost: None,
            note: Some(note),
        },
        fused: r.fused,
        details,
    })
}

/// N-way CI (`method` `ci`) or nmCI (`nmci`) of a request's `estimates` and `patterns`.
#[allow(non_snake_case)]
fn fuse_nway(
    estimates: &[NwayEstimate],
    patterns: &[NwayPair],
    settings: &StructureSettings,
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
    // The structure is checked for both rules (a declared partition that contradicts the
    // estimates is refused); only nmCI uses it.
    let (absorbed, pairs, structure) = absorb_couplings_nway(&estimates, &pairs, settings)?;
    let (result, details): (NwayResult, _) = if method == Method::Ci {
        (covariance_intersection_nway(&estimates, criterion)?, None)
    } else {
        let said = structure.worth_saying(settings.blocks.is_some());
        let details = said.then(|| details_of(&structure, settings.coupling_tol, true, None, None));
        (
            non_monolithic_ci_nway(&absorbed, &pairs, criterion)?,
            details,
        )
    };
    let gains = Gains::Nway(result.gains.iter().map(matrix_to_rows).collect());
    let structure_details = details;
    let details = Details::Nway {
        weights: result.omega,
        blocks: result.blocks,
        iterations: result.iterations as u32,
    };
    let mut response = response_of(method, criterion, &result.x, &result.P, gains, details);
    response.structure = structure_details;
    Ok(response)
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
    let details = Details::Certified(CertifiedDetails {
        status: cert.status,
        iterations: cert.iterations,
        blocks: cert.blocks.clone(),
        repair: cert.repair,
        certificates: Certificates::of(cert),
        upper_bound: trace_upper_bound(&cert.fused.P),
    });
    response(Method::Certified, Criterion::Trace, &cert.fused, details)
}

/// The two-estimate rules computed in closed form, without a solver: their result is the
/// fused estimate, its bound, the gains and at most weights ([`fuse_stack`] takes these).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ClosedForm {
    Ci,
    Nmci,
    Ici,
    Ei,
    Naive,
}

impl ClosedForm {
    /// The closed-form rule `method` names, if it names one.
    pub(crate) fn of(method: Method) -> Option<Self> {
        match method {
            Method::Ci => Some(Self::Ci),
            Method::Nmci => Some(Self::Nmci),
            Method::Ici => Some(Self::Ici),
            Method::Ei => Some(Self::Ei),
            Method::Naive => Some(Self::Naive),
            Method::Certified | Method::Sdp | Method::SdpCuts => None,
        }
    }

    /// The method of this rule.
    pub(crate) fn method(self) -> Method {
        match self {
            Self::Ci => Method::Ci,
            Self::Nmci => Method::Nmci,
            Self::Ici => Method::Ici,
            Self::Ei => Method::Ei,
            Self::Naive => Method::Naive,
        }
    }

    /// The criterion the response reports: EI and naive fusion report the default, having no
    /// weight to optimise.
    fn reported(self, criterion: Criterion) -> Criterion {
        match self {
            Self::Ei | Self::Naive => Criterion::default(),
            _ => criterion,
        }
    }

    /// The fused result and the rule's details.
    pub(crate) fn fuse(
        self,
        problem: &FusionProblem,
        criterion: Criterion,
    ) -> Result<(Fused, Details), InputError> {
        Ok(match self {
            Self::Ci => {
                let ci = covariance_intersection(problem, criterion)?;
                (ci.fused, Details::Omega(ci.omega))
            }
            Self::Nmci => {
                let nm = non_monolithic_ci(problem, criterion)?;
                let details = Details::Blocks {
                    omega: nm.omega,
                    blocks: nm.blocks,
                };
                (nm.fused, details)
            }
            Self::Ici => {
                let ici = inverse_covariance_intersection(problem, criterion)?;
                (ici.fused, Details::Omega(ici.omega))
            }
            Self::Ei => (ellipsoidal_intersection(problem)?, Details::None),
            Self::Naive => (naive_fusion(problem), Details::None),
        })
    }

    /// The response and the fused result it was made from.
    pub(crate) fn response(
        self,
        problem: &FusionProblem,
        criterion: Criterion,
    ) -> Result<(FuseResponse, Fused), InputError> {
        let (fused, details) = self.fuse(problem, criterion)?;
        let r = response(self.method(), self.reported(criterion), &fused, details);
        Ok((r, fused))
    }
}

/// The sampled-SDP response: the relaxation of `problem` (the deflated problem when couplings
/// were absorbed, whose proven lower end holds for the given one), the upper ends proven on
/// `upper` (the absorbed problem, or the given one; `structure::absorb`, "A lower end");
/// `uppers` are the certified upper bounds when the caller has already computed them (the
/// bracket's certificates are then not repeated here); `own_gain`: whether to give the proven
/// bound for the SDP's own gain (`gain_certified_p`, `gain_certified_trace`).
pub(crate) fn sdp_response(
    problem: &FusionProblem,
    upper: &FusionProblem,
    plan: &Plan,
    uppers: Option<UpperBounds>,
    own_gain: bool,
) -> Result<(FuseResponse, Fused), SolveError> {
    let opt = optimal_fusion(problem, &plan.sdp)?;
    let (uppers, cert) = match uppers {
        Some(u) => (u, None),
        None => {
            let cert = bracket_certificate(upper, &plan.certify, None)?;
            let uppers = upper_bounds(upper, cert.as_ref().map(|c| &c.fused.P))?;
            (uppers, cert)
        }
    };
    // The certified rule's bound carried over to the SDP's gain, or the gain's own
    // certificate (`fusion::bracket`, "A given gain's bound").
    let gain_certified = if own_gain {
        gain_certified(
            upper,
            &opt.fused.K_a,
            &plan.certify,
            cert.as_ref().map(|c| &c.fused),
            opt.lower_bound,
        )?
    } else {
        None
    };
    let certificates = cert.as_ref().map(Certificates::of);
    let details = Details::Sdp(SdpDetails {
        blocks: opt.blocks.clone(),
        samples: opt.samples,
        status: opt.status,
        iterations: opt.iterations,
        acceptance_rate: opt.acceptance_rate,
        sampler_choice: opt.sampler_choice,
        lmis: opt.lmis,
        worst_sample_margin: opt.worst_sample_margin,
        bracket: uppers.bracket_with_own(
            opt.lower_bound,
            gain_certified.as_ref().map(trace_upper_bound),
            UpperRule::Sdp,
        ),
        certificates,
        gain_certified_trace: gain_certified.as_ref().map(trace_upper_bound),
        gain_certified_p: gain_certified.as_ref().map(matrix_to_rows),
    });
    let r = response(Method::Sdp, Criterion::Trace, &opt.fused, details);
    Ok((r, opt.fused))
}

/// Parses a JSON request, runs it and returns the JSON response; an array of requests gives
/// the array of their responses ([`fuse_list`]).
pub fn fuse_json(request: &str) -> Result<String, RequestError> {
    if request.len() > MAX_REQUEST_BYTES {
        return Err(RequestError::TooLarge {
            bytes: request.len(),
            limit: MAX_REQUEST_BYTES,
        });
    }
    let malformed = |e: serde_json::Error| RequestError::Malformed(e.to_string());
    // Through a `Value`, so that errors name fields, not text positions (`json`).
    let value = json::parse_text(request)?;
    if let serde_json::Value::Array(values) = value {
        // A list: each element read and run as a request alone ([`fuse_list`]).
        let responses = fuse_list(&requests_from(values)?)?;
        return serde_json::to_string_pretty(&responses).map_err(malformed);
    }
    let req: FuseRequest = json::from_value(value, "a request")?;
    let res = fuse(&req)?;
    serde_json::to_string_pretty(&res).map_err(malformed)
}
