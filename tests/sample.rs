//! The rejection sampler: admissibility, known zeros, seeding, acceptance, budget.
#![cfg(not(target_arch = "wasm32"))] // native tests; tests/web.rs runs in the browser
#![allow(non_snake_case)]

mod common;

use common::*;
use nalgebra::DMatrix;
use nmci::*;

#[test]
fn every_sample_is_admissible_and_respects_known_zeros() {
    let mut r = rng(1);
    for n in [2, 3, 4] {
        let pattern = random_pattern(n, 0.5, &mut r);
        let p = random_problem(n, pattern.clone(), &mut r);
        let s = sample_cross_covariances(&p, 300, 3, SamplerSettings::default()).unwrap();
        assert_eq!(s.len(), 300);
        for P_ab in &s.cross {
            for i in 0..n {
                for j in 0..n {
                    if !pattern.is_unknown(i, j) {
                        assert_eq!(P_ab[(i, j)], 0.0);
                    }
                }
            }
            assert!(min_eigenvalue(&p.joint_covariance(P_ab)) > 0.0);
        }
    }
}

#[test]
fn seeded_reproducible_and_seed_sensitive() {
    let p = paper_example();
    let a = sample_cross_covariances(&p, 50, 42, SamplerSettings::default()).unwrap();
    let b = sample_cross_covariances(&p, 50, 42, SamplerSettings::default()).unwrap();
    let c = sample_cross_covariances(&p, 50, 43, SamplerSettings::default()).unwrap();
    assert_eq!(a, b);
    assert_ne!(a.cross, c.cross);
}

#[test]
fn paper_example_correlations_cover_the_unit_interval() {
    // Diagonal pattern: every proposal is admissible (|ρ| < 1 almost surely) and the
    // correlations are uniform on [−1, 1].
    let p = paper_example();
    let s = sample_cross_covariances(&p, 4000, 5, SamplerSettings::default()).unwrap();
    assert_eq!(s.trials, 4000);
    assert_eq!(s.acceptance_rate(), 1.0);
    let rho: Vec<f64> = s.cross.iter().map(|c| c[(0, 0)] / 3f64.sqrt()).collect();
    let mut hist = [0usize; 4];
    for r in &rho {
        assert!(r.abs() <= 1.0);
        hist[(((r + 1.0) / 0.5) as usize).min(3)] += 1;
    }
    for h in hist {
        assert!((850..1150).contains(&h), "quartile counts {hist:?}");
    }
}

#[test]
fn acceptance_collapses_with_dimension_and_the_budget_stops_it() {
    // n = 4, fully unknown: acceptance about 4e-4 (the brief's figure).
    let P = DMatrix::<f64>::identity(4, 4);
    let p = FusionProblem::from_covariances(P.clone(), P, CrossPattern::fully_unknown(4)).unwrap();
    let s = sample_cross_covariances(&p, 20, 1, SamplerSettings::default()).unwrap();
    let rate = s.acceptance_rate();
    assert!(rate > 1e-4 && rate < 2e-3, "acceptance {rate}");
    let err =
        sample_cross_covariances(&p, 20, 1, SamplerSettings { max_trials: 1000 }).unwrap_err();
    match &err {
        SampleError::BudgetExhausted {
            requested, trials, ..
        } => {
            assert_eq!((*requested, *trials), (20, 1000));
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(err.to_string().contains("raise max_trials"));
    assert!(matches!(
        sample_cross_covariances(&p, 1, 1, SamplerSettings { max_trials: 0 }),
        Err(SampleError::InvalidSettings(_))
    ));
}

#[test]
fn independent_estimates_give_zero_cross_terms() {
    let p = FusionProblem::from_covariances(
        diag(&[1.0, 2.0]),
        diag(&[3.0, 4.0]),
        CrossPattern::independent(2),
    )
    .unwrap();
    let s = sample_cross_covariances(&p, 5, 0, SamplerSettings::default()).unwrap();
    assert!(s.cross.iter().all(|c| c.iter().all(|v| *v == 0.0)));
}
