//! Covariance intersection: exact optimal ω against a brute-force scan, endpoints, gains,
//! and conservativeness against sampled admissible cross-covariances.

use crate::common;

use common::*;
use nalgebra::DMatrix;
use nmci::*;

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
            let m = worst_margin(&p, &ci.fused, &samples.cross);
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
    }
}
