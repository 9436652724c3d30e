//! Property tests on random SPD pairs and patterns: no panic, conservative, symmetric output.

use nalgebra::{DMatrix, DVector};
use nmci::{check::*, contract::*, rules::*, sample::*, structure::*, *};
use proptest::prelude::*;

/// An SPD matrix `G Gᵀ + εI` from raw entries.
fn spd(n: usize, raw: &[f64], eps: f64) -> DMatrix<f64> {
    let g = DMatrix::from_fn(n, n, |i, j| raw[i * n + j]);
    &g * g.transpose() + DMatrix::identity(n, n) * eps
}

fn case() -> impl Strategy<Value = (usize, Vec<f64>, Vec<f64>, Vec<bool>, f64, u64)> {
    (1usize..=4).prop_flat_map(|n| {
        (
            Just(n),
            prop::collection::vec(-3.0f64..3.0, n * n),
            prop::collection::vec(-3.0f64..3.0, n * n),
            prop::collection::vec(prop::bool::weighted(0.4), n * n),
            1e-3f64..2.0,
            any::<u64>(),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn ci_and_nmci_are_conservative_and_symmetric((n, ra, rb, pat, eps, seed) in case()) {
        let P_a = spd(n, &ra, eps);
        let P_b = spd(n, &rb, eps);
        let pattern = CrossPattern::from_matrix(DMatrix::from_fn(n, n, |i, j| pat[i * n + j])).unwrap();
        let p = match FusionProblem::new(DVector::zeros(n), P_a, DVector::zeros(n), P_b, pattern) {
            Ok(p) => p,
            Err(e) => {
                // Only a numerically singular draw may be refused, and then with the PD message.
                prop_assert!(e.to_string().contains("not positive definite"), "{}", e);
                return Ok(());
            }
        };
        // The paper's rejection sampler, and hit-and-run (no trial budget) where its budget
        // runs out: no case is skipped.
        let samples = match sample_cross_covariances(&p, 200, seed, SamplerSettings::rejection(200_000)) {
            Ok(s) => s,
            Err(SampleError::BudgetExhausted { .. }) => {
                sample_cross_covariances(&p, 200, seed, SamplerSettings::hit_and_run())
                    .map_err(|e| TestCaseError::fail(e.to_string()))?
            }
            Err(e) => return Err(TestCaseError::fail(e.to_string())),
        };
        let scale = p.P_a.amax().max(p.P_b.amax());
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let ci = covariance_intersection(&p, criterion).unwrap();
            let nm = non_monolithic_ci(&p, criterion).unwrap();
            for f in [&ci.fused, &nm.fused] {
                prop_assert_eq!(&f.P, &f.P.transpose());
                prop_assert!(f.P.iter().all(|v| v.is_finite()));
                let m = worst_margin(&p, f, &samples.cross).unwrap();
                prop_assert!(m >= -1e-9 * scale, "margin {}", m);
            }
            prop_assert!(nm.fused.criterion(criterion) <= ci.fused.criterion(criterion) + 1e-9 * scale.max(1.0));
        }
    }

    #[test]
    fn fuse_never_panics_on_arbitrary_matrices(
        n in 1usize..4,
        raw_a in prop::collection::vec(prop::num::f64::ANY, 9),
        raw_b in prop::collection::vec(-5.0f64..5.0, 9),
        // Which of P_a, P_b are made symmetric positive definite (`G Gᵀ + I/10` from the raw
        // entries, when finite): otherwise almost every n ≥ 2 case would stop at the
        // symmetry check, and the solve paths would go untested.
        spd_a in any::<bool>(),
        spd_b in any::<bool>(),
        method in prop::sample::select(vec!["ci", "nmci"]),
    ) {
        let rows = |m: &DMatrix<f64>| (0..n).map(|i| m.row(i).iter().copied().collect()).collect::<Vec<Vec<f64>>>();
        let raw = |r: &[f64]| DMatrix::from_fn(n, n, |i, j| r[i * n + j]);
        let finite = raw_a[..n * n].iter().all(|v| v.is_finite() && v.abs() < 1e100);
        let pa = if spd_a && finite { spd(n, &raw_a, 0.1) } else { raw(&raw_a) };
        let pb = if spd_b { spd(n, &raw_b, 0.1) } else { raw(&raw_b) };
        let req = FuseRequest::new(
            if method == "ci" { Method::Ci } else { Method::Nmci },
            rows(&pa),
            rows(&pb),
        );
        // Either a result or a typed error; never a panic.
        match fuse(&req) {
            Ok(r) => prop_assert!(r.trace.is_finite()),
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
    }
}
