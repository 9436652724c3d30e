//! Inverse covariance intersection (ICI; Noack, Sijs, Reinhardt, Hanebeck 2017).
//!
//! `P⁻¹ = P_a⁻¹ + P_b⁻¹ − Γ⁻¹`, `Γ = ω P_a + (1−ω) P_b`, with gains
//! `K_a = P (P_a⁻¹ − ω Γ⁻¹)`, `K_b = P (P_b⁻¹ − (1−ω) Γ⁻¹)` (`K_a + K_b = I`). ICI is
//! conservative when the unknown correlation stems from *common information* (each estimate
//! is an independent part fused with an unknown shared part, as in networks that exchange
//! estimates), and then never looser than CI; it is **not** conservative for an arbitrary
//! admissible `P_ab` (the explorer's region shows where it fails). Note the
//! weight's direction: `ω = 0` returns `P_a` and `ω = 1` returns `P_b` (`Γ` is then the other
//! estimate's covariance and cancels).
//!
//! In the basis of the CI pencil (`P_b = W Wᵀ`, `P_a = W diag(μ) Wᵀ`, one generalized
//! eigenproblem) everything is diagonal: `Γ = W diag(gᵢ) Wᵀ` with `gᵢ(ω) = (1 − ω) + ω μᵢ`,
//! `P = W diag(1/hᵢ) Wᵀ` with `hᵢ = 1/μᵢ + 1 − 1/gᵢ` (between `min(1/μᵢ, 1)` and
//! `max(1/μᵢ, 1)`, so positive), so `tr P(ω) = Σ ‖wᵢ‖²/hᵢ` and `log det P = log det WWᵀ −
//! Σ ln hᵢ` cost `O(n)` per `ω`.
//!
//! Both criteria are convex in `ω`: `Γ(ω)` is affine, so `Γ⁻¹` is matrix-convex and
//! `P⁻¹ = P_a⁻¹ + P_b⁻¹ − Γ⁻¹` matrix-concave; `X ↦ X⁻¹` is matrix-convex and
//! matrix-decreasing, so `P(ω)` is matrix-convex and `tr P` convex; `log det` is concave and
//! increasing, so `log det P = −log det P⁻¹` is convex. (Per axis: `hᵢ` is concave and positive,
//! `1/hᵢ` convex.) The weight is therefore found exactly as for CI: an endpoint when the
//! derivative there does not point inwards (within `1e-9` of the size of its terms; where it
//! does at neither end the criterion is flat and `ω = ½`, the middle of the optimal set),
//! otherwise the root of the analytic derivative by CI's safeguarded Newton
//! (one minimiser for both rules: `ci::minimise_convex`) to machine precision.

use nalgebra::{DMatrix, DVector};

use super::ci::{minimise_convex, weighted, Pencil, Weighted};
use super::{covariance_twins, BlockMean, Criterion, Fused, FusionProblem, MeanPlan};
use crate::error::InputError;
use crate::linalg::symmetrize_in_place;

/// ICI result: the fused estimate and the weight `ω` of `Γ = ω P_a + (1−ω) P_b`.
#[derive(Debug, Clone, PartialEq)]
pub struct IciResult {
    /// Fused estimate, bound and gains.
    pub fused: Fused,
    /// `ω` (`0` gives `P_a`, `1` gives `P_b`).
    pub omega: f64,
}

/// Per-axis quantities of ICI at `ω`: `gᵢ`, `hᵢ = 1/μᵢ + 1 − 1/gᵢ`, each as a sum of
/// non-negative terms so that it keeps its relative accuracy (the plain form cancels when
/// `1/gᵢ` is close to `1/μᵢ` or to `1`): `hᵢ = 1 + (1−ω)(1−μᵢ)/(μᵢ gᵢ)` for `μᵢ ≤ 1` and
/// `hᵢ = 1/μᵢ + ω(μᵢ−1)/gᵢ` above.
fn axis(mu: f64, omega: f64) -> (f64, f64) {
    let g = (1.0 - omega) + omega * mu;
    let h = if mu <= 1.0 {
        1.0 + (1.0 - omega) * (1.0 - mu) / (mu * g)
    } else {
        1.0 / mu + omega * (mu - 1.0) / g
    };
    (g, h)
}

