//! CI's entry points: [`covariance_intersection`], its block-diagonal forms, the covariance at a
//! given `ω`, and the in-place forms the study runs.

use nalgebra::DMatrix;

use crate::error::InputError;
use crate::fusion::{
    covariance_twins, scatter_block, BlockMean, Criterion, Fused, FusionProblem, MeanPlan,
};

use super::omega::{optimal_omega, ENDPOINT_TIE, FLAT_OMEGA};
use super::pencil::{HalfPencil, Pencil};

/// CI result: the fused estimate and the optimal weight `ω` on estimate `a`.
#[derive(Debug, Clone, PartialEq)]
pub struct CiResult {
    /// Fused estimate, bound and gains.
    pub fused: Fused,
    /// Weight on `P_a⁻¹` (`0` = take `b`, `1` = take `a`).
    pub omega: f64,
}

/// `(P, K_a, K_b)` of one pencil at `ω`, exact at the endpoints and, for equal covariances,
/// at the flat criterion's midpoint (`P = P_b`, `K_a = K_b = ½I`).
#[allow(non_snake_case)]
pub(super) fn fuse_at(
    pencil: &Pencil,
    P_a: &DMatrix<f64>,
    P_b: &DMatrix<f64>,
    omega: f64,
) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let n = P_a.nrows();
    let (P, K_a) = if omega == 0.0 {
        (P_b.clone(), DMatrix::zeros(n, n))
    } else if omega == 1.0 {
        (P_a.clone(), DMatrix::identity(n, n))
    } else if omega == FLAT_OMEGA && P_a == P_b {
        (P_b.clone(), DMatrix::identity(n, n) * FLAT_OMEGA)
    } else {
        let P = pencil.covariance(omega);
        let mut K_a = pencil.gain_b(omega);
        from_identity(&mut K_a);
        (P, K_a)
    };
    let mut K_b = K_a.clone();
    from_identity(&mut K_b);
    (P, K_a, K_b)
}

/// `K ← I − K`, entry by entry as `DMatrix::identity(n, n) − K` computes it (`1 − k` on the
/// diagonal, `0 − k` off it), without the two temporaries.
#[allow(non_snake_case)]
fn from_identity(K: &mut DMatrix<f64>) {
    for (j, mut col) in K.column_iter_mut().enumerate() {
        for (i, k) in col.iter_mut().enumerate() {
            *k = if i == j { 1.0 } else { 0.0 } - *k;
        }
    }
}

/// The CI covariance `P(ω) = (ω P_a⁻¹ + (1−ω) P_b⁻¹)⁻¹` for a given weight `ω ∈ [0, 1]`
/// (`ω = 0` gives `P_b` and `ω = 1` gives `P_a`, exactly; any other `ω`, NaN included, is
/// [`InputError::WeightOutOfRange`]).
#[allow(non_snake_case)]
pub fn ci_covariance(problem: &FusionProblem, omega: f64) -> Result<DMatrix<f64>, InputError> {
    if !(0.0..=1.0).contains(&omega) {
        return Err(InputError::WeightOutOfRange {
            name: "omega".into(),
            value: omega,
        });
    }
    if omega == 0.0 {
        return Ok(problem.P_b.clone());
    }
    if omega == 1.0 {
        return Ok(problem.P_a.clone());
    }
    Ok(Pencil::new(&problem.P_a, &problem.P_b)?.covariance(omega))
}

/// Covariance intersection with the weight that exactly minimises `criterion`.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::{Criterion, CrossPattern, FusionProblem, rules::covariance_intersection};
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::fully_unknown(2)).unwrap();
/// let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
/// assert!(ci.omega > 0.0 && ci.omega < 1.0);
/// assert!(ci.fused.trace() > 2.0); // nmCI reaches 2 on this example
/// ```
#[allow(non_snake_case)]
pub fn covariance_intersection(
    problem: &FusionProblem,
    criterion: Criterion,
) -> Result<CiResult, InputError> {
    let pencil = Pencil::new(&problem.P_a, &problem.P_b)?;
    let omega = optimal_omega(&[(&pencil, 1.0)], criterion);
    let (P, K_a, K_b) = fuse_at(&pencil, &problem.P_a, &problem.P_b, omega);
    let x = &K_a * &problem.x_a + &K_b * &problem.x_b;
    Ok(CiResult {
        fused: Fused { x, P, K_a, K_b },
        omega,
    })
}

