//! N-way CI and nmCI: pairwise results for two estimates, weights on the simplex and optimal
//! against a brute-force grid, block splitting, and typed errors.
#![cfg(not(target_arch = "wasm32"))] // native tests; tests/web.rs runs in the browser
#![allow(non_snake_case)]

mod common;

use common::*;
use nalgebra::{DMatrix, DVector};
use nmci::*;

fn estimate(x: DVector<f64>, P: DMatrix<f64>) -> Estimate {
    Estimate::new("e", x, P).unwrap()
}

#[test]
fn two_estimates_give_exactly_the_pairwise_results() {
    let mut r = rng(21);
    for n in [1usize, 3, 6] {
        let p = random_problem(n, CrossPattern::fully_unknown(n), &mut r);
        let es = [
            estimate(p.x_a.clone(), p.P_a.clone()),
            estimate(p.x_b.clone(), p.P_b.clone()),
        ];
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let ci = covariance_intersection(&p, criterion).unwrap();
            let nway = covariance_intersection_nway(&es, criterion).unwrap();
            assert_eq!(nway.P, ci.fused.P);
            assert_eq!(nway.x, ci.fused.x);
            assert_eq!(nway.gains, vec![ci.fused.K_a.clone(), ci.fused.K_b.clone()]);
            assert_eq!(nway.omega, vec![vec![ci.omega, 1.0 - ci.omega]]);
        }
    }
    // nmCI with a diagonal pattern on diagonal covariances: the paper's example.
    let es = [
        estimate(DVector::zeros(2), diag(&[3.0, 1.0])),
        estimate(DVector::zeros(2), diag(&[1.0, 4.0])),
    ];
    let pairs = [PairPattern {
        i: 0,
        j: 1,
        pattern: CrossPattern::diagonal(2),
    }];
    let nm = non_monolithic_ci_nway(&es, &pairs, Criterion::Trace).unwrap();
    let pairwise = non_monolithic_ci(&paper_example(), Criterion::Trace).unwrap();
    assert_eq!(nm.P, pairwise.fused.P);
    assert_eq!(nm.blocks, pairwise.blocks);
    assert_eq!(nm.omega, vec![vec![0.0, 1.0], vec![1.0, 0.0]]);
}

/// Three 2-D estimates: the weights are on the simplex and no point of a 1/400 grid of the
/// simplex (80 601 points, each `tr (Σ ωᵢ Pᵢ⁻¹)⁻¹` by a 2×2 inverse) does better.
#[test]
fn three_estimates_are_optimal_against_a_brute_force_grid() {
    let mut r = rng(31);
    for case in 0..6 {
        let Ps: Vec<DMatrix<f64>> = (0..3).map(|_| random_spd(2, &mut r)).collect();
        let es: Vec<Estimate> = Ps
            .iter()
            .map(|P| estimate(DVector::zeros(2), P.clone()))
            .collect();
        let infos: Vec<DMatrix<f64>> = Ps
            .iter()
            .map(|P| P.clone().try_inverse().unwrap())
            .collect();
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let f = |w: [f64; 3]| {
                let Y = &infos[0] * w[0] + &infos[1] * w[1] + &infos[2] * w[2];
                let P = Y.try_inverse().unwrap();
                match criterion {
                    Criterion::Trace => P.trace(),
                    Criterion::Logdet => P.determinant().ln(),
                }
            };
            let fused = covariance_intersection_nway(&es, criterion).unwrap();
            let w = &fused.omega[0];
            assert!(w.iter().all(|&v| v >= 0.0) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let ours = f([w[0], w[1], w[2]]);
            assert!(
                (fused.P.trace() - f([w[0], w[1], w[2]])).abs() < 1e-9
                    || criterion == Criterion::Logdet
            );
            let m = 400;
            let mut best = f64::INFINITY;
            for i in 0..=m {
                for j in 0..=m - i {
                    let w = [
                        i as f64 / m as f64,
                        j as f64 / m as f64,
                        (m - i - j) as f64 / m as f64,
                    ];
                    best = best.min(f(w));
                }
            }
            assert!(
                ours <= best + 1e-12 * best.abs().max(1.0),
                "case {case} {criterion:?}: {ours} > grid {best}"
            );
            // And the grid gets close to it (it is a minimum, not a lucky low value elsewhere).
            assert!(
                best - ours < 1e-3 * best.abs().max(1.0),
                "case {case}: grid {best}, ours {ours}"
            );
            let sum: DMatrix<f64> = fused.gains.iter().sum();
            assert!((sum - DMatrix::identity(2, 2)).amax() < 1e-9);
        }
    }
}

