//! Conservativeness: does a bound `P̄` with gains `K = [K_a, K_b]` dominate the true fused
//! covariance `K P' Kᵀ` for a given admissible joint covariance `P'`?
//!
//! Over many cross-covariances (a sample set, the explorer's region) only one term depends
//! on `P_ab`: `K P' Kᵀ = D + M + Mᵀ` with `D = K_a P_a K_aᵀ + K_b P_b K_bᵀ` and
//! `M = K_a P_ab K_bᵀ`. [`worst_margin`] forms `P̄ − D` once and takes `λ_min(P̄ − D − M − Mᵀ)`
//! per `P_ab`; [`fused_coins`] forms `A = L⁻¹ K_a`, `B = L⁻¹ K_b` (`P̄ = L Lᵀ`) and
//! `A P_a Aᵀ + B P_b Bᵀ` once and takes `λ_max` of it plus `N + Nᵀ`, `N = A P_ab Bᵀ`. The same
//! quantities as [`conservativeness_margin`] and [`fused_coin`] per `P_ab`, summed in another
//! order (rounding-level differences, tested).
//!
//! When the problem has independent blocks ([`crate::structure::independent_blocks`]: `P_a`, `P_b` and
//! every admissible `P_ab` are zero off them) and the rule's `P̄`, `K_a`, `K_b` are zero off
//! them too (exactly, as every block-wise rule gives them), `P̄ − K P' Kᵀ` and
//! `L⁻¹ K P' Kᵀ L⁻ᵀ` are block-diagonal for every `P'`, so their eigenvalues are those of
//! their blocks: above 2 × 2 (where the whole state is in closed form already) both functions
//! then work block by block (the smallest margin, the largest COIN), each block's quantities
//! as above. Again the same numbers up to rounding.

use nalgebra::DMatrix;

use super::scale::two_to;
use super::{validate_square, Fused, FusionProblem};
use crate::error::InputError;
use crate::linalg::{max_eigenvalue, min_eigenvalue, symmetrize};
use crate::structure::independent_blocks;

/// The problem's independent blocks when the checks of `fused` over `cross` decouple on them
/// (module docs): `P̄`, `K_a`, `K_b` and each `P_ab` zero off them, exactly. `None` for one
/// block or when something couples two blocks.
fn decoupled(
    problem: &FusionProblem,
    fused: &Fused,
    cross: &[DMatrix<f64>],
) -> Option<Vec<Vec<usize>>> {
    // Up to 2 × 2 the whole state is already in closed form.
    let n = problem.dim();
    if n <= 2 {
        return None;
    }
    let blocks = independent_blocks(&problem.P_a, &problem.P_b, &problem.cross_pattern);
    if blocks.len() < 2 {
        return None;
    }
    let mut block_of = vec![0; n];
    for (k, block) in blocks.iter().enumerate() {
        for &i in block {
            block_of[i] = k;
        }
    }
    let zero_off_blocks = |m: &DMatrix<f64>| {
        m.shape() == (n, n)
            && (0..n).all(|j| (0..n).all(|i| block_of[i] == block_of[j] || m[(i, j)] == 0.0))
    };
    let mut matrices = [&fused.P, &fused.K_a, &fused.K_b].into_iter().chain(cross);
    matrices.all(zero_off_blocks).then_some(blocks)
}

/// The problem, the fused result and the cross-covariances on the states `block`.
#[allow(non_snake_case)]
fn on_block(
    problem: &FusionProblem,
    fused: &Fused,
    cross: &[DMatrix<f64>],
    block: &[usize],
) -> (FusionProblem, Fused, Vec<DMatrix<f64>>) {
    let sub = |m: &DMatrix<f64>| m.select_rows(block).select_columns(block);
    (
        problem.restrict(block),
        Fused {
            x: fused.x.select_rows(block),
            P: sub(&fused.P),
            K_a: sub(&fused.K_a),
            K_b: sub(&fused.K_b),
        },
        cross.iter().map(sub).collect(),
    )
}

/// The fused error covariance `K P' Kᵀ = K_a P_a K_aᵀ + K_a P_ab K_bᵀ + K_b P_abᵀ K_aᵀ + K_b P_b K_bᵀ`
/// (the paper's `P_f`) of the gains `K_a`, `K_b` when the cross-covariance is `P_ab`: each
/// `n × n` and finite, else an error naming it.
#[allow(non_snake_case)]
pub fn fused_error_covariance(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    K_b: &DMatrix<f64>,
    P_ab: &DMatrix<f64>,
) -> Result<DMatrix<f64>, InputError> {
    validate_square("K_a", K_a, problem.dim())?;
    validate_square("K_b", K_b, problem.dim())?;
    validate_square("P_ab", P_ab, problem.dim())?;
    Ok(error_covariance(problem, K_a, K_b, P_ab))
}

