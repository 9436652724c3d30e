//! Semi-definite covariances: CI, nmCI, EI and naive fusion in the pseudo-inverse
//! (information) form; ICI's fall-back.
//!
//! A covariance with a zero (or rounding-level) eigenvalue — a collapsed particle cloud, a
//! state a sensor fixes exactly, a measurement model's broadcast row — has no inverse, and the
//! rules' covariance form (`fusion::ci`) refuses it. CI admits a form without one. Write
//! `A⁺` for the pseudo-inverse of `A`'s spectral truncation: `A = Σ λᵢ uᵢuᵢᵀ`, the eigenvalues
//! at most `τ = n ε λ_max` dropped (they are zero to rounding), `A⁺ = Σ_{λᵢ > τ} uᵢuᵢᵀ / λᵢ`.
//! For `ω ∈ [0, 1]` let
//!
//! `F(ω) = ω A⁺ + (1 − ω) B⁺`, `P = F(ω)⁻¹`, `K_a = P ω A⁺`, `K_b = P (1 − ω) B⁺`,
//! `x = K_a x_a + K_b x_b`
//!
//! (Stone Soup's `ChernoffUpdater` computes this form at a fixed `ω`).
//!
//! **Why it is conservative.** `K_a + K_b = P F = I`, so the error is `K_a e_a + K_b e_b`. For
//! any cross-covariance `C`, `0 ⪯ E[(√t K_a e_a − K_b e_b/√t)(…)ᵀ]` gives
//! `K_a C K_bᵀ + K_b Cᵀ K_aᵀ ⪯ t K_a A K_aᵀ + K_b B K_bᵀ / t`; with `t = (1 − ω)/ω` the error
//! covariance is at most `K_a A K_aᵀ/ω + K_b B K_bᵀ/(1 − ω) = P (ω A⁺AA⁺ + (1 − ω) B⁺BB⁺) P`.
//! `A⁺ A A⁺ = A⁺` holds for the given `A`, not only for its truncation: `A⁺` lives on the kept
//! eigenvectors, on which `A` is its truncation. So the bound is `P F P = P`, for every
//! cross-covariance, whatever was dropped: the gains ignore the directions without
//! information, they never trust them. (At `ω = 1`, `K_b = 0` and the bound is `K_a A K_aᵀ`
//! exactly; likewise at `0`.) In floating point the eigenvectors are computed, so this is a
//! statement to the rounding of the eigendecomposition, not a proven one; a bound that must
//! hold in floating point takes positive definite covariances (`fusion::bracket`).
//!
//! **When it exists.** `P` needs `F(ω)` invertible: `A⁺ + B⁺` positive definite, i.e. no
//! direction in which both covariances are zero (`A + B` positive definite). Where there is
//! one, both estimates claim certainty there and no bound of this form exists: the request is
//! refused, the covariances named. A covariance with an eigenvalue below `−τ` is not a
//! covariance and is refused as not positive semi-definite.
//!
//! **The weight.** `A⁺ + B⁺ = L Lᵀ` and `L⁻¹ A⁺ L⁻ᵀ = V diag(α) Vᵀ` (`αᵢ ∈ [0, 1]`) diagonalise
//! both: `F(ω)⁻¹ = M diag(1/dᵢ(ω)) Mᵀ`, `M = L⁻ᵀ V`, `dᵢ(ω) = (1 − αᵢ)(1 − ω) + αᵢ ω`. So
//! `tr P = Σ ‖mᵢ‖²/dᵢ(ω)` and `log det P = −2 log det L − Σ ln dᵢ(ω)`: CI's convex criteria with
//! affine `dᵢ`, minimised by CI's safeguarded Newton (`ci::minimise_convex`), ties included
//! (a flat criterion takes `ω = ½`). An end where some `dᵢ` is zero (a direction only the other
//! estimate informs) is never optimal: its criterion is infinite.
//!
//! nmCI takes one weight per independent block (exact zeros only; `structure::absorb`'s proven
//! inflation needs positive definite blocks) and naive fusion is `(A⁺ + B⁺)⁻¹`, conservative
//! for independent errors only, as always.
//!
//! **EI** (`fusion::ei`; no guarantee, as always) has the same basis: in the coordinates
//! `z = M⁻¹ x` the information of `a` is `diag(α)` and of `b` `diag(1 − α)`, and EI keeps, per
//! axis, the more informed estimate: `P = M diag(1 / max(αᵢ, 1 − αᵢ)) Mᵀ`,
//! `K_a = M diag(kᵢ) M⁻¹` with `kᵢ` 1 where `αᵢ > 1 − αᵢ`, 0 where `αᵢ < 1 − αᵢ`, ½ where the
//! two agree within EI's `η` (`|1 − 2αᵢ| ≤ 10⁻⁹ αᵢ`, i.e. variance ratio `(1 − αᵢ)/αᵢ` within
//! `10⁻⁹` of 1). For positive definite `A`, `B` this is `fusion::ei`'s formula: the pencil's
//! variance ratio `μᵢ` is `(1 − αᵢ)/αᵢ`, and `min(μᵢ, 1)` in `P_b`'s scale is
//! `1/max(αᵢ, 1 − αᵢ)` in this one (tested).
//!
//! **ICI** (`fusion::ici`) has no pseudo-inverse form argued here: its bound
//! `(A⁻¹ + B⁻¹ − (ωA + (1 − ω)B)⁻¹)⁻¹` mixes the covariances and their inverses, and with
//! `A⁺` in place of `A⁻¹` the argument of Noack et al. does not carry over as written. A
//! request for ICI on a semi-definite covariance is therefore fused by CI's form above
//! ([`SemidefiniteRule::Ci`]), which bounds the error for *every* cross-covariance, so in
//! particular for the correlations by common information ICI assumes: ICI's guarantee holds
//! a fortiori, and the response says which rule fused it (`method` `ci`, and the note).

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use super::ci::minimise_convex;
use super::{Criterion, Fused, FusionProblem};
use crate::error::InputError;
use crate::linalg::cholesky_of;
use crate::structure::{independent_blocks, CrossPattern};

