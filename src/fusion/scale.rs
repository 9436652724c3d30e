//! Power-of-two normalisation of a problem's covariances for the solver-based rules (the
//! sampled SDP, the certified rule, the cutting planes).
//!
//! ## Why
//! Interior-point solvers stop on absolute as well as relative tolerances, and the programs
//! of this crate mix the covariances with dimensionless data (the identity block of the
//! sampled SDP's LMIs, the multipliers of the certificates). Solved as given, a problem whose
//! covariances are of order `10⁻¹²` stopped at its starting point (a sampled "optimum" three
//! orders of magnitude above the robust optimum) and one of order `10¹²` was declared
//! infeasible. Covariances in km² for metre-level sensors, or rad² for angles, are of that
//! order.
//!
//! ## The scaling is exact
//! Every rule here is equivariant under a common scaling of the covariances: for `s > 0`, `J`
//! is an admissible joint covariance of `(s P_a, s P_b)` exactly when `J / s` is one of
//! `(P_a, P_b)`, so `P̄ ⪰ K J Kᵀ` for all admissible `J` of the scaled problem exactly when
//! `P̄ / s ⪰ K J' Kᵀ` for all admissible `J'` of the original; the gains are unchanged and
//! traces scale by `s`. With `s = 2ᵏ` multiplying a float by `s` is exact unless the result
//! overflows or leaves the normal range, and [`Pow2::scaled_problem`] uses a scale only when
//! every entry of `s P_a` and `s P_b` is exact (checked by multiplying back); otherwise it
//! keeps `s = 1`. So the scaled problem is exactly `s` times the original, and a proof made
//! for it (a certificate repaired in floating point, a Lagrangian lower bound) is a proof for
//! the original once mapped back by `1/s` — exactly for a matrix whose every entry maps back
//! exactly ([`Pow2::unscale_exact`]), or, where an entry leaves the normal range, with its
//! diagonal raised by a few subnormal units so that it dominates ([`Pow2::unscale_dominating`]),
//! and rounded outward for a scalar bound.
//!
//! ## Which scale
//! A problem whose largest diagonal entry (of `P_a` and `P_b`) lies in `[2⁻⁴, 2⁴]` — the order
//! of magnitude the solver settings were tuned on, and every example, preset and golden file
//! of this crate — is solved as given, so its numbers do not change. Any other is scaled by
//! the `s = 2ᵏ` that brings that entry into `[1, 2)`. The means are not scaled (the gains, and
//! so the fused mean, do not depend on `s`).

use std::borrow::Cow;

use nalgebra::DMatrix;

use super::FusionProblem;

/// The largest diagonal entries for which a problem is solved as given (module docs).
pub(crate) const ORDER_ONE: std::ops::RangeInclusive<f64> = (1.0 / 16.0)..=16.0;

/// The largest diagonal entry of `P_a` and `P_b` (0 if none is positive).
pub(crate) fn largest_variance(problem: &FusionProblem) -> f64 {
    problem
        .P_a
        .diagonal()
        .iter()
        .chain(problem.P_b.diagonal().iter())
        .fold(0.0_f64, |m, &d| m.max(d))
}

/// A power of two `2ᵏ` by which a problem's covariances are multiplied.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Pow2 {
    k: i32,
}

/// `2ᵏ` as a float, for `k` in the normal range `[−1022, 1023]`.
pub(crate) fn two_to(k: i32) -> f64 {
    debug_assert!((-1022..=1023).contains(&k));
    f64::from_bits(((k + 1023) as u64) << 52)
}

/// The least float above finite `x` (`f64::next_up`, which needs Rust 1.86).
pub(crate) fn next_up(x: f64) -> f64 {
    if x == 0.0 {
        f64::from_bits(1)
    } else if x > 0.0 {
        f64::from_bits(x.to_bits() + 1)
    } else {
        f64::from_bits(x.to_bits() - 1)
    }
}

/// The greatest float below finite `x`.
pub(crate) fn next_down(x: f64) -> f64 {
    -next_up(-x)
}