/// Some estimates can be useless: one far worse than the others gets weight exactly 0.
#[test]
fn a_useless_estimate_gets_weight_zero() {
    let es = [
        estimate(DVector::zeros(2), diag(&[1.0, 3.0])),
        estimate(DVector::zeros(2), diag(&[3.0, 1.0])),
        estimate(DVector::zeros(2), diag(&[50.0, 50.0])),
    ];
    let fused = covariance_intersection_nway(&es, Criterion::Trace).unwrap();
    assert_eq!(fused.omega[0][2], 0.0);
    assert!((fused.omega[0][0] - 0.5).abs() < 1e-9, "{:?}", fused.omega);
}

#[test]
fn nmci_nway_splits_into_blocks_and_beats_monolithic() {
    let es = [
        estimate(DVector::from_vec(vec![1.0, 2.0]), diag(&[1.0, 9.0])),
        estimate(DVector::from_vec(vec![3.0, 4.0]), diag(&[9.0, 1.0])),
        estimate(DVector::from_vec(vec![5.0, 6.0]), diag(&[4.0, 4.0])),
    ];
    let diag_pairs: Vec<PairPattern> = [(0, 1), (0, 2), (1, 2)]
        .into_iter()
        .map(|(i, j)| PairPattern {
            i,
            j,
            pattern: CrossPattern::diagonal(2),
        })
        .collect();
    let nm = non_monolithic_ci_nway(&es, &diag_pairs, Criterion::Trace).unwrap();
    assert_eq!(nm.blocks, vec![vec![0], vec![1]]);
    // Per state the best single estimate (1-D CI picks the smallest variance).
    assert!((&nm.P - diag(&[1.0, 1.0])).amax() < 1e-12);
    assert!((nm.x[0] - 1.0).abs() < 1e-12 && (nm.x[1] - 4.0).abs() < 1e-12);
    let mono = covariance_intersection_nway(&es, Criterion::Trace).unwrap();
    assert!(nm.P.trace() < mono.P.trace());
    // A missing pair is fully unknown: no split.
    let nm2 = non_monolithic_ci_nway(&es, &diag_pairs[..2], Criterion::Trace).unwrap();
    assert_eq!(nm2.blocks, vec![vec![0, 1]]);
    assert_eq!(nm2.P, mono.P);
}

#[test]
fn bad_estimate_sets_are_typed_errors() {
    let e2 = estimate(DVector::zeros(2), diag(&[1.0, 1.0]));
    let e3 = estimate(DVector::zeros(3), diag(&[1.0, 1.0, 1.0]));
    let msg = |r: Result<NwayResult, InputError>| r.unwrap_err().to_string();
    assert_eq!(
        msg(covariance_intersection_nway(
            std::slice::from_ref(&e2),
            Criterion::Trace
        )),
        "invalid estimates: fusion needs at least 2 estimates (got 1)"
    );
    assert!(msg(covariance_intersection_nway(
        &[e2.clone(), e3],
        Criterion::Trace
    ))
    .contains("estimates[1] has size 3"));
    let pairs = [PairPattern {
        i: 0,
        j: 0,
        pattern: CrossPattern::diagonal(2),
    }];
    assert!(msg(non_monolithic_ci_nway(
        &[e2.clone(), e2.clone()],
        &pairs,
        Criterion::Trace
    ))
    .contains("pair (0, 0)"));
    let bad = Estimate::new(
        "estimates[4]",
        DVector::zeros(2),
        DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]),
    );
    assert!(bad
        .unwrap_err()
        .to_string()
        .starts_with("estimates[4].p is not positive definite"));
}
