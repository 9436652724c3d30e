use super::{omega::*, pencil::*, rule::*};
use nalgebra::{DMatrix, DVector};

use crate::error::InputError;
use crate::fusion::{covariance_twins, Criterion, FusionProblem};

use crate::fusion::{fuse_estimates, Estimate};
use crate::structure::CrossPattern;

use crate::linalg::test_spd as spd;

fn gaussian(n: usize, seed: &mut u64, shift: f64) -> Estimate {
    let P = spd(n, seed, shift);
    let x = spd(n, seed, 0.0).column(0).into_owned();
    Estimate { x, P }
}

fn problem(a: &Estimate, b: &Estimate) -> FusionProblem {
    FusionProblem::new_trusted(
        a.x.clone(),
        a.P.clone(),
        b.x.clone(),
        b.P.clone(),
        CrossPattern::fully_unknown(a.x.len()),
    )
}

fn covs(e: &[Estimate]) -> Vec<DMatrix<f64>> {
    e.iter().map(|e| e.P.clone()).collect()
}

fn close(a: &DMatrix<f64>, b: &DMatrix<f64>) -> bool {
    (a - b).amax() <= 1e-10 * b.amax().max(1.0)
}

/// Blocks: interior optimum, `b` much better (ω = 0), `a` much better (ω = 1), a twin of
/// block 0 (same covariances, other means) and identical estimates (a tie).
fn blocks(criterion_seed: u64) -> (Vec<Estimate>, Vec<Estimate>) {
    let mut seed = criterion_seed;
    let n = 5;
    let (a0, b0) = (gaussian(n, &mut seed, 0.5), gaussian(n, &mut seed, 0.5));
    let (a1, b1) = (gaussian(n, &mut seed, 9.0), gaussian(n, &mut seed, 0.01));
    let (a2, b2) = (gaussian(n, &mut seed, 0.01), gaussian(n, &mut seed, 9.0));
    let mut a3 = gaussian(n, &mut seed, 1.0);
    let mut b3 = gaussian(n, &mut seed, 1.0);
    a3.P = a0.P.clone();
    b3.P = b0.P.clone();
    let a4 = gaussian(n, &mut seed, 1.0);
    let b4 = a4.clone();
    (vec![a0, a1, a2, a3, a4], vec![b0, b1, b2, b3, b4])
}

/// The balancing power of two is the rounded middle of the extreme diagonal log-ratios.
/// `P_a + t P_b` that does not factor is `InputError::Unfactored`, naming the matrix and
/// the pair (reached here with matrices the input checks would refuse: `P_a = −P_b`).
#[test]
fn a_pencil_that_does_not_factor_names_the_matrix() {
    let I = DMatrix::<f64>::identity(2, 2);
    let e = Pencil::new(&(-&I), &I).err().unwrap();
    assert!(matches!(e, InputError::Unfactored { .. }), "{e}");
    assert!(
        e.to_string()
            .starts_with("P_a + t P_b, formed from P_a and P_b and positive definite in exact arithmetic when they are"),
        "{e}"
    );
}

/// The endpoint test's factorizations of `P_b` and `P_a` (the study's filter covariances,
/// not checked per step) name a failure as the input checks do: not positive definite only
/// when proven. `P_b` below is positive definite as floats (smallest eigenvalue 1.1044);
/// it was called "P_b is not positive definite (smallest eigenvalue 0)" before.
#[test]
fn the_endpoint_test_calls_a_covariance_indefinite_only_when_proven() {
    let I = DMatrix::<f64>::identity(2, 2);
    let undecidable = DMatrix::from_row_slice(
        2,
        2,
        &[
            1.5547804921864044e16,
            -2.2527755614633864e16,
            -2.2527755614633864e16,
            3.264124907555265e16,
        ],
    );
    let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
    let e = HalfPencil::new(&I, &undecidable).err().unwrap();
    assert!(matches!(e, InputError::Singular { .. }), "{e}");
    assert!(e.to_string().starts_with("P_b is singular"), "{e}");
    let e = HalfPencil::new(&I, &indefinite).err().unwrap();
    assert!(matches!(e, InputError::NotPositiveDefinite { .. }), "{e}");
    let half = HalfPencil::new(&I, &I).unwrap();
    let e = half
        .derivative_at_zero(&undecidable, &I, Criterion::Trace)
        .unwrap_err();
    assert!(e.to_string().starts_with("P_a is singular"), "{e}");
}

#[test]
fn the_balance_is_the_power_of_two_between_the_diagonal_ratios() {
    let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
    // log₂ ratios 2 and −6: the middle −2.
    assert_eq!(balance(&d(&[4.0, 1.0]), &d(&[1.0, 64.0])), 0.25);
    // Scaling P_b by 2¹⁰⁰ moves it by 2⁻¹⁰⁰, exactly.
    assert_eq!(
        balance(&d(&[4.0, 1.0]), &d(&[2f64.powi(100), 2f64.powi(106)])),
        2f64.powi(-102)
    );
    // log₂ ratios 0 and 1: the middle ½ rounds away from zero, to 2¹.
    assert_eq!(balance(&d(&[1.0, 2.0]), &d(&[1.0, 1.0])), 2.0);
    // Equal diagonals: 1.
    assert_eq!(balance(&d(&[3.0, 5.0]), &d(&[3.0, 5.0])), 1.0);
}