/// The rules with a pseudo-inverse form here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SemidefiniteRule {
    /// CI with the optimal weight.
    Ci,
    /// nmCI: one weight per independent block.
    Nmci,
    /// Naive fusion (independent errors only).
    Naive,
    /// Ellipsoidal intersection (no guarantee).
    Ei,
}

/// A fusion in the pseudo-inverse form (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct SemidefiniteResult {
    /// The fused estimate, its bound and the gains.
    pub fused: Fused,
    /// The weight of each block (empty for naive fusion).
    pub omega: Vec<f64>,
    /// The blocks (one for CI and naive fusion).
    pub blocks: Vec<Vec<usize>>,
    /// The covariances that lost eigenvalues to the truncation (`"P_a"`, `"P_b"`).
    pub truncated: Vec<String>,
}

/// `A⁺` of `A`'s spectral truncation (module docs) and whether an eigenvalue was dropped;
/// refuses a non-finite matrix or an eigenvalue below `−τ`.
#[allow(non_snake_case)]
fn truncated_inverse(name: &str, A: &DMatrix<f64>) -> Result<(DMatrix<f64>, bool), InputError> {
    if let Some(k) = A.iter().position(|v| !v.is_finite()) {
        return Err(InputError::NotFinite {
            name: name.into(),
            row: k % A.nrows(),
            col: k / A.nrows(),
        });
    }
    let n = A.nrows();
    let eig = SymmetricEigen::new((A + A.transpose()) * 0.5);
    let largest = eig.eigenvalues.amax();
    let tau = n as f64 * f64::EPSILON * largest;
    let smallest = eig.eigenvalues.min();
    if smallest < -tau || !largest.is_finite() {
        return Err(InputError::NotPositiveDefinite {
            name: name.into(),
            min_eigenvalue: smallest,
        });
    }
    let mut inverse = DMatrix::zeros(n, n);
    let mut dropped = false;
    for (i, &lambda) in eig.eigenvalues.iter().enumerate() {
        if lambda > tau {
            let u = eig.eigenvectors.column(i);
            inverse += u * u.transpose() / lambda;
        } else {
            dropped = true;
        }
    }
    Ok(((&inverse + inverse.transpose()) * 0.5, dropped))
}

