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
//! eigenproblem) everything is diagonal: `Γ = W diag(gᵢ) Wᵀ` with `gᵢ(ω) = 1 + ω(μᵢ − 1)`,
//! `P = W diag(1/hᵢ) Wᵀ` with `hᵢ = 1/μᵢ + 1 − 1/gᵢ` (between `min(1/μᵢ, 1)` and
//! `max(1/μᵢ, 1)`, so positive), so `tr P(ω) = Σ ‖wᵢ‖²/hᵢ` and `log det P = log det WWᵀ −
//! Σ ln hᵢ` cost `O(n)` per `ω`.
//!
//! Both criteria are convex in `ω`: `Γ(ω)` is affine, so `Γ⁻¹` is matrix-convex and
//! `P⁻¹ = P_a⁻¹ + P_b⁻¹ − Γ⁻¹` matrix-concave; `X ↦ X⁻¹` is matrix-convex and
//! matrix-decreasing, so `P(ω)` is matrix-convex and `tr P` convex; `log det` is concave and
//! increasing, so `log det P = −log det P⁻¹` is convex. (Per axis: `hᵢ` is concave and positive,
//! `1/hᵢ` convex.) The weight is therefore found exactly as for CI: an endpoint when the
//! derivative there does not point inwards (ties within `1e-9` of the size of its terms go to
//! the endpoint), otherwise the root of the analytic derivative by the Illinois variant of
//! false position (superlinear, always bracketed) to machine precision.

use nalgebra::{DMatrix, DVector};

use super::ci::Pencil;
use super::{covariance_twins, Criterion, Estimate, Fused, FusionProblem};
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

/// Per-axis quantities of ICI at `ω`: `gᵢ`, `hᵢ`.
fn axis(mu: f64, omega: f64) -> (f64, f64) {
    let g = 1.0 + omega * (mu - 1.0);
    (g, 1.0 / mu + 1.0 - 1.0 / g)
}

/// The criterion's derivative at `ω` summed over `pencils`, each counted with its multiplicity
/// (the blocks of a block-diagonal problem share one `ω`; equal blocks share a pencil), and
/// the size of the terms it sums (its rounding scale). With `hᵢ' = (μᵢ − 1)/gᵢ²`:
/// trace `−Σ ‖wᵢ‖² hᵢ'/hᵢ²`, log-det `−Σ hᵢ'/hᵢ`.
fn slope(pencils: &[(&Pencil, f64)], criterion: Criterion, omega: f64) -> (f64, f64) {
    let (mut d, mut size) = (0.0, 0.0);
    for (pencil, count) in pencils {
        for (&c, &mu) in pencil.weights.iter().zip(&pencil.mu) {
            let (g, h) = axis(mu, omega);
            let dh = (mu - 1.0) / (g * g);
            let (term, scale) = match criterion {
                Criterion::Trace => (c * dh / (h * h), c * dh.abs() / (h * h)),
                Criterion::Logdet => (dh / h, dh.abs() / h),
            };
            d -= count * term;
            size += count * scale;
        }
    }
    (d, size)
}

/// Relative derivative below which an endpoint counts as optimal (as CI's tie rule).
const ENDPOINT_TIE: f64 = 1e-9;

/// The minimiser over `[0, 1]` of the (convex) criterion summed over `pencils`: an endpoint
/// exactly when the derivative there does not point inwards, otherwise the root of the
/// derivative by the Illinois variant of false position.
fn optimal_omega(pencil: &[(&Pencil, f64)], criterion: Criterion) -> f64 {
    let slope = |w: f64| slope(pencil, criterion, w);
    let (mut g_lo, size0) = slope(0.0);
    if g_lo >= -ENDPOINT_TIE * size0 {
        return 0.0;
    }
    let (mut g_hi, size1) = slope(1.0);
    if g_hi <= ENDPOINT_TIE * size1 {
        return 1.0;
    }
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let mut last_side = 0;
    for _ in 0..200 {
        let secant = (lo * g_hi - hi * g_lo) / (g_hi - g_lo);
        let mid = if secant > lo && secant < hi {
            secant
        } else {
            0.5 * (lo + hi)
        };
        if mid <= lo || mid >= hi {
            break;
        }
        let (g, size) = slope(mid);
        if g == 0.0 || g.abs() <= 4.0 * f64::EPSILON * size {
            return mid;
        }
        if g < 0.0 {
            lo = mid;
            g_lo = g;
            if last_side == -1 {
                g_hi *= 0.5; // Illinois: the stale end's value halved
            }
            last_side = -1;
        } else {
            hi = mid;
            g_hi = g;
            if last_side == 1 {
                g_lo *= 0.5;
            }
            last_side = 1;
        }
    }
    0.5 * (lo + hi)
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
/// use nmci::*;
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

/// Monolithic ICI of block-stored estimates in place: `a[k] ← ICI(a[k], b[k])` with one
/// common `ω` minimising the criterion summed over the blocks (the blocks are independent
/// parts of one state; the tracking study's `ici` agents). Blocks whose covariances equal an
/// earlier block's in both estimates share its pencil, bound and gains. Returns `ω`.
#[allow(non_snake_case)]
pub(crate) fn ici_in_place(
    a: &mut [Estimate],
    b: &[Estimate],
    criterion: Criterion,
) -> Result<f64, InputError> {
    let twins = covariance_twins(a, b);
    let mut pencils: Vec<Option<Pencil>> = Vec::with_capacity(a.len());
    for (k, twin) in twins.iter().enumerate() {
        pencils.push(match twin {
            Some(_) => None,
            None => Some(Pencil::new(&a[k].P, &b[k].P)?),
        });
    }
    let source = |k: usize| twins[k].unwrap_or(k);
    // Each distinct pencil once, counted as often as its block occurs.
    let mut counts = vec![0.0; a.len()];
    for k in 0..a.len() {
        counts[source(k)] += 1.0;
    }
    let refs: Vec<(&Pencil, f64)> = pencils
        .iter()
        .zip(&counts)
        .filter_map(|(p, &c)| p.as_ref().map(|p| (p, c)))
        .collect();
    let omega = optimal_omega(&refs, criterion);
    if omega == 0.0 {
        return Ok(omega); // P = P_a, K_a = I: keep `a`
    }
    if omega == 1.0 {
        a.clone_from_slice(b); // P = P_b, K_a = 0
        return Ok(omega);
    }
    let mut covariances: Vec<Option<DMatrix<f64>>> = vec![None; a.len()];
    for k in 0..a.len() {
        let fresh;
        let pencil = match pencils[source(k)].as_ref() {
            Some(p) => p,
            // Not reached (a block's source always has its pencil); kept total without a panic.
            None => {
                fresh = Pencil::new(&a[k].P, &b[k].P)?;
                &fresh
            }
        };
        let P = match twins[k].and_then(|t| covariances[t].clone()) {
            Some(shared) => shared,
            None => interior_covariance(pencil, omega),
        };
        // x = K_a x_a + K_b x_b = W (k ∘ W⁻¹x_a + (1 − k) ∘ W⁻¹x_b): no gain matrix formed.
        let (u_a, u_b) = (pencil.coordinates(&a[k].x), pencil.coordinates(&b[k].x));
        let coords = DVector::from_iterator(
            u_a.len(),
            gain_scales(pencil, omega)
                .zip(u_a.iter().zip(u_b.iter()))
                .map(|(s, (ua, ub))| s * ua + (1.0 - s) * ub),
        );
        a[k] = Estimate {
            x: &pencil.basis * coords,
            P: P.clone(),
        };
        covariances[k] = Some(P);
    }
    Ok(omega)
}