#[test]
fn block_nmci_in_place_matches_per_block_ci() {
    for criterion in [Criterion::Trace, Criterion::Logdet] {
        let (mut a, b) = blocks(7);
        let reference: Vec<CiResult> = a
            .iter()
            .zip(&b)
            .map(|(a, b)| covariance_intersection(&problem(a, b), criterion).unwrap())
            .collect();
        let omegas = fuse_estimates(&mut a, &b, |a, b| nmci_in_place(a, b, criterion)).unwrap();
        assert_eq!(omegas[1], 0.0);
        assert_eq!(omegas[2], 1.0);
        assert_eq!(omegas[3], omegas[0]);
        assert!(omegas[0] > 0.0 && omegas[0] < 1.0);
        assert_eq!(omegas[4], 0.5, "a flat criterion takes the midpoint");
        for (k, r) in reference.iter().enumerate() {
            assert!((omegas[k] - r.omega).abs() < 1e-9, "{criterion:?} {k}");
            assert!(close(&a[k].P, &r.fused.P), "{criterion:?} block {k}");
            let x = DMatrix::from_column_slice(5, 1, a[k].x.as_slice());
            let rx = DMatrix::from_column_slice(5, 1, r.fused.x.as_slice());
            assert!(close(&x, &rx), "{criterion:?} mean {k}");
        }
    }
}

#[test]
fn block_ci_in_place_matches_independent_ci() {
    for criterion in [Criterion::Trace, Criterion::Logdet] {
        let (mut a, b) = blocks(11);
        let problems: Vec<FusionProblem> = a.iter().zip(&b).map(|(a, b)| problem(a, b)).collect();
        let (fused, omega_ref) = covariance_intersection_independent(&problems, criterion).unwrap();
        let omega = fuse_estimates(&mut a, &b, |a, b| ci_in_place(a, b, criterion)).unwrap();
        assert!((omega - omega_ref).abs() < 1e-12);
        for (k, f) in fused.iter().enumerate() {
            assert!(close(&a[k].P, &f.P), "{criterion:?} block {k}");
            assert!((&a[k].x - &f.x).amax() < 1e-10, "{criterion:?} mean {k}");
        }
    }
}

/// Pairs whose CI optimum is interior: `P_a`, `P_b` random with comparable scales.
fn interior_pairs(count: usize) -> Vec<(DMatrix<f64>, DMatrix<f64>)> {
    let mut seed = 5;
    let mut pairs = Vec::new();
    while pairs.len() < count {
        let n = 2 + pairs.len() % 4;
        let (a, b) = (spd(n, &mut seed, 0.1), spd(n, &mut seed, 0.1));
        let pencil = Pencil::new(&a, &b).unwrap();
        let w = optimal_omega(&[(&pencil, 1.0)], Criterion::Trace);
        if w > 0.0 && w < 1.0 && optimal_omega(&[(&pencil, 1.0)], Criterion::Logdet) > 0.0 {
            pairs.push((a, b));
        }
    }
    pairs
}

#[test]
fn the_weight_is_found_by_newton_in_a_few_steps() {
    // The safeguard (bisection) alone needs ~50 steps to reach 4ε; Newton with the exact
    // second derivative converges quadratically: a wrong `d2` shows as many more steps.
    let mut most = 0;
    for (a, b) in interior_pairs(40) {
        let pencil = Pencil::new(&a, &b).unwrap();
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let (w, steps) = solve_omega(&[(&pencil, 1.0)], criterion);
            if w > 0.0 && w < 1.0 {
                // The derivative vanishes there (to rounding of its terms).
                let (g, _, size) = derivatives(&[(&pencil, 1.0)], criterion, w);
                assert!(g.abs() <= 1e-12 * size, "{criterion:?}: g = {g:e}");
                most = most.max(steps);
            }
        }
    }
    assert!(most <= 8, "Newton took up to {most} steps");
}

#[test]
fn the_weight_does_not_depend_on_the_scale() {
    // CI's ω is invariant under P_a, P_b → c P_a, c P_b (both criteria change by a
    // constant): the endpoint tests and the stopping rule must be relative to the scale.
    for (a, b) in interior_pairs(10) {
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let at = |c: f64| {
                let pencil = Pencil::new(&(&a * c), &(&b * c)).unwrap();
                let w = optimal_omega(&[(&pencil, 1.0)], criterion);
                // The in-place rule decides the endpoints its own way: the same ω.
                let (w_in_place, _) =
                    ci_block_in_place(&mut (&a * c), &(&b * c), criterion).unwrap();
                assert_eq!(w_in_place, w);
                w
            };
            let w = at(1.0);
            for k in [-12, -8, -4, 4, 8, 12] {
                let wk = at(10f64.powi(k));
                assert!((wk - w).abs() <= 1e-12, "{criterion:?} 1e{k}: {wk} vs {w}");
            }
        }
    }
}