/// [`fused_error_covariance`] without the checks, for the rules' own gains and samples.
#[allow(non_snake_case)]
pub(crate) fn error_covariance(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    K_b: &DMatrix<f64>,
    P_ab: &DMatrix<f64>,
) -> DMatrix<f64> {
    let cross = K_a * P_ab * K_b.transpose();
    K_a * &problem.P_a * K_a.transpose()
        + &cross
        + cross.transpose()
        + K_b * &problem.P_b * K_b.transpose()
}

/// A fused result given by the caller: `P`, `K_a`, `K_b` `n × n` and `x` of size `n`, finite.
fn check_fused(problem: &FusionProblem, fused: &Fused) -> Result<(), InputError> {
    let n = problem.dim();
    validate_square("P", &fused.P, n)?;
    validate_square("K_a", &fused.K_a, n)?;
    validate_square("K_b", &fused.K_b, n)?;
    super::validate_vector("x", &fused.x, n)
}

/// A set of cross-covariances given by the caller, each checked as `cross[i]`.
#[allow(non_snake_case)]
fn check_cross(problem: &FusionProblem, cross: &[DMatrix<f64>]) -> Result<(), InputError> {
    for (i, P_ab) in cross.iter().enumerate() {
        validate_square(&format!("cross[{i}]"), P_ab, problem.dim())?;
    }
    Ok(())
}

/// `λ_min(P̄ − K P' Kᵀ)` for one cross-covariance: `≥ 0` means conservative for it. The fused
/// result's matrices and `P_ab` must be `n × n` and finite (an error names the one that is not).
#[allow(non_snake_case)]
pub fn conservativeness_margin(
    problem: &FusionProblem,
    fused: &Fused,
    P_ab: &DMatrix<f64>,
) -> Result<f64, InputError> {
    check_fused(problem, fused)?;
    validate_square("P_ab", P_ab, problem.dim())?;
    Ok(margin(problem, fused, P_ab))
}

/// [`conservativeness_margin`] without the checks.
#[allow(non_snake_case)]
pub(crate) fn margin(problem: &FusionProblem, fused: &Fused, P_ab: &DMatrix<f64>) -> f64 {
    let P_f = error_covariance(problem, &fused.K_a, &fused.K_b, P_ab);
    min_eigenvalue(&(&fused.P - P_f))
}

/// The smallest [`conservativeness_margin`] over a set of cross-covariances (`+∞` for none).
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap();
/// let s = sample_cross_covariances(&p, 100, 1, SamplerSettings::default()).unwrap();
/// assert!(worst_margin(&p, &nm.fused, &s.cross).unwrap() >= -1e-12);
/// ```
///
/// The fused result's matrices and each `cross[i]` must be `n × n` and finite (an error names
/// the one that is not).
#[allow(non_snake_case)]
pub fn worst_margin(
    problem: &FusionProblem,
    fused: &Fused,
    cross: &[DMatrix<f64>],
) -> Result<f64, InputError> {
    check_fused(problem, fused)?;
    check_cross(problem, cross)?;
    Ok(lowest_margin(problem, fused, cross))
}

/// [`worst_margin`] without the checks.
#[allow(non_snake_case)]
pub(crate) fn lowest_margin(problem: &FusionProblem, fused: &Fused, cross: &[DMatrix<f64>]) -> f64 {
    if cross.is_empty() {
        return f64::INFINITY;
    }
    if let Some(blocks) = decoupled(problem, fused, cross) {
        return blocks
            .iter()
            .map(|block| {
                let (problem, fused, cross) = on_block(problem, fused, cross, block);
                worst_margin_dense(&problem, &fused, &cross)
            })
            .fold(f64::INFINITY, f64::min);
    }
    worst_margin_dense(problem, fused, cross)
}

/// [`worst_margin`] on the whole state.
#[allow(non_snake_case)]
fn worst_margin_dense(problem: &FusionProblem, fused: &Fused, cross: &[DMatrix<f64>]) -> f64 {
    let K_bt = fused.K_b.transpose();
    let C = &fused.P
        - &fused.K_a * &problem.P_a * fused.K_a.transpose()
        - &fused.K_b * &problem.P_b * &K_bt;
    cross
        .iter()
        .map(|P_ab| {
            let M = &fused.K_a * P_ab * &K_bt;
            min_eigenvalue(&(&C - &M - M.transpose()))
        })
        .fold(f64::INFINITY, f64::min)
}