/// `x · 2ᵏ` when that product is exact (it maps back to `x`), else `None`.
fn exact_times(x: f64, k: i32) -> Option<f64> {
    let y = x * two_to(k);
    (y.is_finite() && y * two_to(-k) == x).then_some(y)
}

impl Pow2 {
    /// No scaling.
    pub(crate) const ONE: Pow2 = Pow2 { k: 0 };

    /// [`Pow2::ONE`] when the largest diagonal entry of `P_a` and `P_b` lies in
    /// [`ORDER_ONE`] (or is not positive and finite), else the scale that brings it into
    /// `[1, 2)` (module docs).
    pub(crate) fn normalising(problem: &FusionProblem) -> Pow2 {
        let largest = largest_variance(problem);
        if !(largest.is_finite() && largest > 0.0) || ORDER_ONE.contains(&largest) {
            return Pow2::ONE;
        }
        // The exponent e with 2ᵉ ≤ largest < 2ᵉ⁺¹ (subnormals: below −1022, clamped).
        let e = if largest >= f64::MIN_POSITIVE {
            ((largest.to_bits() >> 52) & 0x7ff) as i32 - 1023
        } else {
            -1022
        };
        Pow2 {
            k: (-e).clamp(-1022, 1022),
        }
    }

    /// `(2ᵏ P_a, 2ᵏ P_b)` with the means and pattern unchanged, and the scale used: this
    /// one when every entry scales exactly, else [`Pow2::ONE`] with the problem as given
    /// (borrowed: no copy when nothing is scaled).
    #[allow(non_snake_case)]
    pub(crate) fn scaled_problem(self, problem: &FusionProblem) -> (Cow<'_, FusionProblem>, Pow2) {
        if self.k == 0 {
            return (Cow::Borrowed(problem), Pow2::ONE);
        }
        let scale = |m: &DMatrix<f64>| -> Option<DMatrix<f64>> {
            let mut out = m.clone();
            for v in out.iter_mut() {
                *v = exact_times(*v, self.k)?;
            }
            Some(out)
        };
        match (scale(&problem.P_a), scale(&problem.P_b)) {
            (Some(P_a), Some(P_b)) => (
                Cow::Owned(FusionProblem {
                    P_a,
                    P_b,
                    x_a: problem.x_a.clone(),
                    x_b: problem.x_b.clone(),
                    cross_pattern: problem.cross_pattern.clone(),
                }),
                self,
            ),
            _ => (Cow::Borrowed(problem), Pow2::ONE),
        }
    }