#[test]
fn a_tie_takes_the_midpoint_and_averages_the_means_at_every_scale() {
    // Equal covariances: g ≡ 0, computed as rounding noise of either sign; the tie tolerance
    // scales with the terms, so at every scale and size ω = ½, the bound is the covariance
    // (to rounding) and the mean the average of the two (an endpoint would drop one).
    let mut seed = 13;
    for k in -8..=8 {
        for n in 1..=5 {
            let P = spd(n, &mut seed, 0.1) * 10f64.powi(k);
            let a = Estimate {
                x: DVector::from_fn(n, |i, _| i as f64 + 1.0),
                P: P.clone(),
            };
            let b = Estimate {
                x: DVector::from_fn(n, |i, _| -3.0 * i as f64),
                P: P.clone(),
            };
            let p = problem(&a, &b);
            let average = (&a.x + &b.x) * 0.5;
            for criterion in [Criterion::Trace, Criterion::Logdet] {
                let ci = covariance_intersection(&p, criterion).unwrap();
                assert_eq!(ci.omega, 0.5, "CI 1e{k}, n = {n}, {criterion:?}");
                assert!(
                    (&ci.fused.x - &average).amax() <= 1e-12 * average.amax().max(1.0),
                    "CI 1e{k}, n = {n}: {} vs {average}",
                    ci.fused.x
                );
                assert!(close(&ci.fused.P, &P), "CI 1e{k}, n = {n}");
                let mut fused = a.P.clone();
                let (w, pencil) = ci_block_in_place(&mut fused, &b.P, criterion).unwrap();
                assert_eq!(w, 0.5, "in place 1e{k}, n = {n}, {criterion:?}");
                assert!(pencil.is_some());
                assert!(close(&fused, &P), "in place 1e{k}, n = {n}");
            }
        }
    }
}

#[test]
fn endpoints_in_place_need_no_eigendecomposition() {
    // The in-place rule decides ω = 0 and ω = 1 from the derivatives at the endpoints
    // (Cholesky factorizations); only an interior optimum builds the pencil.
    let (a, b) = blocks(7);
    for criterion in [Criterion::Trace, Criterion::Logdet] {
        for (k, expected) in [(1, Some(0.0)), (2, Some(1.0)), (0, None)] {
            let mut fused = a[k].P.clone();
            let (w, pencil) = ci_block_in_place(&mut fused, &b[k].P, criterion).unwrap();
            match expected {
                Some(endpoint) => {
                    assert_eq!(w, endpoint, "{criterion:?} block {k}");
                    assert!(pencil.is_none(), "{criterion:?} block {k}");
                }
                None => assert!(w > 0.0 && w < 1.0 && pencil.is_some()),
            }
        }
    }
}

#[test]
fn twins_of_endpoint_blocks_take_the_endpoint() {
    // A twin (same covariances in both estimates, other means) of a block at ω = 0 takes
    // b's estimate, of a block at ω = 1 keeps a's: as CI of the twin alone would.
    let (a0, b0) = blocks(19);
    for criterion in [Criterion::Trace, Criterion::Logdet] {
        for k in [1, 2] {
            let mut seed = 40 + k as u64;
            let twin_a = Estimate {
                x: gaussian(5, &mut seed, 1.0).x,
                P: a0[k].P.clone(),
            };
            let twin_b = Estimate {
                x: gaussian(5, &mut seed, 1.0).x,
                P: b0[k].P.clone(),
            };
            let reference = covariance_intersection(&problem(&twin_a, &twin_b), criterion)
                .unwrap()
                .fused;
            let mut a = vec![a0[k].clone(), twin_a];
            let b = vec![b0[k].clone(), twin_b.clone()];
            assert_eq!(covariance_twins(&covs(&a), &covs(&b)), vec![None, Some(0)]);
            let omegas = fuse_estimates(&mut a, &b, |a, b| nmci_in_place(a, b, criterion)).unwrap();
            assert_eq!(omegas, vec![if k == 1 { 0.0 } else { 1.0 }; 2]);
            assert_eq!(a[1].x, reference.x, "{criterion:?} block {k}");
            assert_eq!(a[1].P, reference.P, "{criterion:?} block {k}");
        }
    }
}

#[test]
fn twins_are_exactly_equal_covariances_in_both() {
    let (a, b) = blocks(3);
    assert_eq!(
        covariance_twins(&covs(&a), &covs(&b)),
        vec![None, None, None, Some(0), None]
    );
}
