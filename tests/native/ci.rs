//! Covariance intersection: exact optimal ω against a brute-force scan, endpoints, gains,
//! and conservativeness against sampled admissible cross-covariances.

use crate::common;

use common::*;
use nalgebra::DMatrix;
use nmci::{check::*, rules::*, sample::*, structure::*, *};

/// The criterion at ω computed directly: P(ω) = (ω P_a⁻¹ + (1−ω) P_b⁻¹)⁻¹.
fn direct(problem: &FusionProblem, omega: f64, criterion: Criterion) -> f64 {
    let info = problem.P_a.clone().try_inverse().unwrap() * omega
        + problem.P_b.clone().try_inverse().unwrap() * (1.0 - omega);
    let P = info.try_inverse().unwrap();
    match criterion {
        Criterion::Trace => P.trace(),
        Criterion::Logdet => P.determinant().ln(),
    }
}

/// Brute force: a 2 001-point grid (the criterion is convex), then golden-section refinement around the best point.
fn brute_force(problem: &FusionProblem, criterion: Criterion) -> (f64, f64) {
    let f = |w: f64| direct(problem, w, criterion);
    let steps = 2_000;
    let (mut best_w, mut best) = (0.0, f(0.0));
    for k in 1..=steps {
        let w = k as f64 / steps as f64;
        let v = f(w);
        if v < best {
            best = v;
            best_w = w;
        }
    }
    let (mut lo, mut hi) = (
        (best_w - 1.0 / steps as f64).max(0.0),
        (best_w + 1.0 / steps as f64).min(1.0),
    );
    let g = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..200 {
        let a = hi - g * (hi - lo);
        let b = lo + g * (hi - lo);
        if f(a) < f(b) {
            hi = b;
        } else {
            lo = a;
        }
    }
    let w = 0.5 * (lo + hi);
    let v = f(w);
    if v < best {
        (w, v)
    } else {
        (best_w, best)
    }
}

#[test]
fn exact_omega_matches_brute_force_scan() {
    let mut r = rng(11);
    for &n in &[2usize, 5, 14] {
        for case in 0..6 {
            let p = random_problem(n, CrossPattern::fully_unknown(n), &mut r);
            for criterion in [Criterion::Trace, Criterion::Logdet] {
                let ci = covariance_intersection(&p, criterion).unwrap();
                let ours = direct(&p, ci.omega, criterion);
                let reported = ci.fused.criterion(criterion);
                let (w_bf, bf) = brute_force(&p, criterion);
                let scale = bf.abs().max(1.0);
                assert!(
                    ours <= bf + 1e-12 * scale,
                    "n={n} case={case} {criterion:?}: exact {ours} (ω={}) worse than brute force {bf} (ω={w_bf})",
                    ci.omega
                );
                assert!(
                    (ours - bf).abs() <= 1e-9 * scale,
                    "n={n} case={case} {criterion:?}: {ours} vs {bf}"
                );
                assert!(
                    (reported - ours).abs() <= 1e-9 * scale,
                    "reported criterion {reported} vs {ours}"
                );
            }
        }
    }
}

#[test]
fn endpoint_optima_are_exact() {
    // P_a much larger than P_b in every direction: take b (ω = 0 exactly); and vice versa.
    let p = FusionProblem::from_covariances(
        diag(&[10.0, 20.0]),
        diag(&[1.0, 2.0]),
        CrossPattern::fully_unknown(2),
    )
    .unwrap();
    let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
    assert_eq!(ci.omega, 0.0);
    assert_eq!(ci.fused.P, p.P_b);
    assert_eq!(ci.fused.K_a, DMatrix::zeros(2, 2));
    assert_eq!(ci.fused.K_b, DMatrix::identity(2, 2));
    let p = FusionProblem::from_covariances(
        diag(&[1.0, 2.0]),
        diag(&[10.0, 20.0]),
        CrossPattern::fully_unknown(2),
    )
    .unwrap();
    let ci = covariance_intersection(&p, Criterion::Logdet).unwrap();
    assert_eq!(ci.omega, 1.0);
    assert_eq!(ci.fused.P, p.P_a);
    assert_eq!(ci.fused.K_a, DMatrix::identity(2, 2));
}