    /// `2ᵏ m` for each of `ms`, rounded (samples: data that is not part of a proof); borrowed
    /// when nothing is scaled.
    pub(crate) fn scale_all(self, ms: &[DMatrix<f64>]) -> Cow<'_, [DMatrix<f64>]> {
        if self.k == 0 {
            return Cow::Borrowed(ms);
        }
        Cow::Owned(ms.iter().map(|m| self.scale(m)).collect())
    }

    /// `2ᵏ m`, rounded (for data that is not part of a proof: samples, a solver's point).
    pub(crate) fn scale(self, m: &DMatrix<f64>) -> DMatrix<f64> {
        if self.k == 0 {
            return m.clone();
        }
        m * two_to(self.k)
    }

    /// `2⁻ᵏ m`, rounded (a solver's point, not a proof).
    pub(crate) fn unscale(self, m: &DMatrix<f64>) -> DMatrix<f64> {
        Pow2 { k: -self.k }.scale(m)
    }

    /// `2⁻ᵏ m` when every entry maps back exactly (a proven bound stays proven), else `None`.
    pub(crate) fn unscale_exact(self, m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
        let mut out = m.clone();
        for v in out.iter_mut() {
            *v = exact_times(*v, -self.k)?;
        }
        Some(out)
    }

    /// A symmetric float matrix `P̃ ⪰ 2⁻ᵏ m` for a symmetric `m` (a proven bound stays
    /// proven): `2⁻ᵏ m` itself when every entry maps back exactly ([`Pow2::unscale_exact`]);
    /// otherwise the rounded products with each diagonal entry raised by `δ = 2n·2⁻¹⁰⁷⁵` and
    /// rounded up. A product by a power of two is exact unless it leaves the normal range, and
    /// then its rounding error is at most `2⁻¹⁰⁷⁵` (half the spacing of the subnormals), so
    /// `P̃ − 2⁻ᵏ m` has diagonal entries at least `δ − 2⁻¹⁰⁷⁵ = (2n − 1)·2⁻¹⁰⁷⁵` and
    /// off-diagonal ones at most `2⁻¹⁰⁷⁵` in magnitude: it is diagonally dominant, hence positive
    /// definite (Gershgorin). The cost is a few subnormal units per diagonal entry. `None` when
    /// an entry overflows.
    pub(crate) fn unscale_dominating(self, m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
        if let Some(exact) = self.unscale_exact(m) {
            return Some(exact);
        }
        let n = m.nrows();
        let delta = n as f64 * f64::from_bits(1); // 2n·2⁻¹⁰⁷⁵ = n·2⁻¹⁰⁷⁴
        let mut out = self.unscale(m);
        for i in 0..n {
            // The float sum is within half a unit of the exact one; the next float above it
            // is not below it.
            out[(i, i)] = next_up(out[(i, i)] + delta);
        }
        out.iter().all(|v| v.is_finite()).then_some(out)
    }

    /// `2⁻ᵏ x`, rounded (a solver's objective, a violation).
    pub(crate) fn unscale_value(self, x: f64) -> f64 {
        x * two_to(-self.k)
    }

    /// A float no larger than `2⁻ᵏ x` (for a proven lower bound `x`).
    pub(crate) fn unscale_down(self, x: f64) -> f64 {
        self.unscale_outwards(x, next_down)
    }

    /// A float no smaller than `2⁻ᵏ x` (for a proven upper bound `x`).
    pub(crate) fn unscale_up(self, x: f64) -> f64 {
        self.unscale_outwards(x, next_up)
    }

    /// `2⁻ᵏ x` exactly, or the rounded product moved one float by `step` (outwards).
    fn unscale_outwards(self, x: f64, step: fn(f64) -> f64) -> f64 {
        exact_times(x, -self.k).unwrap_or_else(|| {
            let y = self.unscale_value(x);
            if y.is_nan() {
                y
            } else {
                step(y)
            }
        })
    }
}

