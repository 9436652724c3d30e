//! The structure of a request's problem: declared `blocks` and `coupling_tol` applied
//! (`structure::absorb`), the problem each rule solves, and the response's
//! [`StructureDetails`].

use nalgebra::DMatrix;

use super::response::StructureDetails;
use crate::error::InputError;
use crate::fusion::nmci::non_monolithic_ci;
use crate::fusion::rules::{BlockUse, Method};
use crate::fusion::{Criterion, FusionProblem};
use crate::structure::absorb::block_of;
use crate::structure::{absorb_couplings, independent_blocks, BlockStructure, StructureSettings};

/// A problem ready for a rule: the one it solves and what the response says of it.
pub(crate) struct Structured {
    /// The absorbed problem for rules that absorb, the deflated one for the sampled SDP (when
    /// there is one), the given one otherwise.
    pub problem: FusionProblem,
    /// The problem whose proven upper ends hold for the given one: the absorbed problem (the
    /// given one itself when nothing was absorbed); `None` for the CI family, which has none.
    pub upper: Option<FusionProblem>,
    /// The problem the sampled SDP solves: the deflated one when there is one, the given one
    /// otherwise (`structure::absorb`, "A lower end"); `None` for the CI family.
    pub relaxed: Option<FusionProblem>,
    /// The response's `structure`.
    pub details: Option<StructureDetails>,
}

/// Applies `settings` to `problem` for `method` (every method: a declared partition that
/// contradicts the problem is refused whatever the rule).
pub(crate) fn structured(
    problem: FusionProblem,
    settings: &StructureSettings,
    method: Method,
) -> Result<Structured, InputError> {
    if method.block_use() == BlockUse::None && settings.blocks.is_none() {
        // The CI family (CI, ICI, EI, naive) fuses the given covariances whatever their
        // structure, says nothing of it, and has no upper end to prove on an absorbed problem:
        // with no declared partition to check, the settings are all there is to validate.
        settings.validate(problem.dim())?;
        return Ok(Structured {
            problem,
            upper: None,
            relaxed: None,
            details: None,
        });
    }
    let absorbed = absorb_couplings(&problem, settings)?;
    let said = absorbed.structure.worth_saying(settings.blocks.is_some());
    let tol = settings.coupling_tol;
    let relaxed = absorbed.deflated.clone().unwrap_or_else(|| problem.clone());
    let (solved, details) = match (method.block_use(), &absorbed.deflated) {
        (BlockUse::None, _) => (problem.clone(), None),
        (BlockUse::Absorbs, _) => {
            let details = said.then(|| {
                let cost = nmci_trace_cost(&problem, &absorbed.problem, &absorbed.structure);
                details_of(&absorbed.structure, tol, true, cost, None)
            });
            (absorbed.problem.clone(), details)
        }
        (BlockUse::Deflates, Some(deflated)) => {
            let lead = format!(
                "rule {} solves the covariances with the couplings dropped and the diagonal lowered by as much (a problem whose robust optimum is at most the given one's), so its proven lower end holds for the given problem; its upper end is proven on the absorbed problem",
                method.name()
            );
            let details = details_of(&absorbed.structure, tol, true, None, Some(lead));
            (deflated.clone(), Some(details))
        }
        (BlockUse::Deflates, None) | (BlockUse::AsGiven, _) => {
            let why = if method.block_use() == BlockUse::AsGiven {
                "stops on a bracket computed on the problem it solves, whose lower end must hold for the covariances as given"
            } else {
                "would need the covariances with their diagonal lowered, which are not proven positive definite"
            };
            let details = said.then(|| as_given(&problem, &absorbed.structure, tol, method, why));
            (problem.clone(), details)
        }
    };
    Ok(Structured {
        problem: solved,
        upper: Some(absorbed.problem),
        relaxed: Some(relaxed),
        details,
    })
}

/// The `structure` of a rule that solves the covariances as given (module docs of
/// `structure::absorb`, "A lower end"): the given problem's blocks, and `why` nothing was
/// absorbed.
fn as_given(
    problem: &FusionProblem,
    s: &BlockStructure,
    tol: f64,
    method: Method,
    why: &str,
) -> StructureDetails {
    let exact = independent_blocks(&problem.P_a, &problem.P_b, &problem.cross_pattern);
    let kept = (!s.couplings.is_empty()).then(|| {
        format!(
            "{} near-zero coupling{} not absorbed: rule {} {why}, so it solves their {} block{} ({} with absorption, as nmci, certified and sdp use)",
            s.couplings.len(),
            if s.couplings.len() == 1 { " was" } else { "s were" },
            method.name(),
            exact.len(),
            if exact.len() == 1 { "" } else { "s" },
            s.blocks.len(),
        )
    });
    let as_given = BlockStructure {
        blocks: exact,
        couplings: Vec::new(),
        exact_blocks: s.exact_blocks,
        near_miss: s.near_miss.clone(),
    };
    details_of(&as_given, tol, false, None, kept)
}

/// The response's structure of `s`, with a first sentence `lead` before its own note.
pub(crate) fn details_of(
    s: &BlockStructure,
    tol: f64,
    absorbed: bool,
    nmci_trace_cost: Option<f64>,
    lead: Option<String>,
) -> StructureDetails {
    let note = [lead, s.note(tol)]
        .into_iter()
        .flatten()
        .collect::<Vec<_>>()
        .join("; ");
    StructureDetails {
        blocks: s.blocks.clone(),
        exact_blocks: s.exact_blocks,
        coupling_tol: tol,
        absorbed,
        couplings: s.couplings.clone(),
        trace_added: s.trace_added(),
        nmci_trace_cost,
        note: (!note.is_empty()).then_some(note),
    }
}

/// nmCI's trace on the absorbed problem minus its trace on `given` with the couplings set to
/// zero (`StructureDetails::nmci_trace_cost`); `None` when nothing was absorbed or those
/// covariances are not positive definite.
#[allow(non_snake_case)]
fn nmci_trace_cost(
    given: &FusionProblem,
    absorbed: &FusionProblem,
    s: &BlockStructure,
) -> Option<f64> {
    if s.couplings.is_empty() {
        return None;
    }
    let n = given.dim();
    let of = block_of(n, &s.blocks);
    let drop = |P: &DMatrix<f64>| {
        DMatrix::from_fn(n, n, |i, j| if of[i] == of[j] { P[(i, j)] } else { 0.0 })
    };
    let dropped = FusionProblem::new(
        given.x_a.clone(),
        drop(&given.P_a),
        given.x_b.clone(),
        drop(&given.P_b),
        given.cross_pattern.clone(),
    )
    .ok()?;
    let with = non_monolithic_ci(absorbed, Criterion::Trace).ok()?;
    let without = non_monolithic_ci(&dropped, Criterion::Trace).ok()?;
    Some(with.fused.trace() - without.fused.trace())
}