/// The conservativeness index (COIN): `λ_max(L⁻¹ E L⁻ᵀ)` with `P = L Lᵀ` and `E` the true
/// error covariance. `≤ 1` exactly when `P ⪰ E` (conservative); `1` for `P = E`; smaller is
/// more conservative (`P` inflated by `c` gives `1/c`); `> 1` is not conservative. A single
/// number for "less conservative" (the paper's open question (i)).
///
/// `P` must be a covariance ([`validate_covariance`](super::validate_covariance)); `E` of the
/// same size, finite and symmetric (to the same tolerance), not necessarily definite: the
/// equivalence with `P ⪰ E` holds for any symmetric `E` (a singular true covariance is
/// common, and one a little indefinite from rounding gets the index its floats define).
/// When an intermediate result overflows (`P` small against `E`), the index is recomputed
/// with both scaled to unit size by powers of two (`P` by a power of four, so that its
/// Cholesky factor scales exactly) and scaled back; in the normal range such scalings change
/// no rounding (tested bit for bit). An index beyond the largest float is then `+∞`.
///
/// ```
/// use nalgebra::DMatrix;
/// use nmci::check::conservativeness_index;
/// let E = DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.5, 1.0]);
/// assert!((conservativeness_index(&E, &E).unwrap() - 1.0).abs() < 1e-12);
/// assert!((conservativeness_index(&(&E * 4.0), &E).unwrap() - 0.25).abs() < 1e-12);
/// ```
#[allow(non_snake_case)]
pub fn conservativeness_index(
    P: &DMatrix<f64>,
    E: &DMatrix<f64>,
) -> Result<f64, crate::error::InputError> {
    super::validate_covariance("P", P)?;
    super::validate_symmetric("E", E)?;
    if E.shape() != P.shape() {
        return Err(crate::error::InputError::SizeMismatch {
            name: "E".into(),
            found: E.nrows(),
            expected: P.nrows(),
        });
    }
    let coin = coin_of(P, E)?;
    if coin.is_finite() {
        return Ok(coin);
    }
    // Both scaled by powers of two to a largest entry near 1 (E only when non-zero; a zero E
    // gives a finite index above). The index scales by 2^(k_E − k_P), applied in two halves so
    // that an intermediate product overflows only when the index does.
    let exponent = |m: &DMatrix<f64>| {
        let a = m.amax();
        if a > 0.0 {
            (a.log2().floor() as i32).clamp(-1021, 1021)
        } else {
            0
        }
    };
    // k_P even: P's Cholesky factor then scales by exactly 2^(k_P/2).
    let (k_P, k_E) = (exponent(P) & !1, exponent(E));
    let c = coin_of(&(P * two_to(-k_P)), &(E * two_to(-k_E)))?;
    let d = k_E - k_P;
    Ok(c * two_to(d / 2) * two_to(d - d / 2))
}

/// `λ_max(L⁻¹ E L⁻ᵀ)` with `P = L Lᵀ`, no checks: [`conservativeness_index`] for matrices a
/// rule or the study computed (and [`fused_coin`]).
#[allow(non_snake_case)]
pub(crate) fn coin_of(P: &DMatrix<f64>, E: &DMatrix<f64>) -> Result<f64, crate::error::InputError> {
    let L = bound_factor(P)?;
    // W = L⁻¹ E L⁻ᵀ: two triangular solves.
    let mut W = E.clone();
    L.solve_lower_triangular_mut(&mut W);
    let mut W = W.transpose();
    L.solve_lower_triangular_mut(&mut W);
    Ok(max_eigenvalue(&W))
}

/// `L` with `P = L Lᵀ` for the COIN's bound `P`; an error naming `P` when it is not positive
/// definite.
#[allow(non_snake_case)]
fn bound_factor(P: &DMatrix<f64>) -> Result<DMatrix<f64>, crate::error::InputError> {
    Ok(crate::linalg::cholesky(P)
        .ok_or_else(|| super::definiteness_error("P", P))?
        .unpack())
}

/// COIN of a fused result for one cross-covariance: `E = K P' Kᵀ`. The fused result's
/// matrices and `P_ab` must be `n × n` and finite (an error names the one that is not).
#[allow(non_snake_case)]
pub fn fused_coin(
    problem: &FusionProblem,
    fused: &Fused,
    P_ab: &DMatrix<f64>,
) -> Result<f64, crate::error::InputError> {
    check_fused(problem, fused)?;
    validate_square("P_ab", P_ab, problem.dim())?;
    let E = error_covariance(problem, &fused.K_a, &fused.K_b, P_ab);
    coin_of(&fused.P, &E)
}