#[test]
fn paper_example_ci_is_interior_and_looser_than_nmci() {
    let p = paper_example();
    let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
    assert!(ci.omega > 0.0 && ci.omega < 1.0);
    assert!(ci.fused.trace() > 2.0 + 1e-3);
    // Closed form check of the trace at ω: 1/(ω/3 + 1 − ω) + 1/(ω + (1 − ω)/4)
    let w = ci.omega;
    let expected = 1.0 / (w / 3.0 + 1.0 - w) + 1.0 / (w + (1.0 - w) / 4.0);
    assert!((ci.fused.trace() - expected).abs() < 1e-12);
}

#[test]
fn gains_are_unbiased_and_reproduce_the_ci_covariance() {
    let mut r = rng(3);
    for n in [2, 4, 7] {
        let p = random_problem(n, CrossPattern::fully_unknown(n), &mut r);
        let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
        let I = DMatrix::<f64>::identity(n, n);
        assert!((&ci.fused.K_a + &ci.fused.K_b - &I).amax() < 1e-12);
        // K_a = ω P P_a⁻¹, K_b = (1−ω) P P_b⁻¹
        let Kb = &ci.fused.P * p.P_b.clone().try_inverse().unwrap() * (1.0 - ci.omega);
        assert!((Kb - &ci.fused.K_b).amax() < 1e-9);
        let x = &ci.fused.K_a * &p.x_a + &ci.fused.K_b * &p.x_b;
        assert!((x - &ci.fused.x).amax() < 1e-12);
        assert!(
            (&ci.fused.P - ci.fused.P.transpose()).amax() == 0.0,
            "P symmetric"
        );
        // The covariance at ω, from its definition with plain inverses (not the pencil the
        // rule uses): P = (ω P_a⁻¹ + (1 − ω) P_b⁻¹)⁻¹.
        let inv = |m: &DMatrix<f64>| m.clone().try_inverse().unwrap();
        let P = inv(&(inv(&p.P_a) * ci.omega + inv(&p.P_b) * (1.0 - ci.omega)));
        assert!((&P - &ci.fused.P).amax() <= 1e-10 * P.amax(), "n = {n}");
    }
}

#[test]
fn ci_is_conservative_for_sampled_admissible_cross_covariances() {
    let mut r = rng(5);
    for (n, pattern_p) in [(2usize, 1.0), (3, 0.6), (3, 1.0), (4, 0.3)] {
        let pattern = random_pattern(n, pattern_p, &mut r);
        let p = random_problem(n, pattern, &mut r);
        let samples =
            sample_cross_covariances(&p, 1000, 17, SamplerSettings::rejection(50_000_000)).unwrap();
        assert_eq!(samples.len(), 1000);
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let ci = covariance_intersection(&p, criterion).unwrap();
            let m = worst_margin(&p, &ci.fused, &samples.cross).unwrap();
            assert!(m >= -1e-10, "n={n}: CI not conservative, margin {m}");
        }
    }
}

#[test]
fn block_structured_monolithic_ci_equals_dense_ci() {
    let mut r = rng(19);
    let groups = vec![vec![0, 4, 5], vec![1, 3], vec![2], vec![6, 7]];
    let n = 8;
    for criterion in [Criterion::Trace, Criterion::Logdet] {
        for _ in 0..4 {
            let P_a = block_spd(n, &groups, &mut r);
            let P_b = block_spd(n, &groups, &mut r);
            let x_a = nalgebra::DVector::from_fn(n, |i, _| i as f64);
            let x_b = nalgebra::DVector::from_fn(n, |i, _| -(i as f64));
            let p = FusionProblem::new(x_a, P_a, x_b, P_b, CrossPattern::fully_unknown(n)).unwrap();
            let dense = covariance_intersection(&p, criterion).unwrap();
            let blocks = covariance_intersection_blocks(&p, &groups, criterion).unwrap();
            assert!(
                (dense.omega - blocks.omega).abs() < 1e-9,
                "{} vs {}",
                dense.omega,
                blocks.omega
            );
            assert!((&dense.fused.P - &blocks.fused.P).amax() < 1e-9);
            assert!((&dense.fused.K_a - &blocks.fused.K_a).amax() < 1e-9);
            assert!((&dense.fused.x - &blocks.fused.x).amax() < 1e-9);
        }
    }
}