/// The joint diagonalisation of `A⁺`, `B⁺` (module docs): `M` and the `αᵢ`, or the refusal
/// where `A⁺ + B⁺` is singular.
#[allow(non_snake_case)]
fn joint_basis(
    Y_a: &DMatrix<f64>,
    Y_b: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, DVector<f64>), InputError> {
    let n = Y_a.nrows();
    let no_bound = || {
        InputError::Estimates(
        "P_a and P_b are both zero in some direction (their sum is singular): both estimates claim certainty there and no bound exists".into(),
    )
    };
    let L = cholesky_of(Y_a + Y_b).ok_or_else(no_bound)?.l();
    let L_inv = L
        .clone()
        .try_inverse()
        .filter(|m| m.iter().all(|v| v.is_finite()))
        .ok_or_else(no_bound)?;
    let C = &L_inv * Y_a * L_inv.transpose();
    let eig = SymmetricEigen::new((&C + C.transpose()) * 0.5);
    // The αᵢ lie in [0, 1] in exact arithmetic (A⁺ ⪯ A⁺ + B⁺); rounding can put them outside
    // by a few ε, which would make a dᵢ negative at an end.
    let alpha = eig.eigenvalues.map(|a| a.clamp(0.0, 1.0));
    let M = L_inv.transpose() * eig.eigenvectors;
    debug_assert_eq!(M.ncols(), n);
    Ok((M, alpha))
}

/// CI in the pseudo-inverse form of one block: the weight and the fused result.
#[allow(non_snake_case)]
fn ci_block(
    x_a: &DVector<f64>,
    Y_a: &DMatrix<f64>,
    x_b: &DVector<f64>,
    Y_b: &DMatrix<f64>,
    criterion: Criterion,
) -> Result<(f64, Fused), InputError> {
    let (M, alpha) = joint_basis(Y_a, Y_b)?;
    let c: Vec<f64> = M.column_iter().map(|m| m.norm_squared()).collect();
    let d = |i: usize, omega: f64| (1.0 - alpha[i]) * (1.0 - omega) + alpha[i] * omega;
    let derivatives = |omega: f64| {
        let (mut g, mut h, mut size) = (0.0, 0.0, 0.0);
        for i in 0..alpha.len() {
            let (di, s) = (d(i, omega), 2.0 * alpha[i] - 1.0);
            if di <= 0.0 {
                // An end where a direction has no information from the weighted estimate:
                // the criterion is infinite there, never optimal (module docs).
                return if omega < 0.5 {
                    (f64::NEG_INFINITY, 0.0, 1.0)
                } else {
                    (f64::INFINITY, 0.0, 1.0)
                };
            }
            match criterion {
                Criterion::Trace => {
                    g -= c[i] * s / (di * di);
                    h += 2.0 * c[i] * s * s / (di * di * di);
                    size += c[i] * (1.0 + s.abs()) / (di * di);
                }
                Criterion::Logdet => {
                    g -= s / di;
                    h += s * s / (di * di);
                    size += (1.0 + s.abs()) / di;
                }
            }
        }
        (g, h, size)
    };
    let (omega, _) = minimise_convex(derivatives);
    let inv_d = DVector::from_fn(alpha.len(), |i, _| 1.0 / d(i, omega));
    let P = &M * DMatrix::from_diagonal(&inv_d) * M.transpose();
    let P = (&P + P.transpose()) * 0.5;
    Ok((
        omega,
        gains_and_mean(P, Y_a * omega, Y_b * (1.0 - omega), x_a, x_b),
    ))
}