/// [`fused_coin`] for each of many cross-covariances (module docs: the parts that do not
/// depend on `P_ab` are computed once), with the checks of [`worst_margin`].
#[allow(non_snake_case)]
pub fn fused_coins(
    problem: &FusionProblem,
    fused: &Fused,
    cross: &[DMatrix<f64>],
) -> Result<Vec<f64>, crate::error::InputError> {
    check_fused(problem, fused)?;
    check_cross(problem, cross)?;
    let L = bound_factor(&fused.P)?;
    if let Some(blocks) = decoupled(problem, fused, cross) {
        let mut coins = vec![f64::NEG_INFINITY; cross.len()];
        for block in &blocks {
            let (problem, fused, cross) = on_block(problem, fused, cross, block);
            let L = bound_factor(&fused.P)?;
            for (coin, c) in coins
                .iter_mut()
                .zip(block_coins(&problem, &fused, &cross, &L))
            {
                *coin = coin.max(c);
            }
        }
        return Ok(coins);
    }
    Ok(block_coins(problem, fused, cross, &L))
}

/// [`fused_coins`] on the whole state, with `P̄ = L Lᵀ`.
#[allow(non_snake_case)]
fn block_coins(
    problem: &FusionProblem,
    fused: &Fused,
    cross: &[DMatrix<f64>],
    L: &DMatrix<f64>,
) -> Vec<f64> {
    let solve = |K: &DMatrix<f64>| {
        let mut X = K.clone();
        L.solve_lower_triangular_mut(&mut X);
        X
    };
    let (A, B) = (solve(&fused.K_a), solve(&fused.K_b));
    let Bt = B.transpose();
    let W0 = symmetrize(&(&A * &problem.P_a * A.transpose() + &B * &problem.P_b * &Bt));
    cross
        .iter()
        .map(|P_ab| {
            let N = &A * P_ab * &Bt;
            max_eigenvalue(&(&W0 + &N + N.transpose()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::known::naive_fusion;
    use crate::fusion::nmci::non_monolithic_ci;
    use crate::fusion::Criterion;
    use crate::structure::CrossPattern;

    /// Two 2 × 2 blocks, interleaved ({0, 2} and {1, 3}), each cross block wholly unknown.
    #[allow(non_snake_case)]
    fn interleaved() -> FusionProblem {
        let P_a = DMatrix::from_row_slice(
            4,
            4,
            &[
                3.0, 0.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.2, 0.5, 0.0, 1.0, 0.0, 0.0, 0.2, 0.0, 2.0,
            ],
        );
        let P_b = DMatrix::from_row_slice(
            4,
            4,
            &[
                1.0, 0.0, -0.3, 0.0, 0.0, 4.0, 0.0, 1.0, -0.3, 0.0, 2.0, 0.0, 0.0, 1.0, 0.0, 2.0,
            ],
        );
        FusionProblem::from_covariances(P_a, P_b, CrossPattern::from_fn(4, |i, j| i % 2 == j % 2))
            .unwrap()
    }

    /// The checks decouple exactly when the module docs say: independent blocks, a rule zero
    /// off them, samples zero off them, above 2 × 2.
    #[test]
    #[allow(non_snake_case)]
    fn checks_decouple_on_the_blocks_a_rule_respects_only() {
        let p = interleaved();
        let blocks = Some(vec![vec![0, 2], vec![1, 3]]);
        let zero = DMatrix::zeros(4, 4);
        let P_ab = DMatrix::from_fn(4, 4, |i, j| if i % 2 == j % 2 { 0.1 } else { 0.0 });
        // nmCI and naive fusion work block by block: exact zeros off the blocks.
        for fused in [
            non_monolithic_ci(&p, Criterion::Trace).unwrap().fused,
            naive_fusion(&p),
        ] {
            assert_eq!(decoupled(&p, &fused, &[zero.clone(), P_ab.clone()]), blocks);
            // A gain entry, a bound entry or a sample entry off the blocks couples them.
            for which in 0..3 {
                let mut f = fused.clone();
                let mut cross = P_ab.clone();
                match which {
                    0 => f.K_a[(0, 1)] = 1e-300,
                    1 => f.P[(3, 2)] = -1e-300,
                    _ => cross[(1, 2)] = 1e-300,
                }
                assert_eq!(decoupled(&p, &f, &[cross]), None, "case {which}");
            }
        }
        // One block (a fully unknown P_ab), or 2 × 2 (closed form already): the whole state.
        let one = FusionProblem::from_covariances(
            p.P_a.clone(),
            p.P_b.clone(),
            CrossPattern::fully_unknown(4),
        )
        .unwrap();
        assert_eq!(decoupled(&one, &naive_fusion(&one), &[zero]), None);
        let two = p.restrict(&[0, 1]);
        assert_eq!(
            independent_blocks(&two.P_a, &two.P_b, &two.cross_pattern).len(),
            2
        );
        assert_eq!(
            decoupled(&two, &naive_fusion(&two), &[DMatrix::zeros(2, 2)]),
            None
        );
    }
}