#[test]
fn block_structured_ci_rejects_bad_blocks() {
    let mut r = rng(20);
    let groups = vec![vec![0, 2], vec![1]];
    let P_a = block_spd(3, &groups, &mut r);
    let p =
        FusionProblem::from_covariances(P_a.clone(), P_a, CrossPattern::fully_unknown(3)).unwrap();
    let e = covariance_intersection_blocks(&p, &[vec![0, 2]], Criterion::Trace).unwrap_err();
    assert_eq!(
        e.to_string(),
        "the blocks are not a partition of the 3 states: state 1 is in no block"
    );
    let e = covariance_intersection_blocks(&p, &[vec![0, 2], vec![1, 2]], Criterion::Trace)
        .unwrap_err();
    assert!(e.to_string().contains("state 2 is in two blocks"));
    let e = covariance_intersection_blocks(&p, &[vec![0, 7], vec![1, 2]], Criterion::Trace)
        .unwrap_err();
    assert!(e.to_string().contains("state 7 does not exist"));
    let e =
        covariance_intersection_blocks(&p, &[vec![0, 1], vec![2]], Criterion::Trace).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("P_a is not block-diagonal in the given blocks: entry (0, 2)"),
        "{e}"
    );
}

#[test]
fn ci_covariance_is_the_ci_bound_at_any_weight() {
    // Against plain inverses at interior weights, and exactly P_b / P_a at the endpoints.
    let mut r = rng(31);
    for n in [1, 2, 4] {
        let p = random_problem(n, CrossPattern::fully_unknown(n), &mut r);
        for omega in [0.0, 0.1, 0.5, 0.9, 1.0] {
            let got = ci_covariance(&p, omega).unwrap();
            let expected = (p.P_a.clone().try_inverse().unwrap() * omega
                + p.P_b.clone().try_inverse().unwrap() * (1.0 - omega))
                .try_inverse()
                .unwrap();
            assert!(
                (&got - &expected).amax() <= 1e-10 * expected.amax(),
                "n = {n}, ω = {omega}"
            );
        }
        assert_eq!(ci_covariance(&p, 0.0).unwrap(), p.P_b);
        assert_eq!(ci_covariance(&p, 1.0).unwrap(), p.P_a);
        // A weight outside [0, 1] is refused by name (it gave a matrix of NaN before).
        for omega in [-0.5, 1.5, f64::NAN, f64::INFINITY] {
            let e = ci_covariance(&p, omega).unwrap_err();
            assert!(matches!(e, InputError::WeightOutOfRange { .. }), "{e}");
            assert_eq!(
                e.to_string(),
                format!("omega must be in [0, 1] (got {omega})")
            );
        }
    }
}

/// `Q diag(v) Qᵀ` for the orthogonal `Q = Hₙ/√n` (Sylvester's Hadamard matrix, n = 2, 4, 8):
/// every entry is `(1/n) Σₖ ±vₖ`, exact in floating point when the `vₖ` are powers of two
/// spanning fewer than 50 octaves, and within a few ulps of `‖v‖` otherwise.
fn hadamard_congruence(v: &[f64]) -> DMatrix<f64> {
    let n = v.len();
    let h = |i: usize, j: usize| {
        if (i & j).count_ones() % 2 == 0 {
            1.0
        } else {
            -1.0
        }
    };
    DMatrix::from_fn(n, n, |i, j| {
        (0..n).map(|k| h(i, k) * h(j, k) * v[k]).sum::<f64>() / n as f64
    })
}

fn relative_error(a: &DMatrix<f64>, reference: &DMatrix<f64>) -> f64 {
    (a - reference).norm() / reference.norm()
}

/// Pairs of covariances with one eigenbasis, rotated away from the axes by a Hadamard matrix
/// so that the rules' factorizations see dense matrices, with eigenvalues `2^e`, `e` spread
/// over `±span` and in the opposite order in `P_b`. Each covariance has condition number
/// `κ = 2^(2 span)`; the pair's ratios `a_k/b_k` span `κ²`. The inputs are exact, so the
/// references (`Q diag(g) Qᵀ` with `g` per axis) are accurate to a few ulps.
fn codiagonal_pairs(span: i32) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut pairs = Vec::new();
    for n in [2usize, 4, 8] {
        let e: Vec<i32> = (0..n)
            .map(|k| -span + (2 * span * k as i32) / (n as i32 - 1))
            .collect();
        let a: Vec<f64> = e.iter().map(|&e| 2f64.powi(e)).collect();
        let b: Vec<f64> = a.iter().rev().copied().collect();
        // The same pair with P_b scaled by 2^30 and 2^±70 (a sensor far worse or far better
        // overall; beyond 2^53 apart, P_a + P_b would lose P_b to rounding without the
        // balancing power of two).
        for k in [30, 70, -70] {
            let b_far: Vec<f64> = b.iter().map(|v| v * 2f64.powi(k)).collect();
            pairs.push((a.clone(), b_far));
        }
        pairs.push((a, b));
    }
    pairs
}