/// EI in the pseudo-inverse form (module docs): per axis of the joint basis, the more
/// informed estimate.
#[allow(non_snake_case)]
fn ei(
    x_a: &DVector<f64>,
    Y_a: &DMatrix<f64>,
    x_b: &DVector<f64>,
    Y_b: &DMatrix<f64>,
) -> Result<Fused, InputError> {
    let n = Y_a.nrows();
    let (M, alpha) = joint_basis(Y_a, Y_b)?;
    let inv_d = alpha.map(|a| 1.0 / a.max(1.0 - a));
    let k = alpha.map(|a| {
        if (1.0 - 2.0 * a).abs() <= 1e-9 * a {
            0.5
        } else if a > 0.5 {
            1.0
        } else {
            0.0
        }
    });
    let P = &M * DMatrix::from_diagonal(&inv_d) * M.transpose();
    let P = (&P + P.transpose()) * 0.5;
    // M⁻¹ = Vᵀ Lᵀ = Mᵀ (A⁺ + B⁺): M is L⁻ᵀ V with V orthogonal.
    let M_inv = M.transpose() * (Y_a + Y_b);
    let K_a = &M * DMatrix::from_diagonal(&k) * M_inv;
    let K_b = DMatrix::identity(n, n) - &K_a;
    let x = &K_a * x_a + &K_b * x_b;
    Ok(Fused { x, P, K_a, K_b })
}

/// `K_a = P W_a`, `K_b = P W_b` and `x = K_a x_a + K_b x_b` (`W_a`, `W_b` the weighted
/// information matrices).
#[allow(non_snake_case)]
fn gains_and_mean(
    P: DMatrix<f64>,
    W_a: DMatrix<f64>,
    W_b: DMatrix<f64>,
    x_a: &DVector<f64>,
    x_b: &DVector<f64>,
) -> Fused {
    let K_a = &P * W_a;
    let K_b = &P * W_b;
    let x = &K_a * x_a + &K_b * x_b;
    Fused { x, P, K_a, K_b }
}

/// `rule` on two estimates whose covariances may be semi-definite (module docs): `x_a`,
/// `P_a`, `x_b`, `P_b` as in a [`FusionProblem`], `pattern` the known zeros of `P_ab` (nmCI's
/// blocks). Errors name the covariance: non-finite, sizes, not positive semi-definite, or
/// both zero in a direction.
#[allow(non_snake_case)]
pub fn fuse_semidefinite(
    rule: SemidefiniteRule,
    x_a: &DVector<f64>,
    P_a: &DMatrix<f64>,
    x_b: &DVector<f64>,
    P_b: &DMatrix<f64>,
    pattern: &CrossPattern,
    criterion: Criterion,
) -> Result<SemidefiniteResult, InputError> {
    let n = P_a.nrows();
    super::validate_square("P_a", P_a, n)?;
    super::validate_square("P_b", P_b, n)?;
    super::validate_vector("x_a", x_a, n)?;
    super::validate_vector("x_b", x_b, n)?;
    super::validate_symmetric("P_a", P_a)?;
    super::validate_symmetric("P_b", P_b)?;
    let (Y_a, dropped_a) = truncated_inverse("P_a", P_a)?;
    let (Y_b, dropped_b) = truncated_inverse("P_b", P_b)?;
    let mut dropped = [dropped_a, dropped_b];
    let whole: Vec<usize> = (0..n).collect();
    let (fused, omega, blocks) = match rule {
        SemidefiniteRule::Naive => {
            let (M, _) = joint_basis(&Y_a, &Y_b)?;
            let P = &M * M.transpose();
            let P = (&P + P.transpose()) * 0.5;
            (
                gains_and_mean(P, Y_a, Y_b, x_a, x_b),
                Vec::new(),
                vec![whole],
            )
        }
        SemidefiniteRule::Ci => {
            let (w, fused) = ci_block(x_a, &Y_a, x_b, &Y_b, criterion)?;
            (fused, vec![w], vec![whole])
        }
        SemidefiniteRule::Ei => (ei(x_a, &Y_a, x_b, &Y_b)?, Vec::new(), vec![whole]),
        SemidefiniteRule::Nmci => {
            let blocks = independent_blocks(P_a, P_b, pattern);
            let mut fused = Fused {
                x: DVector::zeros(n),
                P: DMatrix::zeros(n, n),
                K_a: DMatrix::zeros(n, n),
                K_b: DMatrix::zeros(n, n),
            };
            let mut omega = Vec::with_capacity(blocks.len());
            let mut truncated_blocks = [false, false];
            for block in &blocks {
                let pick = |v: &DVector<f64>| DVector::from_fn(block.len(), |i, _| v[block[i]]);
                let sub = |m: &DMatrix<f64>| {
                    DMatrix::from_fn(block.len(), block.len(), |i, j| m[(block[i], block[j])])
                };
                // Each block truncated on its own (module docs: the argument holds for any
                // truncation, block by block, as A and B are block-diagonal in these blocks).
                let (Ya_k, da) = truncated_inverse("P_a", &sub(P_a))?;
                let (Yb_k, db) = truncated_inverse("P_b", &sub(P_b))?;
                truncated_blocks[0] |= da;
                truncated_blocks[1] |= db;
                let (w, f) = ci_block(&pick(x_a), &Ya_k, &pick(x_b), &Yb_k, criterion)?;
                for (i, &bi) in block.iter().enumerate() {
                    fused.x[bi] = f.x[i];
                    for (j, &bj) in block.iter().enumerate() {
                        fused.P[(bi, bj)] = f.P[(i, j)];
                        fused.K_a[(bi, bj)] = f.K_a[(i, j)];
                        fused.K_b[(bi, bj)] = f.K_b[(i, j)];
                    }
                }
                omega.push(w);
            }
            dropped = truncated_blocks;
            (fused, omega, blocks)
        }
    };
    let truncated = ["P_a", "P_b"]
        .iter()
        .zip(dropped)
        .filter(|(_, d)| *d)
        .map(|(name, _)| name.to_string())
        .collect();
    Ok(SemidefiniteResult {
        fused,
        omega,
        blocks,
        truncated,
    })
}