/// Monolithic CI (one `ω` for the whole state) on a problem whose covariances are
/// block-diagonal in `blocks` (each a list of state indices, together a partition of the
/// state): the pencil of the whole problem is the union of the blocks' pencils, so one small
/// eigenproblem per block gives the same exact `ω` and bound as [`covariance_intersection`] on
/// the dense matrices, at a fraction of the cost (8 blocks of 14 instead of one 112×112).
///
/// Entries of `P_a`, `P_b` outside the blocks must be exactly zero.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// use nmci::rules::covariance_intersection_blocks;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::fully_unknown(2)).unwrap();
/// let blocks = covariance_intersection_blocks(&p, &[vec![0], vec![1]], Criterion::Trace).unwrap();
/// let dense = covariance_intersection(&p, Criterion::Trace).unwrap();
/// assert!((blocks.omega - dense.omega).abs() < 1e-12);
/// ```
#[allow(non_snake_case)]
pub fn covariance_intersection_blocks(
    problem: &FusionProblem,
    blocks: &[Vec<usize>],
    criterion: Criterion,
) -> Result<CiResult, InputError> {
    let n = problem.dim();
    crate::structure::check_partition(n, blocks)?;
    let mut block_of = vec![0; n];
    for (b, block) in blocks.iter().enumerate() {
        for &i in block {
            block_of[i] = b;
        }
    }
    for i in 0..n {
        for j in 0..n {
            if block_of[i] != block_of[j] {
                for (name, m) in [("P_a", &problem.P_a), ("P_b", &problem.P_b)] {
                    if m[(i, j)] != 0.0 {
                        return Err(InputError::NotBlockDiagonal {
                            name: name.into(),
                            row: i,
                            col: j,
                            value: m[(i, j)],
                        });
                    }
                }
            }
        }
    }
    let subs: Vec<FusionProblem> = blocks.iter().map(|b| problem.restrict(b)).collect();
    let (parts, omega) = covariance_intersection_independent(&subs, criterion)?;
    let mut P = DMatrix::zeros(n, n);
    let mut K_a = DMatrix::zeros(n, n);
    for (block, part) in blocks.iter().zip(&parts) {
        scatter_block(&mut P, block, &part.P);
        scatter_block(&mut K_a, block, &part.K_a);
    }
    let K_b = DMatrix::identity(n, n) - &K_a;
    let x = &K_a * &problem.x_a + &K_b * &problem.x_b;
    Ok(CiResult {
        fused: Fused { x, P, K_a, K_b },
        omega,
    })
}

/// Monolithic CI (one `ω`) over independent sub-problems stored separately — the blocks of a
/// block-diagonal problem kept in block storage (as a tracking filter does). Returns each
/// block's fused result and the common weight; identical to [`covariance_intersection`] on
/// the assembled dense problem.
#[allow(non_snake_case)]
pub fn covariance_intersection_independent(
    blocks: &[FusionProblem],
    criterion: Criterion,
) -> Result<(Vec<Fused>, f64), InputError> {
    let pencils = blocks
        .iter()
        .map(|s| Pencil::new(&s.P_a, &s.P_b))
        .collect::<Result<Vec<_>, _>>()?;
    let refs: Vec<(&Pencil, f64)> = pencils.iter().map(|p| (p, 1.0)).collect();
    let omega = optimal_omega(&refs, criterion);
    let fused = blocks
        .iter()
        .zip(&pencils)
        .map(|(sub, pencil)| {
            let (P, K_a, K_b) = fuse_at(pencil, &sub.P_a, &sub.P_b, omega);
            let x = &K_a * &sub.x_a + &K_b * &sub.x_b;
            Fused { x, P, K_a, K_b }
        })
        .collect();
    Ok((fused, omega))
}

/// Each distinct pencil of block-stored estimates once, counted as often as its block occurs
/// (`pencils[k]` is `None` for a twin of an earlier block, `twins` from [`covariance_twins`]):
/// the one form in which CI and ICI sum their criterion over blocks.
pub(in crate::fusion) fn weighted<'a>(
    pencils: &'a [Option<Pencil>],
    twins: &[Option<usize>],
) -> Vec<(&'a Pencil, f64)> {
    let mut counts = vec![0.0; pencils.len()];
    for (k, twin) in twins.iter().enumerate() {
        counts[twin.unwrap_or(k)] += 1.0;
    }
    pencils
        .iter()
        .zip(&counts)
        .filter_map(|(p, &c)| p.as_ref().map(|p| (p, c)))
        .collect()
}

/// Monolithic CI of block-stored estimates, in place: `P_a[k] ← CI(P_a[k], P_b[k])` with one
/// common `ω` (the blocks are independent parts of one state), and the plan that fuses the
/// means ([`MeanPlan`]). For filters that keep their estimates in blocks (the tracking study);
/// no gains. Same `ω` and numbers as [`covariance_intersection_independent`] up to rounding.
/// Blocks whose covariances equal an earlier block's in both estimates ([`covariance_twins`])
/// share its pencil and fused covariance.
#[allow(non_snake_case)]
pub(crate) fn ci_in_place(
    P_a: &mut [DMatrix<f64>],
    P_b: &[DMatrix<f64>],
    criterion: Criterion,
) -> Result<(f64, MeanPlan), InputError> {
    let twins = covariance_twins(P_a, P_b);
    let mut pencils = Vec::with_capacity(P_a.len());
    for (k, twin) in twins.iter().enumerate() {
        pencils.push(match twin {
            Some(_) => None,
            None => Some(Pencil::new(&P_a[k], &P_b[k])?),
        });
    }
    let source = |k: usize| twins[k].unwrap_or(k);
    let omega = optimal_omega(&weighted(&pencils, &twins), criterion);
    for k in 0..P_a.len() {
        if let Some(pencil) = &pencils[source(k)] {
            // A twin's source t < k is fused already: its covariance is the twin's.
            let (done, rest) = P_a.split_at_mut(k);
            let shared = twins[k].map(|t| &done[t]);
            pencil.fuse_covariance_into(&mut rest[0], &P_b[k], omega, shared);
        }
    }
    let mut plan = MeanPlan::with_blocks(P_a.len());
    let slots: Vec<Option<usize>> = pencils
        .into_iter()
        .map(|p| p.map(|p| plan.push_pencil(p)))
        .collect();
    for k in 0..P_a.len() {
        // Every source has its pencil (only twins have none).
        plan.blocks.push(match slots[source(k)] {
            Some(slot) => BlockMean::ci(omega, slot),
            None => BlockMean::Keep,
        });
    }
    Ok((omega, plan))
}