/// CI, ICI and EI keep the accuracy the conditioning of their inputs allows: at condition
/// numbers `κ` of `2²⁰` (about 10⁶) and `2⁴⁰` (about 10¹²), `P` is within `16 ε κ` (relative,
/// Frobenius) of the exact answer, and CI's trace at its own `ω` within `16 ε κ` of the exact
/// optimum. Through the textbook pencil of `P_a` against `P_b` alone (before the balanced
/// pencil) the ratios' spread `κ²` entered instead: this test failed at `κ = 2²⁰` with 9·10⁻⁷.
#[test]
fn ill_conditioned_pairs_keep_the_accuracy_their_conditioning_allows() {
    for span in [10, 20] {
        let kappa = 2f64.powi(2 * span);
        let tol = 16.0 * f64::EPSILON * kappa;
        for (a, b) in codiagonal_pairs(span) {
            let n = a.len();
            let p = FusionProblem::from_covariances(
                hadamard_congruence(&a),
                hadamard_congruence(&b),
                CrossPattern::fully_unknown(n),
            )
            .unwrap();
            let ci_axis = |w: f64| -> Vec<f64> {
                a.iter()
                    .zip(&b)
                    .map(|(a, b)| 1.0 / (w / a + (1.0 - w) / b))
                    .collect()
            };
            // CI at a fixed weight, and at its optimum against the exact optimal trace.
            for w in [0.25, 0.5, 0.75] {
                let P = ci_covariance(&p, w).unwrap();
                let e = relative_error(&P, &hadamard_congruence(&ci_axis(w)));
                assert!(
                    e <= tol,
                    "span {span} n {n} ω {w}: CI's P off by {e:.2e} > {tol:.2e}"
                );
            }
            let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
            let exact_trace = |w: f64| ci_axis(w).iter().sum::<f64>();
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..200 {
                let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
                if exact_trace(m1) < exact_trace(m2) {
                    hi = m2;
                } else {
                    lo = m1;
                }
            }
            let best = exact_trace(0.0)
                .min(exact_trace(1.0))
                .min(exact_trace(0.5 * (lo + hi)));
            let t = ci.fused.trace();
            assert!(
                (t - best).abs() <= tol * best,
                "span {span} n {n}: CI's trace {t} against the optimum {best}"
            );
            let e = relative_error(&ci.fused.P, &hadamard_congruence(&ci_axis(ci.omega)));
            assert!(
                e <= tol,
                "span {span} n {n}: CI's P off by {e:.2e} > {tol:.2e}"
            );
            // ICI at its weight (Γ = ω P_a + (1−ω) P_b), EI (per axis min(a, b)).
            let ici = inverse_covariance_intersection(&p, Criterion::Trace).unwrap();
            let w = ici.omega;
            let ici_axis: Vec<f64> = a
                .iter()
                .zip(&b)
                .map(|(&a, &b)| {
                    // 1/a + 1/b − 1/γ as a sum of non-negative terms (γ = w a + (1−w) b).
                    let g = w * a + (1.0 - w) * b;
                    let info = if a <= b {
                        1.0 / b + (1.0 - w) * (b - a) / (a * g)
                    } else {
                        1.0 / a + w * (a - b) / (b * g)
                    };
                    1.0 / info
                })
                .collect();
            let e = relative_error(&ici.fused.P, &hadamard_congruence(&ici_axis));
            assert!(
                e <= tol,
                "span {span} n {n}: ICI's P off by {e:.2e} > {tol:.2e}"
            );
            let ei = ellipsoidal_intersection(&p).unwrap();
            let ei_axis: Vec<f64> = a.iter().zip(&b).map(|(a, b)| a.min(*b)).collect();
            let e = relative_error(&ei.P, &hadamard_congruence(&ei_axis));
            assert!(
                e <= tol,
                "span {span} n {n}: EI's P off by {e:.2e} > {tol:.2e}"
            );
        }
    }
}