/// `D m D` with `D = diag(2^{k_i})` chosen so that every diagonal entry lands in `[1, 4)`
/// (Jacobi equilibration by powers of two), when every diagonal entry is positive and every
/// product is exact; else `None`. A congruence with a positive diagonal `D` keeps positive
/// definiteness both ways, and powers of two keep the entries exact, so a proof for `D m D`
/// is one for `m` — for covariances whose variances span many orders of magnitude (mixed
/// units), where a proof on `m` itself needs its smallest eigenvalue above about `n u tr m`.
pub(crate) fn equilibrated(m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = m.nrows();
    let mut k = Vec::with_capacity(n);
    for i in 0..n {
        let d = m[(i, i)];
        if !(d.is_finite() && d >= f64::MIN_POSITIVE) {
            return None;
        }
        let e = ((d.to_bits() >> 52) & 0x7ff) as i32 - 1023;
        k.push(-e.div_euclid(2));
    }
    let mut out = m.clone();
    for j in 0..n {
        for i in 0..n {
            let v = exact_times(exact_times(m[(i, j)], k[i])?, k[j])?;
            out[(i, j)] = v;
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::CrossPattern;
    use nalgebra::DVector;

    fn problem(s: f64) -> FusionProblem {
        let m = |v: &[f64]| DMatrix::from_row_slice(2, 2, v) * s;
        FusionProblem::new(
            DVector::from_vec(vec![1.0, 2.0]),
            m(&[3.0, 0.5, 0.5, 1.0]),
            DVector::zeros(2),
            m(&[1.0, -0.3, -0.3, 4.0]),
            CrossPattern::fully_unknown(2),
        )
        .unwrap()
    }

    #[test]
    fn the_scale_brings_the_largest_diagonal_entry_into_one_to_two_exactly() {
        for s in [1e-300, 1e-12, 1e-3, 30.0, 1e12, 1e300] {
            let p = problem(s);
            let (scaled, used) = Pow2::normalising(&p).scaled_problem(&p);
            let largest = scaled.P_a.diagonal().max().max(scaled.P_b.diagonal().max());
            assert!((1.0..2.0).contains(&largest), "s {s}: {largest}");
            assert_ne!(used, Pow2::ONE);
            assert_eq!(used, Pow2::normalising(&p), "s {s}");
            assert_eq!(used.unscale_exact(&scaled.P_a).unwrap(), p.P_a, "s {s}");
            assert_eq!(used.unscale_exact(&scaled.P_b).unwrap(), p.P_b, "s {s}");
            assert_eq!(scaled.x_a, p.x_a);
        }
    }

    #[test]
    fn problems_of_order_one_are_left_as_they_are() {
        // Largest diagonal entries 4 s: from 2⁻⁴ to 2⁴ inclusive.
        for s in [1.0 / 64.0, 0.1, 1.0, 2.5, 4.0] {
            let p = problem(s);
            assert_eq!(Pow2::normalising(&p), Pow2::ONE, "s {s}");
            let (same, used) = Pow2::normalising(&p).scaled_problem(&p);
            assert!(matches!(same, Cow::Borrowed(_)) && used == Pow2::ONE);
        }
        assert_ne!(Pow2::normalising(&problem(4.1)), Pow2::ONE);
        assert_ne!(Pow2::normalising(&problem(0.97 / 64.0)), Pow2::ONE);
    }

    #[test]
    fn scaling_down_is_exact_up_to_about_308_orders_below_the_largest_variance() {
        // Largest variance 1e10, scaled by 2⁻³³: an entry 1e-290 lands at ~1.2e-300 (normal,
        // exact), 1e-300 at ~1.2e-310 (subnormal, bits lost): then nothing is scaled.
        for (entry, scaled) in [(1e-290, true), (1e-300, false)] {
            let mut p = problem(2.5e9);
            p.P_a[(0, 1)] = entry;
            p.P_a[(1, 0)] = entry;
            let (_, used) = Pow2::normalising(&p).scaled_problem(&p);
            assert_eq!(used != Pow2::ONE, scaled, "{entry}");
        }
    }

    /// Mapped back below the normal range, a bound still dominates its exact image: `P̃ 2ᵏ − m`
    /// (exact: scaling up a float by a power of two is, and the difference of floats this close
    /// is) is diagonally dominant with a positive diagonal; and where everything maps back
    /// exactly, nothing changes.
    #[test]
    fn a_bound_mapped_below_the_normal_range_still_dominates() {
        let m = DMatrix::from_row_slice(
            3,
            3,
            &[1.5, 3e-20, -7e-21, 3e-20, 1.25, 1e-25, -7e-21, 1e-25, 1.0],
        );
        for k in [1000, 1010, 1020] {
            let s = Pow2 { k };
            assert!(s.unscale_exact(&m).is_none(), "k {k}");
            let p = s.unscale_dominating(&m).unwrap();
            let back = p.map(|v| v * two_to(k / 2) * two_to(k - k / 2));
            let d = &back - &m;
            for i in 0..3 {
                let off: f64 = (0..3).filter(|&j| j != i).map(|j| d[(i, j)].abs()).sum();
                assert!(d[(i, i)] > off, "k {k} row {i}: {d}");
            }
            assert_eq!(p, p.transpose());
        }
        let s = Pow2 { k: 10 };
        assert_eq!(s.unscale_dominating(&m), s.unscale_exact(&m));
    }

    #[test]
    fn degenerate_and_subnormal_diagonals() {
        // No positive diagonal entry: nothing to normalise by.
        let mut zero = problem(1.0);
        zero.P_a.fill(0.0);
        zero.P_b.fill(0.0);
        assert_eq!(Pow2::normalising(&zero), Pow2::ONE);
        // Subnormal variances scale up exactly (by 2¹⁰²², the most the exponent allows).
        let mut tiny = problem(1.0);
        tiny.P_a *= 1e-310;
        tiny.P_b *= 1e-310;
        let (scaled, used) = Pow2::normalising(&tiny).scaled_problem(&tiny);
        assert_eq!(used, Pow2 { k: 1022 });
        assert!(scaled.P_b[(1, 1)] >= f64::MIN_POSITIVE);
        assert_eq!(used.unscale_exact(&scaled.P_b).unwrap(), tiny.P_b);
    }

    #[test]
    fn scale_and_unscale_multiply_by_the_power_of_two() {
        let m = DMatrix::from_row_slice(2, 2, &[3.0, -0.5, 0.25, 1e-300]);
        assert_eq!(Pow2 { k: 3 }.scale(&m), &m * 8.0);
        assert_eq!(Pow2 { k: -3 }.scale(&m), &m / 8.0);
        assert_eq!(Pow2 { k: 3 }.unscale(&m), &m / 8.0);
        assert_eq!(Pow2::ONE.scale(&m), m);
        assert_eq!(Pow2 { k: 3 }.unscale_value(8.0), 1.0);
    }

    #[test]
    fn next_up_and_down_are_the_neighbouring_floats() {
        for x in [0.0, 1.0, -1.0, 3e-310, -3e-310, 1e300, f64::MIN_POSITIVE] {
            let (u, d) = (next_up(x), next_down(x));
            assert!(d < x && x < u, "{x}");
            assert!(next_down(u) == x || x == 0.0, "{x}");
            assert!(next_up(d) == x || x == 0.0, "{x}");
        }
        assert_eq!(next_up(1.0), 1.0 + f64::EPSILON);
    }

    #[test]
    fn equilibration_puts_the_diagonal_in_one_to_four_exactly() {
        let m = DMatrix::from_row_slice(
            3,
            3,
            &[1e160, 1e79, 0.0, 1e79, 1.0, 0.25, 0.0, 0.25, 3e-200],
        );
        let e = equilibrated(&m).unwrap();
        for i in 0..3 {
            assert!((1.0..4.0).contains(&e[(i, i)]), "{}", e[(i, i)]);
        }
        // Each entry is m's times 2^(k_i + k_j), exactly: the ratios are powers of two.
        for (a, b) in e.iter().zip(m.iter()) {
            if *b != 0.0 {
                let r = a / b;
                assert_eq!(r, 2f64.powi(r.log2().round() as i32));
            }
        }
        assert!(equilibrated(&DMatrix::from_row_slice(1, 1, &[-1.0])).is_none());
        assert!(equilibrated(&DMatrix::from_row_slice(1, 1, &[0.0])).is_none());
    }

    #[test]
    fn an_inexact_scaling_is_not_used_and_inexact_values_round_outwards() {
        // An entry that would become subnormal when scaled down.
        let mut p = problem(1e200);
        p.P_a[(0, 1)] = 1e-300;
        p.P_a[(1, 0)] = 1e-300;
        let (same, used) = Pow2::normalising(&p).scaled_problem(&p);
        assert_eq!(used, Pow2::ONE);
        assert_eq!(*same, p);
        let down = Pow2 { k: 1060 - 1022 };
        // (2⁻¹⁰²² + 2⁻¹⁰⁷⁴) · 2⁻³⁸ needs a bit below the subnormal range.
        let x = next_up(f64::MIN_POSITIVE);
        assert!(down
            .unscale_exact(&DMatrix::from_element(1, 1, x))
            .is_none());
        let rounded = down.unscale_value(x);
        assert!(down.unscale_down(x) < rounded && rounded < down.unscale_up(x));
        // One float outwards of the rounded product, no further.
        assert_eq!(down.unscale_down(x), next_down(rounded));
        assert_eq!(down.unscale_up(x), next_up(rounded));
        assert_eq!(Pow2 { k: 3 }.unscale_down(8.0), 1.0);
        assert_eq!(Pow2 { k: 3 }.unscale_up(8.0), 1.0);
        assert_eq!(Pow2 { k: 3 }.unscale_down(24.0), 3.0);
        assert_eq!(Pow2 { k: -3 }.unscale_up(3.0), 24.0);
    }
}