/// Whether `error`, refusing a covariance of a two-estimate request, is one the
/// pseudo-inverse form can take instead: not positive definite, singular or ill-conditioned
/// (the form itself then refuses a matrix that is not positive semi-definite).
pub(crate) fn definiteness_refusal(error: &InputError) -> bool {
    matches!(
        error,
        InputError::NotPositiveDefinite { name, .. }
            | InputError::Singular { name, .. }
            | InputError::IllConditioned { name, .. }
            if name == "P_a" || name == "P_b"
    )
}

/// The problem's estimates fused by `rule` in the pseudo-inverse form (a positive definite
/// problem gives the covariance form's result to rounding: tested).
pub fn fuse_semidefinite_problem(
    rule: SemidefiniteRule,
    problem: &FusionProblem,
    criterion: Criterion,
) -> Result<SemidefiniteResult, InputError> {
    fuse_semidefinite(
        rule,
        &problem.x_a,
        &problem.P_a,
        &problem.x_b,
        &problem.P_b,
        &problem.cross_pattern,
        criterion,
    )
}

#[cfg(test)]
#[allow(non_snake_case)]
mod tests {
    use super::*;
    use crate::fusion::ci::covariance_intersection;
    use crate::fusion::nmci::non_monolithic_ci;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn spd(n: usize, rank: usize, rng: &mut ChaCha8Rng) -> DMatrix<f64> {
        let g = DMatrix::from_fn(n, rank, |_, _| rng.random_range(-1.0..1.0));
        &g * g.transpose()
    }

