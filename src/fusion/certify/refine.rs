//! Three states: cones of directions refined where the certificate is tight (the parent's
//! module docs, "Adaptive cones").
//!
//! Start from the four octants of the half-space `v₃ ≥ 0` ([`cone_generators`]), certify on
//! them, and cut in two ([`bisect`]) the cones that carry the most of the solver's dual — the
//! moment matrix of condition 3, which is where the worst directions of `K J Kᵀ` sit — then
//! certify again on the finer cover, until the trace stops falling, the cone budget is spent
//! or the time limit is reached. Every round's certificate is a complete proof on its own
//! (the cones of any round cover space, [`bisect`] being an exact subdivision), repaired as
//! every certificate is; the smallest proven trace is kept. Nothing here needs to be right for
//! the bound to be proven: the choice of cones only decides how tight it is.

use nalgebra::DMatrix;

use crate::error::SolveError;
use crate::fusion::program::Deadline;
use crate::fusion::upper::trace_upper_bound;
use crate::fusion::FusionProblem;

use super::assemble::Piece;
use super::geometry::{bisect, cone_generators, cone_piece};
use super::settings::CertifySettings;
use super::sos::{certify_pieces, BlockCertificate};

/// A round whose proven trace falls by less than this fraction of the trace ends the
/// refinement (the brackets close at `10⁻⁶`).
const STALL_RTOL: f64 = 1e-8;

/// A cone is cut when its share of the dual is at least this fraction of the largest share.
const SPLIT_SHARE: f64 = 0.05;

/// The adaptive certificate of a three-state block: at most `budget` cones (module docs).
pub(super) fn certify_adaptive(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
    budget: u32,
    settings: &CertifySettings,
) -> Result<BlockCertificate, SolveError> {
    let deadline = Deadline::after(settings.time_limit);
    let mut cones = cone_generators(4)?;
    // The best proof so far and its proven trace.
    let mut best: Option<(f64, BlockCertificate)> = None;
    loop {
        let pieces: Vec<Piece> = cones
            .iter()
            .map(|u| Piece {
                multipliers: cone_piece(u),
            })
            .collect();
        let round = CertifySettings {
            time_limit: settings.time_limit.map(|_| deadline.remaining()),
            ..*settings
        };
        let (certificate, shares) = match certify_pieces(problem, gain, 1, &pieces, &round) {
            Ok(solved) => solved,
            // A finer round that fails or runs out of time leaves the proof already found.
            Err(
                SolveError::SolverFailed { .. }
                | SolveError::NotProven { .. }
                | SolveError::TimeLimit { .. },
            ) if best.is_some() => break,
            Err(e) => return Err(e),
        };
        let trace = trace_upper_bound(&certificate.P);
        let previous = best.as_ref().map(|(p, _)| *p);
        let stalled = previous.is_some_and(|p| p - trace <= STALL_RTOL * p.abs());
        if previous.is_none_or(|p| trace < p) {
            best = Some((trace, certificate));
        }
        if stalled || cones.len() >= budget as usize || deadline.passed() {
            break;
        }
        let largest = shares.iter().copied().fold(0.0, f64::max);
        let mut order: Vec<usize> = (0..cones.len()).collect();
        order.sort_by(|&a, &b| shares[b].total_cmp(&shares[a]));
        let room = budget as usize - cones.len();
        let mut cut = vec![false; cones.len()];
        for k in order
            .into_iter()
            .filter(|&k| shares[k] >= SPLIT_SHARE * largest && largest > 0.0)
            .take(room)
        {
            cut[k] = true;
        }
        let mut next = Vec::with_capacity(cones.len() + room);
        for (u, &cut) in cones.iter().zip(&cut) {
            match cut.then(|| bisect(u)).flatten() {
                Some(halves) => next.extend(halves),
                None => next.push(*u),
            }
        }
        if next.len() == cones.len() {
            break;
        }
        cones = next;
    }
    best.map(|(_, certificate)| certificate)
        .ok_or_else(|| SolveError::SolverFailed {
            status: "no round of the adaptive cones solved".into(),
            iterations: 0,
        })
}
