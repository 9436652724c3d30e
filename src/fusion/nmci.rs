//! Non-monolithic covariance intersection (nmCI): one CI weight per independent block.
//!
//! The paper's nmGMD (eq. (nmGMD)) fuses independent parts of the state with their own
//! weights `ω = [ω_x, ω_y, …]`. Here the parts are found, not declared: they are the
//! [`independent_blocks`](crate::structure::independent_blocks) of `P_a`, `P_b` and the cross pattern.
//! Each block is fused by exact CI; the bound and gains are block-diagonal in that
//! partition. With a single block nmCI is CI.

use super::ci::covariance_intersection;
use super::{per_block, Criterion, Fused, FusionProblem};
use crate::error::InputError;
use crate::structure::independent_blocks;

/// nmCI result: the fused estimate, the blocks and one weight per block.
#[derive(Debug, Clone, PartialEq)]
pub struct NmciResult {
    /// Fused estimate, bound and gains.
    pub fused: Fused,
    /// One CI weight per block, in the order of `blocks`.
    pub omega: Vec<f64>,
    /// The independent blocks (state indices, ascending; blocks ordered by first state).
    pub blocks: Vec<Vec<usize>>,
}

/// Non-monolithic CI.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::{Criterion, CrossPattern, FusionProblem, rules::non_monolithic_ci};
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap();
/// assert_eq!(nm.omega, vec![0.0, 1.0]);
/// assert_eq!(nm.fused.P, DMatrix::identity(2, 2));
/// ```
#[allow(non_snake_case)]
pub fn non_monolithic_ci(
    problem: &FusionProblem,
    criterion: Criterion,
) -> Result<NmciResult, InputError> {
    let blocks = independent_blocks(&problem.P_a, &problem.P_b, &problem.cross_pattern);
    let mut omega = Vec::with_capacity(blocks.len());
    let fused = per_block(problem, &blocks, |_, sub| {
        let ci = covariance_intersection(&sub, criterion)?;
        omega.push(ci.omega);
        Ok::<_, InputError>((ci.fused.K_a, ci.fused.P))
    })?;
    Ok(NmciResult {
        fused,
        omega,
        blocks,
    })
}