    /// Positive definite pairs: the covariance form's result, to rounding.
    #[test]
    fn on_positive_definite_pairs_it_is_ci_and_nmci() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for n in 1..=5 {
            let A = spd(n, n + 2, &mut rng);
            let B = spd(n, n + 2, &mut rng);
            let xa = DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0));
            let xb = DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0));
            let p = FusionProblem::new(xa, A, xb, B, CrossPattern::fully_unknown(n)).unwrap();
            for criterion in [Criterion::Trace, Criterion::Logdet] {
                let ours = fuse_semidefinite_problem(SemidefiniteRule::Ci, &p, criterion).unwrap();
                let ci = covariance_intersection(&p, criterion).unwrap();
                assert!((ours.omega[0] - ci.omega).abs() <= 1e-7, "n = {n}");
                let scale = ci.fused.P.amax();
                assert!(
                    (&ours.fused.P - &ci.fused.P).amax() <= 1e-9 * scale,
                    "n = {n}"
                );
                assert!((&ours.fused.x - &ci.fused.x).amax() <= 1e-8, "n = {n}");
                assert!(ours.truncated.is_empty());
            }
        }
        let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
        // EI: the covariance form's P, gains and mean, ties (equal variances on an axis)
        // included.
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        for n in 1..=5 {
            let A = spd(n, n + 2, &mut rng);
            let B = if n == 3 {
                A.clone()
            } else {
                spd(n, n + 2, &mut rng)
            };
            let xa = DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0));
            let xb = DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0));
            let p = FusionProblem::new(xa, A, xb, B, CrossPattern::fully_unknown(n)).unwrap();
            let ours = fuse_semidefinite_problem(SemidefiniteRule::Ei, &p, Criterion::Trace)
                .unwrap()
                .fused;
            let ei = crate::fusion::ei::ellipsoidal_intersection(&p).unwrap();
            let scale = ei.P.amax();
            assert!((&ours.P - &ei.P).amax() <= 1e-9 * scale, "n = {n}");
            assert!((&ours.K_a - &ei.K_a).amax() <= 1e-8, "n = {n}");
            assert!((&ours.x - &ei.x).amax() <= 1e-8, "n = {n}");
        }
        let p = FusionProblem::from_covariances(
            d(&[3.0, 1.0]),
            d(&[1.0, 4.0]),
            CrossPattern::diagonal(2),
        )
        .unwrap();
        let ours = fuse_semidefinite_problem(SemidefiniteRule::Nmci, &p, Criterion::Trace).unwrap();
        let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap();
        assert_eq!(ours.omega, nm.omega);
        assert!((&ours.fused.P - &nm.fused.P).amax() <= 1e-14);
    }

    /// Rank-deficient covariances: the bound dominates the error covariance of its gains for
    /// random joint covariances (any cross-covariance the two admit), the gains sum to the
    /// identity, and the optimal weight is never worse than a grid of weights.
    #[test]
    fn rank_deficient_pairs_get_a_bound_for_every_cross_covariance() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for n in 2..=5 {
            for rank_a in 1..n {
                // Joint covariance of rank ≥ n so that A + B is positive definite generically.
                let G = DMatrix::from_fn(2 * n, 2 * n, |_, _| rng.random_range(-1.0..1.0));
                let mut mask = DMatrix::<f64>::identity(2 * n, 2 * n);
                for i in rank_a..n {
                    mask[(i, i)] = 0.0;
                }
                let J = &mask * &G * G.transpose() * &mask;
                let A = J.view((0, 0), (n, n)).into_owned();
                let B = J.view((n, n), (n, n)).into_owned();
                let C = J.view((0, n), (n, n)).into_owned();
                let zero = DVector::zeros(n);
                let r = fuse_semidefinite(
                    SemidefiniteRule::Ci,
                    &zero,
                    &A,
                    &zero,
                    &B,
                    &CrossPattern::fully_unknown(n),
                    Criterion::Trace,
                )
                .unwrap();
                let f = &r.fused;
                let identity = &f.K_a + &f.K_b;
                assert!((identity - DMatrix::identity(n, n)).amax() <= 1e-8, "n {n}");
                let cross = &f.K_a * &C * f.K_b.transpose();
                let error = &f.K_a * &A * f.K_a.transpose()
                    + &f.K_b * &B * f.K_b.transpose()
                    + &cross
                    + cross.transpose();
                let margin = (&f.P - error).symmetric_eigenvalues().min();
                assert!(
                    margin >= -1e-8 * f.P.amax(),
                    "n {n} rank {rank_a}: {margin}"
                );
                // The grid: F(ω)⁻¹'s trace at 99 weights is never below the optimum's.
                let (Ya, _) = truncated_inverse("P_a", &A).unwrap();
                let (Yb, _) = truncated_inverse("P_b", &B).unwrap();
                for k in 1..100 {
                    let w = k as f64 / 100.0;
                    if let Some(inv) = (&Ya * w + &Yb * (1.0 - w)).try_inverse() {
                        assert!(
                            inv.trace() >= f.P.trace() * (1.0 - 1e-9),
                            "n {n} rank {rank_a} ω {w}"
                        );
                    }
                }
                assert_eq!(r.truncated, vec!["P_a".to_string()]);
            }
        }
    }

    /// A collapsed covariance, one fixed state, and both zero in a direction (refused).
    #[test]
    fn collapsed_fixed_and_impossible_pairs() {
        let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
        let zero = DVector::zeros(2);
        let run = |A: DMatrix<f64>, B: DMatrix<f64>, xa: &DVector<f64>| {
            fuse_semidefinite(
                SemidefiniteRule::Ci,
                xa,
                &A,
                &zero,
                &B,
                &CrossPattern::fully_unknown(2),
                Criterion::Trace,
            )
        };
        // P_a = diag(½, 0): a claims state 1 exactly; the form takes that direction as
        // uninformed by a (it never trusts a claim of certainty), so state 1 is b's: its mean,
        // and the variance 3/(1 − ω) of b's weighted information.
        let xa = DVector::from_row_slice(&[1.0, 2.0]);
        let r = run(d(&[0.5, 0.0]), d(&[2.0, 3.0]), &xa).unwrap();
        let w = r.omega[0];
        assert!(w > 0.0 && w < 1.0, "{w}");
        assert!(
            (r.fused.P[(1, 1)] - 3.0 / (1.0 - w)).abs() <= 1e-12,
            "{}",
            r.fused.P
        );
        assert!(r.fused.x[1].abs() <= 1e-12, "{}", r.fused.x);
        assert!((r.fused.P[(0, 0)] - 1.0 / (2.0 * w + (1.0 - w) / 2.0)).abs() <= 1e-12);
        assert_eq!(r.truncated, vec!["P_a".to_string()]);
        // A semi-definite rank-one P_a (a broadcast row): a bound on the informed direction.
        let row = DMatrix::from_row_slice(2, 2, &[0.04, 0.04, 0.04, 0.04]);
        let r = run(row, d(&[4.1, 0.04]), &zero).unwrap();
        assert!(r.fused.P.trace() <= 4.14 + 1e-12);
        // EI: state 0 takes the more informed a (½ against 2), state 1 b's alone; both
        // zero in a direction is refused as for CI.
        let run_ei = |A: DMatrix<f64>, B: DMatrix<f64>| {
            fuse_semidefinite(
                SemidefiniteRule::Ei,
                &xa,
                &A,
                &zero,
                &B,
                &CrossPattern::fully_unknown(2),
                Criterion::Trace,
            )
        };
        let r = run_ei(d(&[0.5, 0.0]), d(&[2.0, 3.0])).unwrap();
        assert!(
            (&r.fused.P - d(&[0.5, 3.0])).amax() <= 1e-12,
            "{}",
            r.fused.P
        );
        assert!((&r.fused.x - DVector::from_row_slice(&[1.0, 0.0])).amax() <= 1e-12);
        assert!(run_ei(d(&[1.0, 0.0]), d(&[2.0, 0.0])).is_err());
        // Both zero in direction 1: no bound.
        let e = run(d(&[1.0, 0.0]), d(&[2.0, 0.0]), &zero).unwrap_err();
        assert!(e.to_string().contains("both zero in some direction"), "{e}");
        // Indefinite: refused, named.
        let e = run(d(&[1.0, -0.5]), d(&[2.0, 3.0]), &zero).unwrap_err();
        assert!(matches!(e, InputError::NotPositiveDefinite { ref name, .. } if name == "P_a"));
        // Equal covariances: the midpoint, the mean averaged.
        let xb = DVector::from_row_slice(&[-1.0, 0.0]);
        let r = fuse_semidefinite(
            SemidefiniteRule::Ci,
            &xa,
            &d(&[1.0, 0.0]),
            &xb,
            &d(&[1.0, 0.0]),
            &CrossPattern::fully_unknown(2),
            Criterion::Trace,
        );
        assert!(r.is_err(), "both zero in direction 1");
        let r = fuse_semidefinite(
            SemidefiniteRule::Ci,
            &xa,
            &d(&[1.0, 1e-30]),
            &xb,
            &d(&[1.0, 1e-30]),
            &CrossPattern::fully_unknown(2),
            Criterion::Trace,
        );
        assert!(
            r.is_err(),
            "1e-30 is zero next to 1: both zero in direction 1"
        );
    }
}