/// nmCI of block-stored estimates in place: each block fused by CI with its own `ω`, returned
/// in block order with the plan that fuses the means ([`MeanPlan`]). The endpoints are tested
/// first from the criterion's derivative at `ω = 1` and `ω = 0` (one Cholesky factorization
/// each); only an interior optimum needs the eigendecomposition of the pencil. In a fusion
/// network most blocks of most fusions sit at an endpoint (one agent knows strictly more about
/// that part of the state), so nmCI in block storage is mostly factorizations. Twin blocks
/// ([`covariance_twins`]) share the work.
#[allow(non_snake_case)]
pub(crate) fn nmci_in_place(
    P_a: &mut [DMatrix<f64>],
    P_b: &[DMatrix<f64>],
    criterion: Criterion,
) -> Result<(Vec<f64>, MeanPlan), InputError> {
    let twins = covariance_twins(P_a, P_b);
    let mut plan = MeanPlan::with_blocks(P_a.len());
    // The plan's pencil of each block, when its ω is interior.
    let mut slots: Vec<Option<usize>> = Vec::with_capacity(P_a.len());
    let mut omegas: Vec<f64> = Vec::with_capacity(P_a.len());
    for (k, twin) in twins.iter().enumerate() {
        let (omega, slot) = match *twin {
            Some(t) => {
                let omega = omegas[t];
                match slots[t] {
                    Some(slot) => {
                        let (done, rest) = P_a.split_at_mut(k);
                        plan.pencils[slot].fuse_covariance_into(
                            &mut rest[0],
                            &P_b[k],
                            omega,
                            Some(&done[t]),
                        );
                    }
                    None if omega == 0.0 => P_a[k].clone_from(&P_b[k]),
                    None => {} // ω = 1: keep a
                }
                (omega, slots[t])
            }
            None => {
                let (omega, pencil) = ci_block_in_place(&mut P_a[k], &P_b[k], criterion)?;
                (omega, pencil.map(|p| plan.push_pencil(p)))
            }
        };
        plan.blocks.push(match slot {
            Some(slot) => BlockMean::ci(omega, slot),
            None if omega == 0.0 => BlockMean::Take,
            None => BlockMean::Keep,
        });
        omegas.push(omega);
        slots.push(slot);
    }
    Ok((omegas, plan))
}

/// CI of one block's covariance in place (`P_a ← CI(P_a, P_b)`): `ω`, and the pencil when `ω`
/// is interior.
#[allow(non_snake_case)]
pub(super) fn ci_block_in_place(
    P_a: &mut DMatrix<f64>,
    P_b: &DMatrix<f64>,
    criterion: Criterion,
) -> Result<(f64, Option<Pencil>), InputError> {
    let half = HalfPencil::new(P_a, P_b)?;
    // g is non-decreasing (convex criterion): a clearly negative g(1) settles ω = 1 without
    // g(0); otherwise g(0) decides between ω = 0, the flat criterion (both ends optimal:
    // `FLAT_OMEGA`, as in `optimal_omega`), ω = 1 (a tie at 1) and an interior optimum.
    let (g1, size1) = half.derivative_at_one(P_a, criterion);
    if g1 < -ENDPOINT_TIE * size1 {
        return Ok((1.0, None));
    }
    let (g0, size0) = half.derivative_at_zero(P_a, P_b, criterion)?;
    if g0 >= -ENDPOINT_TIE * size0 {
        if g1 <= ENDPOINT_TIE * size1 {
            let pencil = Pencil::new(P_a, P_b)?;
            // Equal covariances: `P(½)` is `P_b`, exactly (as `fuse_at` gives it).
            if *P_a != *P_b {
                pencil.fuse_covariance_into(P_a, P_b, FLAT_OMEGA, None);
            }
            return Ok((FLAT_OMEGA, Some(pencil)));
        }
        P_a.clone_from(P_b);
        return Ok((0.0, None));
    }
    if g1 <= ENDPOINT_TIE * size1 {
        return Ok((1.0, None));
    }
    let pencil = Pencil::new(P_a, P_b)?;
    let omega = optimal_omega(&[(&pencil, 1.0)], criterion);
    pencil.fuse_covariance_into(P_a, P_b, omega, None);
    Ok((omega, Some(pencil)))
}