/// The criterion's first and second derivative at `ω` summed over `pencils` (with their
/// multiplicities, [`Weighted`]), and the size of the terms the first sums (its rounding
/// scale). With `hᵢ' = (μᵢ − 1)/gᵢ²` and `hᵢ'' = −2(μᵢ − 1)²/gᵢ³`: trace
/// `−Σ ‖wᵢ‖² hᵢ'/hᵢ²` and `Σ ‖wᵢ‖² (2hᵢ'²/hᵢ³ − hᵢ''/hᵢ²)`; log-det `−Σ hᵢ'/hᵢ` and
/// `Σ (hᵢ'²/hᵢ² − hᵢ''/hᵢ)` (both second derivatives are positive: `hᵢ'' ≤ 0`).
fn derivatives(pencils: &Weighted, criterion: Criterion, omega: f64) -> (f64, f64, f64) {
    let (mut d1, mut d2, mut size) = (0.0, 0.0, 0.0);
    for &(pencil, count) in pencils {
        for (&c, &mu) in pencil.weights.iter().zip(&pencil.mu) {
            let (g, h) = axis(mu, omega);
            let dh = (mu - 1.0) / (g * g);
            let ddh = -2.0 * (mu - 1.0) * (mu - 1.0) / (g * g * g);
            let (term, second, scale) = match criterion {
                Criterion::Trace => (
                    c * dh / (h * h),
                    c * (2.0 * dh * dh / (h * h * h) - ddh / (h * h)),
                    c * dh.abs() / (h * h),
                ),
                Criterion::Logdet => (dh / h, dh * dh / (h * h) - ddh / h, dh.abs() / h),
            };
            d1 -= count * term;
            d2 += count * second;
            size += count * scale;
        }
    }
    (d1, d2, size)
}

/// The minimiser over `[0, 1]` of ICI's (convex) criterion summed over `pencils`: CI's
/// minimiser ([`minimise_convex`]: endpoint ties, safeguarded Newton) on ICI's derivatives.
fn optimal_omega(pencils: &Weighted, criterion: Criterion) -> f64 {
    minimise_convex(|omega| derivatives(pencils, criterion, omega)).0
}

/// `(P, K_a)` of one pencil at `ω`, exact at the endpoints (`ω = 0` gives `P_a`, `ω = 1`
/// gives `P_b`).
#[allow(non_snake_case)]
fn fuse_at(
    pencil: &Pencil,
    P_a: &DMatrix<f64>,
    P_b: &DMatrix<f64>,
    omega: f64,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = P_a.nrows();
    if omega == 0.0 {
        (P_a.clone(), DMatrix::identity(n, n))
    } else if omega == 1.0 {
        (P_b.clone(), DMatrix::zeros(n, n))
    } else {
        let K_a = pencil.scaled_product(gain_scales(pencil, omega), &pencil.basis_inv());
        (interior_covariance(pencil, omega), K_a)
    }
}

/// `P = W diag(1/hᵢ) Wᵀ` at an interior `ω`.
#[allow(non_snake_case)]
fn interior_covariance(pencil: &Pencil, omega: f64) -> DMatrix<f64> {
    let scales = pencil.mu.iter().map(|&mu| 1.0 / axis(mu, omega).1);
    let mut P = pencil.scaled_product(scales, &pencil.basis.transpose());
    symmetrize_in_place(&mut P);
    P
}

/// `K_a = P P_a⁻¹ − ω P Γ⁻¹ = W diag(kᵢ) W⁻¹` with `kᵢ = (1/μᵢ − ω/gᵢ)/hᵢ`.
fn gain_scales(pencil: &Pencil, omega: f64) -> impl Iterator<Item = f64> + '_ {
    pencil.mu.iter().map(move |&mu| {
        let (g, h) = axis(mu, omega);
        (1.0 / mu - omega / g) / h
    })
}

/// ICI with the weight minimising `criterion` (see the module docs).
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// use nmci::rules::inverse_covariance_intersection;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::fully_unknown(2)).unwrap();
/// let ici = inverse_covariance_intersection(&p, Criterion::Trace).unwrap();
/// let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
/// assert!(ici.fused.trace() < ci.fused.trace());
/// ```
#[allow(non_snake_case)]
pub fn inverse_covariance_intersection(
    problem: &FusionProblem,
    criterion: Criterion,
) -> Result<IciResult, InputError> {
    let n = problem.dim();
    let pencil = Pencil::new(&problem.P_a, &problem.P_b)?;
    let omega = optimal_omega(&[(&pencil, 1.0)], criterion);
    let (P, K_a) = fuse_at(&pencil, &problem.P_a, &problem.P_b, omega);
    let K_b = DMatrix::identity(n, n) - &K_a;
    let x: DVector<f64> = &K_a * &problem.x_a + &K_b * &problem.x_b;
    Ok(IciResult {
        fused: Fused { x, P, K_a, K_b },
        omega,
    })
}

/// ICI's fused mean at an interior `ω`: `x = K_a x_a + K_b x_b = W (k ∘ W⁻¹x_a + (1 − k) ∘
/// W⁻¹x_b)`, no gain matrix formed.
pub(super) fn fused_mean(
    pencil: &Pencil,
    x_a: &DVector<f64>,
    x_b: &DVector<f64>,
    omega: f64,
) -> DVector<f64> {
    let (u_a, u_b) = (pencil.coordinates(x_a), pencil.coordinates(x_b));
    let coords = DVector::from_iterator(
        u_a.len(),
        gain_scales(pencil, omega)
            .zip(u_a.iter().zip(u_b.iter()))
            .map(|(s, (ua, ub))| s * ua + (1.0 - s) * ub),
    );
    &pencil.basis * coords
}

