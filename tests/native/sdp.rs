//! The sampled SDP: the paper's example to 1e-6, lower bound against nmCI, working set
//! equal to the full program, and solver failures reported as errors carrying the status.

use crate::common;

use common::*;
use nmci::{bounds::*, contract::*, rules::*, sample::*, sdp::*, structure::*, *};
use rand::Rng;

#[test]
fn paper_example_reaches_diag_1_1() {
    let p = paper_example();
    for (samples, seed) in [(50, 0), (100, 1), (200, 2)] {
        let opt = optimal_fusion(
            &p,
            &SdpSettings {
                samples,
                seed,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(
            (opt.fused.trace() - 2.0).abs() < 1e-6,
            "N={samples}: trace {}",
            opt.fused.trace()
        );
        assert!((&opt.fused.P - diag(&[1.0, 1.0])).amax() < 1e-6);
        assert!((&opt.fused.K_a - diag(&[0.0, 1.0])).amax() < 1e-6);
        assert_eq!(opt.samples, samples);
        assert!(opt.iterations > 0);
        assert!(opt.worst_sample_margin > -1e-7);
        assert!(opt.dual_objective <= opt.fused.trace() + 1e-7);
    }
}

#[test]
fn sampled_sdp_is_a_lower_bound_on_nmci() {
    let mut r = rng(31);
    for (n, prob) in [(2usize, 0.5), (2, 1.0), (3, 0.5), (3, 0.3), (4, 0.25)] {
        let pattern = random_pattern(n, prob, &mut r);
        let p = random_problem(n, pattern, &mut r);
        let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap();
        let opt = optimal_fusion(
            &p,
            &SdpSettings {
                samples: 100,
                seed: 3,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(
            opt.fused.trace() <= nm.fused.trace() + 1e-6,
            "n={n}: SDP {} above nmCI {}",
            opt.fused.trace(),
            nm.fused.trace()
        );
        let I = nalgebra::DMatrix::<f64>::identity(n, n);
        assert!((&opt.fused.K_a + &opt.fused.K_b - I).amax() < 1e-12);
        // The solution satisfies its own sampled constraints, computed here independently:
        // the same 100 samples (same sampler, same seed), and for each the margin
        // λ_min(P̄ − K P' Kᵀ) with `P' = [[P_a, X], [Xᵀ, P_b]]` written out.
        let drawn = sample_cross_covariances(&p, 100, 3, SamplerSettings::default()).unwrap();
        let (K_a, K_b, P) = (&opt.fused.K_a, &opt.fused.K_b, &opt.fused.P);
        let margin = margin_by_hand(&p, K_a, K_b, P, &drawn.cross);
        let scale = p.P_a.amax().max(p.P_b.amax());
        assert!(
            margin >= -1e-7 * scale,
            "n={n}: a sampled constraint is violated by {margin}"
        );
        assert!(
            (margin - opt.worst_sample_margin).abs() <= 1e-9 * scale,
            "n={n}: reported worst margin {} vs {margin}",
            opt.worst_sample_margin
        );
    }
}

#[test]
fn working_set_equals_the_full_program() {
    let mut r = rng(7);
    for (n, prob) in [(2usize, 1.0), (3, 0.5)] {
        let p = random_problem(n, random_pattern(n, prob, &mut r), &mut r);
        let samples =
            sample_cross_covariances(&p, 150, 1, SamplerSettings::rejection(50_000_000)).unwrap();
        let ws = optimal_fusion_for_samples(&p, &samples, &SdpSettings::default()).unwrap();
        let full = optimal_fusion_for_samples(
            &p,
            &samples,
            &SdpSettings {
                working_set: false,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(full.lmis, 150);
        assert!(ws.lmis < 150);
        assert!(
            (ws.fused.trace() - full.fused.trace()).abs() < 1e-6,
            "{} vs {}",
            ws.fused.trace(),
            full.fused.trace()
        );
    }
}

#[test]
fn nearly_singular_samples_are_handled() {
    // Correlations within 1e-9 of ±1: the paper's P'⁻¹ form explodes here, the congruent form does not.
    let p = paper_example();
    let s3 = 3f64.sqrt();
    let near = |rx: f64, ry: f64| diag(&[rx * s3, ry * 2.0]);
    let cross = vec![
        near(1.0 - 1e-9, -1.0 + 1e-9),
        near(-1.0 + 1e-9, 1.0 - 1e-9),
        near(0.3, 0.2),
        near(0.99, 0.99),
    ];
    let samples = CrossSamples {
        cross,
        trials: 4,
        auto: None,
    };
    let opt = optimal_fusion_for_samples(&p, &samples, &SdpSettings::default()).unwrap();
    assert!(
        (opt.fused.trace() - 2.0).abs() < 1e-6,
        "trace {}",
        opt.fused.trace()
    );
}

#[test]
fn solver_failure_is_an_error_carrying_the_status() {
    let p = paper_example();
    let err = optimal_fusion(
        &p,
        &SdpSettings {
            samples: 50,
            max_iter: 2,
            ..Default::default()
        },
    )
    .unwrap_err();
    match &err {
        SolveError::SolverFailed { status, iterations } => {
            assert_eq!(status, "MaxIterations");
            assert_eq!(*iterations, 2);
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(err.to_string().contains("MaxIterations"));
}

#[test]
fn invalid_settings_are_rejected() {
    let p = paper_example();
    for s in [
        SdpSettings {
            samples: 0,
            ..Default::default()
        },
        SdpSettings {
            tolerance: 0.0,
            ..Default::default()
        },
        SdpSettings {
            tolerance: f64::NAN,
            ..Default::default()
        },
        SdpSettings {
            batch: 0,
            ..Default::default()
        },
        SdpSettings {
            max_iter: 0,
            ..Default::default()
        },
    ] {
        assert!(
            matches!(optimal_fusion(&p, &s), Err(SolveError::InvalidSettings(_))),
            "{s:?}"
        );
    }
    let empty = CrossSamples {
        cross: vec![],
        trials: 0,
        auto: None,
    };
    assert!(matches!(
        optimal_fusion_for_samples(&p, &empty, &SdpSettings::default()),
        Err(SolveError::InvalidSettings(_))
    ));
}

#[test]
fn splitting_into_independent_blocks_is_exact() {
    let mut r = rng(44);
    let groups = vec![vec![0, 3], vec![1, 2, 4]];
    let n = 5;
    let P_a = block_spd(n, &groups, &mut r);
    let P_b = block_spd(n, &groups, &mut r);
    let unknown = nalgebra::DMatrix::from_fn(n, n, |i, j| {
        groups.iter().any(|g| g.contains(&i) && g.contains(&j)) && (i == j || r.random_bool(0.5))
    });
    let p = FusionProblem::from_covariances(P_a, P_b, CrossPattern::from_matrix(unknown).unwrap())
        .unwrap();
    let samples =
        sample_cross_covariances(&p, 120, 6, SamplerSettings::rejection(50_000_000)).unwrap();
    let split = optimal_fusion_for_samples(&p, &samples, &SdpSettings::default()).unwrap();
    let whole = optimal_fusion_for_samples(
        &p,
        &samples,
        &SdpSettings {
            split_blocks: false,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(split.blocks, groups);
    assert_eq!(whole.blocks.len(), 1);
    assert!(
        (split.fused.trace() - whole.fused.trace()).abs() < 1e-6,
        "{} vs {}",
        split.fused.trace(),
        whole.fused.trace()
    );
    assert!(split.worst_sample_margin > -1e-7);
    // Gains between blocks are exactly zero.
    assert_eq!(split.fused.K_a[(0, 1)], 0.0);
    assert_eq!(split.fused.P[(3, 4)], 0.0);
}

/// The proven bracket of the fuse response: the Lagrangian bound below, the best proven rule
/// above; `lower ≤ upper` always (no tolerance), and on the paper's example the bracket
/// closes on the robust optimum 2 by 100 samples.
#[test]
fn certified_gap_brackets_the_robust_optimum() {
    let request = |pattern: &str, samples: usize, seed: u64| {
        serde_json::from_str::<FuseRequest>(&format!(
            r#"{{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]], "pab_unknown": {pattern},
                "method": "sdp", "samples": {samples}, "seed": {seed}}}"#
        ))
        .unwrap()
    };
    let diagonal = "[[true, false], [false, true]]";
    let full = "[[true, true], [true, true]]";
    for samples in [100, 300] {
        let r = fuse(&request(diagonal, samples, 4)).unwrap();
        let (lower, upper) = {
            let b = r.bracket().unwrap();
            (b.lower, b.upper)
        };
        // The robust optimum is exactly 2 here (separable pattern: nmCI's diag(1, 1) is
        // optimal, Reinhardt et al. 2015 per block): both proven ends must enclose it, the
        // upper one by no more than its rounding.
        assert!(lower <= 2.0 && 2.0 <= upper, "[{lower}, {upper}] misses 2");
        assert!(upper <= 2.0 * (1.0 + 1e-14), "upper {upper}");
        assert!(lower >= 2.0 * (1.0 - 1e-6), "lower {lower}");
        assert!(
            r.bracket().map(|b| b.upper_rule) == Some(UpperRule::Nmci)
                || r.bracket().map(|b| b.upper_rule) == Some(UpperRule::Certified),
            "{:?}",
            r.bracket().map(|b| b.upper_rule)
        );
        // The gap is the exact difference rounded up: with Knuth's TwoSum,
        // `upper − lower = d + e` exactly, so the gap must be ≥ d + e, and within a few
        // units in the last place of it.
        let gap = r.bracket().unwrap().gap();
        let d = upper - lower;
        let bb = d - upper;
        let e = (upper - (d - bb)) + (-lower - bb);
        assert!(
            gap > d || (gap == d && e <= 0.0),
            "gap {gap} below {d} + {e}"
        );
        assert!(gap - d <= 4.0 * f64::EPSILON * d.abs().max(f64::MIN_POSITIVE));
        assert!(gap <= 1e-6, "gap {gap}");
    }
    // The README's figures for the paper's example, 100 samples, seed 0.
    let r = fuse(&request(diagonal, 100, 0)).unwrap();
    let (lower, upper) = {
        let b = r.bracket().unwrap();
        (b.lower, b.upper)
    };
    assert!(
        lower >= 1.99999999996,
        "README: at least 1.99999999996, got {lower}"
    );
    // nmCI's trace 2 rounded up, exactly (README, docs/contract.md).
    assert_eq!(
        upper, 2.0000000000000044,
        "README: at most 2.0000000000000044"
    );
    assert_eq!(r.bracket().map(|b| b.upper_rule), Some(UpperRule::Nmci));
    assert!(
        r.bracket().unwrap().gap_relative() <= 2e-11,
        "README: 2·10⁻¹¹"
    );
    // Fully unknown P_ab: CI is optimal (and nmCI is CI); the bracket holds.
    let r = fuse(&request(full, 100, 5)).unwrap();
    let fully_unknown = FusionProblem::from_covariances(
        diag(&[3.0, 1.0]),
        diag(&[1.0, 4.0]),
        CrossPattern::fully_unknown(2),
    )
    .unwrap();
    let ci = covariance_intersection(&fully_unknown, Criterion::Trace).unwrap();
    assert!((r.upper_bound().unwrap() - ci.fused.trace()).abs() < 1e-12);
    assert!(r.bracket().unwrap().lower <= r.upper_bound().unwrap());
    // Random problems and patterns: never lower > upper; the response serializes the keys.
    let mut rng = rng(77);
    for (n, prob) in [(2usize, 0.5), (3, 0.4), (3, 1.0), (4, 0.3)] {
        let p = random_problem(n, random_pattern(n, prob, &mut rng), &mut rng);
        let rows = |m: &nalgebra::DMatrix<f64>| {
            (0..n)
                .map(|i| (0..n).map(|j| m[(i, j)]).collect::<Vec<_>>())
                .collect::<Vec<_>>()
        };
        let mut req = FuseRequest::new(Method::Sdp, rows(&p.P_a), rows(&p.P_b));
        req.pair.pab_unknown = Some(
            (0..n)
                .map(|i| (0..n).map(|j| p.cross_pattern.is_unknown(i, j)).collect())
                .collect(),
        );
        req.options.samples = Some(100);
        req.options.seed = Some(1);
        let r = fuse(&req).unwrap();
        let (lower, upper) = {
            let b = r.bracket().unwrap();
            (b.lower, b.upper)
        };
        // Both ends proven: no tolerance.
        assert!(lower <= upper, "n={n}: {lower} > {upper}");
        assert!(lower > 0.0, "n={n}: a trivial lower bound");
        // The upper end is the best rule's trace, rounded up: never above CI's or nmCI's
        // (computed here) beyond rounding, and at least the named rule's own trace.
        let ci = covariance_intersection(&p, Criterion::Trace)
            .unwrap()
            .fused
            .trace();
        let nm = non_monolithic_ci(&p, Criterion::Trace)
            .unwrap()
            .fused
            .trace();
        assert!(
            upper <= ci.min(nm) * (1.0 + 1e-13),
            "n={n}: {upper} vs CI {ci}, nmCI {nm}"
        );
        match r.bracket().map(|b| b.upper_rule) {
            Some(UpperRule::Ci) => assert!(upper >= ci && upper <= ci * (1.0 + 1e-13)),
            Some(UpperRule::Nmci) => assert!(upper >= nm && upper <= nm * (1.0 + 1e-13)),
            Some(UpperRule::Certified) => assert!(upper < ci.min(nm)),
            other => panic!("n={n}: upper bound rule {other:?}"),
        }
        // The JSON carries the same numbers.
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["lower_bound"].as_f64(), Some(lower));
        assert_eq!(json["upper_bound"].as_f64(), Some(upper));
        assert_eq!(json["gap"].as_f64(), r.bracket().map(|b| b.gap()));
        assert_eq!(
            json["gap_relative"].as_f64(),
            r.bracket().map(|b| b.gap_relative())
        );
    }
}