/// Monolithic ICI of block-stored estimates in place: `P_a[k] ← ICI(P_a[k], P_b[k])` with one
/// common `ω` minimising the criterion summed over the blocks (the blocks are independent
/// parts of one state; the tracking study's `ici` agents), and the plan that fuses the means
/// ([`MeanPlan`]). Blocks whose covariances equal an earlier block's in both estimates share
/// its pencil and bound. Returns `ω`.
#[allow(non_snake_case)]
pub(crate) fn ici_in_place(
    P_a: &mut [DMatrix<f64>],
    P_b: &[DMatrix<f64>],
    criterion: Criterion,
) -> Result<(f64, MeanPlan), InputError> {
    let twins = covariance_twins(P_a, P_b);
    let mut pencils: Vec<Option<Pencil>> = Vec::with_capacity(P_a.len());
    for (k, twin) in twins.iter().enumerate() {
        pencils.push(match twin {
            Some(_) => None,
            None => Some(Pencil::new(&P_a[k], &P_b[k])?),
        });
    }
    let source = |k: usize| twins[k].unwrap_or(k);
    let omega = optimal_omega(&weighted(&pencils, &twins), criterion);
    let mut plan = MeanPlan::with_blocks(P_a.len());
    if omega == 0.0 || omega == 1.0 {
        // ω = 0: P = P_a, K_a = I (keep `a`); ω = 1: P = P_b, K_a = 0.
        if omega == 1.0 {
            P_a.clone_from_slice(P_b);
        }
        let how = if omega == 0.0 {
            BlockMean::Keep
        } else {
            BlockMean::Take
        };
        plan.blocks.resize(P_a.len(), how);
        return Ok((omega, plan));
    }
    let slots: Vec<Option<usize>> = pencils
        .into_iter()
        .map(|p| p.map(|p| plan.push_pencil(p)))
        .collect();
    for k in 0..P_a.len() {
        let slot = match slots[source(k)] {
            Some(slot) => slot,
            // Not reached (a block's source always has its pencil); kept total without a panic.
            None => plan.push_pencil(Pencil::new(&P_a[k], &P_b[k])?),
        };
        // A twin's source t < k is fused already: its covariance is the twin's.
        P_a[k] = match twins[k] {
            Some(t) => P_a[t].clone(),
            None => interior_covariance(&plan.pencils[slot], omega),
        };
        plan.blocks.push(BlockMean::Ici {
            pencil: slot,
            omega,
        });
    }
    Ok((omega, plan))
}

#[cfg(test)]
#[allow(non_snake_case)]
mod tests {
    use super::*;

    use crate::linalg::test_spd as spd;

    /// The criterion at `ω` from the fused covariance itself (not the pencil's sums).
    fn criterion_at(P_a: &DMatrix<f64>, P_b: &DMatrix<f64>, omega: f64, c: Criterion) -> f64 {
        let Gamma = P_a * omega + P_b * (1.0 - omega);
        let inv = |m: &DMatrix<f64>| m.clone().try_inverse().unwrap();
        let P = inv(&(inv(P_a) + inv(P_b) - inv(&Gamma)));
        match c {
            Criterion::Trace => P.trace(),
            Criterion::Logdet => P.determinant().ln(),
        }
    }

    /// The analytic first and second derivatives against central differences of the
    /// criterion computed from `P(ω)` directly — what the Newton steps rely on — and the
    /// minimiser's step count: at most 8 interior evaluations on 40 random pencils, ending
    /// where the derivative is zero to within the rounding of its terms.
    #[test]
    fn derivatives_match_the_criterion_and_newton_converges_in_few_steps() {
        let mut seed = 11;
        let mut interior = 0;
        for case in 0..40 {
            let n = 2 + case % 5;
            let (P_a, P_b) = (spd(n, &mut seed, 0.3), spd(n, &mut seed, 0.3));
            let pencil = Pencil::new(&P_a, &P_b).unwrap();
            for criterion in [Criterion::Trace, Criterion::Logdet] {
                let f = |w: f64| criterion_at(&P_a, &P_b, w, criterion);
                let d = |w: f64| derivatives(&[(&pencil, 1.0)], criterion, w);
                for w in [0.2, 0.5, 0.8] {
                    let h = 1e-4;
                    let (d1, d2, _) = d(w);
                    let fd1 = (f(w + h) - f(w - h)) / (2.0 * h);
                    let fd2 = (d(w + h).0 - d(w - h).0) / (2.0 * h);
                    let scale = f(w).abs().max(1.0);
                    assert!(
                        (d1 - fd1).abs() <= 1e-6 * scale,
                        "case {case}: {d1} vs {fd1}"
                    );
                    assert!(
                        (d2 - fd2).abs() <= 1e-5 * d2.abs().max(scale),
                        "case {case}: {d2} vs {fd2}"
                    );
                    assert!(d2 > 0.0, "convex");
                }
                let (w, steps) = minimise_convex(d);
                assert!(steps <= 8, "case {case} {criterion:?}: {steps} steps");
                if w > 0.0 && w < 1.0 {
                    interior += 1;
                    let (g, _, size) = d(w);
                    assert!(g.abs() <= 1e-9 * size, "case {case}: g = {g} of {size}");
                }
            }
        }
        assert!(interior >= 20, "only {interior} interior optima tried");
    }
}
