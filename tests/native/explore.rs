//! The explorer's analysis and the known-correlation fusion behind its region.

use crate::common;

use common::*;
use nalgebra::DMatrix;
use nmci::{check::*, contract::*, explore::*, rules::*, sample::*, structure::*, *};

#[test]
fn known_correlation_fusion_is_the_blue() {
    let mut r = rng(12);
    for n in [2, 3, 5] {
        let p = random_problem(n, random_pattern(n, 0.5, &mut r), &mut r);
        let s =
            sample_cross_covariances(&p, 20, 2, SamplerSettings::rejection(10_000_000)).unwrap();
        let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
        for P_ab in &s.cross {
            let best = known_correlation_fusion(&p, P_ab).unwrap();
            // (Hᵀ P'⁻¹ H)⁻¹ with H = [I; I]
            let inv = p.joint_covariance(P_ab).try_inverse().unwrap();
            let info = inv.view((0, 0), (n, n))
                + inv.view((0, n), (n, n))
                + inv.view((n, 0), (n, n))
                + inv.view((n, n), (n, n));
            let reference = info.try_inverse().unwrap();
            assert!((&best.P - &reference).amax() < 1e-8 * reference.amax().max(1.0));
            assert_eq!(best.P, best.P.transpose());
            // It is the fused covariance of its own gains, and no other gain does better.
            let own = fused_error_covariance(&p, &best.K_a, &best.K_b, P_ab).unwrap();
            assert!((&own - &best.P).amax() < 1e-8 * own.amax().max(1.0));
            let with_ci_gains =
                fused_error_covariance(&p, &ci.fused.K_a, &ci.fused.K_b, P_ab).unwrap();
            assert!(min_eigenvalue(&(with_ci_gains - &best.P)) > -1e-9);
        }
    }
}

#[test]
fn known_correlation_fusion_on_the_boundary_takes_the_pseudo_inverse() {
    // A singular joint covariance, not zero: state 1 is the same estimate twice (P_a = P_b =
    // P_ab = 1: S = P_a + P_b − P_ab − P_ba = 0 there), state 2 two independent estimates
    // (variances 1 and 4, scaled by 10¹⁰ in the second case so that the tolerance of the
    // pseudo-inverse must be relative). The optimum per state: variance 1 (no gain from
    // fusing an estimate with itself, K_a = 0 on S's null space) and 1·4/5 = 0.8, K_a = 4/5.
    for scale in [1.0, 1e10] {
        let p = FusionProblem::from_covariances(
            diag(&[1.0, scale]),
            diag(&[1.0, 4.0 * scale]),
            CrossPattern::diagonal(2),
        )
        .unwrap();
        let P_ab = diag(&[1.0, 0.0]);
        let f = known_correlation_fusion(&p, &P_ab).unwrap();
        let expected_P = diag(&[1.0, 0.8 * scale]);
        let expected_K_a = diag(&[0.0, 0.8]);
        assert!((&f.P - &expected_P).amax() <= 1e-12 * scale, "{}", f.P);
        assert!((&f.K_a - &expected_K_a).amax() <= 1e-12, "{}", f.K_a);
        assert_eq!(&f.K_a + &f.K_b, DMatrix::identity(2, 2));
        // Its gains attain it: the fused error covariance for this P_ab.
        let own = fused_error_covariance(&p, &f.K_a, &f.K_b, &P_ab).unwrap();
        assert!((&own - &f.P).amax() <= 1e-12 * scale);
    }
}

fn request(json: &str) -> ExploreRequest {
    serde_json::from_str(json).unwrap()
}

#[test]
fn paper_example_analysis() {
    let a = explore(&request(
        r#"{"pa": [[3,0],[0,1]], "pb": [[1,0],[0,4]], "pab_unknown": [[true,false],[false,true]]}"#,
    ))
    .unwrap();
    assert_eq!(a.n, 2);
    // The estimates' rows: tr and det of diag(3, 1) and diag(1, 4).
    let rows: Vec<(&str, f64, f64)> = a
        .estimates
        .iter()
        .map(|e| (e.name.as_str(), e.trace, e.det))
        .collect();
    assert_eq!(rows, [("pa", 4.0, 3.0), ("pb", 5.0, 4.0)]);
    // Every rule the registry marks for the explorer, in registry order.
    let methods: Vec<Method> = a.rules.iter().map(|r| r.method).collect();
    let expected: Vec<Method> = RULES
        .iter()
        .filter(|r| r.explorer)
        .map(|r| r.method)
        .collect();
    assert_eq!(methods, expected);
    assert!(a
        .rules
        .iter()
        .all(|r| r.response.is_some() && r.error.is_none()));
    let trace = |m| a.response(m).unwrap().trace;
    assert_eq!(trace(Method::Nmci), 2.0);
    assert!(trace(Method::Ci) > 3.0);
    let sdp = a.response(Method::Sdp).unwrap();
    assert!((sdp.trace - 2.0).abs() < 1e-6);
    let gap = a.gap.as_ref().unwrap();
    // The robust optimum is 2 (nmCI optimal on this separable pattern): proven on both sides.
    assert!(gap.lower <= 2.0 && 2.0 <= gap.upper && gap.upper <= 2.0 * (1.0 + 1e-14));
    assert!(gap.absolute < 1e-6 && gap.closed, "{gap:?}");
    assert_eq!(a.region_count, 300);
    assert_eq!(a.region.len(), 300 * 4);
    let margin = |m| a.rule(m).unwrap().margin.unwrap();
    assert!(margin(Method::Ci) > 0.0);
    assert!(margin(Method::Nmci) >= -1e-12 && margin(Method::Sdp) > -1e-7);
    // Every possible true fused covariance lies inside the nmCI bound diag(1, 1).
    for k in 0..a.region_count {
        let P = DMatrix::from_row_slice(2, 2, &a.region[4 * k..4 * k + 4]);
        assert!(min_eigenvalue(&(DMatrix::identity(2, 2) - P)) > -1e-12);
    }
}

#[test]
fn sampler_failure_leaves_ci_and_nmci_and_says_why() {
    let eye = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
    let a = explore(&request(&format!(
        r#"{{"pa": {eye}, "pb": {eye}, "max_trials": 50, "samples": 20, "region_samples": 20}}"#
    )))
    .unwrap();
    let sdp = a.rule(Method::Sdp).unwrap();
    assert!(sdp.response.is_none() && a.gap.is_none());
    assert!(a
        .rules
        .iter()
        .all(|r| r.margin.is_none() && r.coin.is_none()));
    assert!(sdp
        .error
        .as_ref()
        .unwrap()
        .contains("rejection sampler accepted only"));
    assert!(a
        .region_error
        .as_ref()
        .unwrap()
        .contains("raise max_trials"));
    assert!(a.response(Method::Ci).unwrap().trace > 0.0);
    assert!(a.response(Method::Nmci).unwrap().trace > 0.0);
}

#[test]
fn explore_rejects_bad_input() {
    for (json, needle) in [
        (
            r#"{"pa": [[1,2],[2,1]], "pb": [[1,0],[0,1]]}"#,
            "P_a is not positive definite",
        ),
        (
            r#"{"pa": [[1]], "pb": [[1]], "samples": 0}"#,
            "`samples` must be at least 1",
        ),
        (
            r#"{"pa": [[1]], "pb": [[1]], "max_trials": 0}"#,
            "`max_trials` must be at least 1",
        ),
    ] {
        let err = explore(&request(json)).unwrap_err().to_string();
        assert!(err.contains(needle), "{err}");
    }
    assert!(
        serde_json::from_str::<ExploreRequest>(r#"{"pa": [[1]], "pb": [[1]], "bogus": 1}"#)
            .is_err()
    );
}

#[test]
fn naive_fusion_is_the_independent_blue_and_not_conservative_under_correlation() {
    let mut r = rng(13);
    let p = random_problem(3, CrossPattern::fully_unknown(3), &mut r);
    let naive = naive_fusion(&p);
    let Pa_inv = p.P_a.clone().try_inverse().unwrap();
    let Pb_inv = p.P_b.clone().try_inverse().unwrap();
    let reference = (&Pa_inv + &Pb_inv).try_inverse().unwrap();
    assert!((&naive.P - &reference).amax() < 1e-10);
    let x = &reference * (&Pa_inv * &p.x_a + &Pb_inv * &p.x_b);
    assert!((&naive.x - x).amax() < 1e-10);
    // Two copies of the same information (correlation 0.9): naive claims half the covariance.
    let I = DMatrix::<f64>::identity(2, 2);
    let same =
        FusionProblem::from_covariances(I.clone(), I.clone(), CrossPattern::fully_unknown(2))
            .unwrap();
    let m = conservativeness_margin(&same, &naive_fusion(&same), &(I * 0.9)).unwrap();
    assert!((m + 0.45).abs() < 1e-12, "margin {m}");
}

/// ICI, EI and naive fusion are in the analysis with what they are guaranteed for, and every
/// rule has its COIN over the region: `≤ 1` exactly when its margin is `≥ 0` (both say "the
/// bound dominates `K P' Kᵀ` for every drawn `P'`"); CI and nmCI conservative, naive fusion
/// not (on the paper example its bound diag(3/4, 4/5) misses positively correlated `P'`).
#[test]
fn every_rule_with_its_coin_over_the_region() {
    let a = explore(&request(
        r#"{"pa": [[3,0],[0,1]], "pb": [[1,0],[0,4]], "pab_unknown": [[true,false],[false,true]],
            "samples": 50}"#,
    ))
    .unwrap();
    for (m, g) in [
        (Method::Ici, Guarantee::CommonInformation),
        (Method::Ei, Guarantee::None),
        (Method::Naive, Guarantee::None),
        (Method::Ci, Guarantee::Conservative),
        (Method::Sdp, Guarantee::Relaxation),
    ] {
        assert_eq!(a.response(m).unwrap().guarantee(), g, "{m}");
    }
    assert!((a.response(Method::Naive).unwrap().trace - (0.75 + 0.8)).abs() < 1e-12);
    let coin = |m| a.rule(m).unwrap().coin.unwrap();
    let margin = |m| a.rule(m).unwrap().margin.unwrap();
    for r in &a.rules {
        let (name, margin, coin) = (r.method, r.margin.unwrap(), r.coin.unwrap());
        assert!(coin.median <= coin.max, "{name}");
        if margin.abs() > 1e-9 {
            assert_eq!(
                margin < 0.0,
                coin.max > 1.0,
                "{name}: margin {margin}, COIN {coin:?}"
            );
        }
    }
    assert!(coin(Method::Ci).max < 1.0 && coin(Method::Nmci).max <= 1.0 + 1e-9);
    assert!(coin(Method::Naive).max > 1.0 && margin(Method::Naive) < 0.0);
    // The SDP's bound touches the region: COIN at most 1 up to solver tolerance.
    assert!(coin(Method::Sdp).max <= 1.0 + 1e-6);
    // No region, no COIN.
    let none = explore(&request(
        r#"{"pa": [[2,0],[0,2]], "pb": [[1,0],[0,1]], "region_samples": 0}"#,
    ))
    .unwrap();
    assert!(none
        .rules
        .iter()
        .all(|r| r.coin.is_none() && r.margin.is_none()));
}

#[test]
fn the_certified_rule_in_the_explorer() {
    // 2-D, one known zero: the certified rule is below nmCI, conservative over the region,
    // and closes the bracket from above.
    let a = explore(&request(
        r#"{"pa": [[2.7, -1.5], [-1.5, 1.25]], "pb": [[3.75, 0.05], [0.05, 4.1]],
            "pab_unknown": [[true, true], [false, true]], "sampler": "hit_and_run"}"#,
    ))
    .unwrap();
    let certified = a.rule(Method::Certified).unwrap();
    let cert = certified.response.as_ref().expect("certified");
    assert!(cert.trace < a.response(Method::Nmci).unwrap().trace - 1e-3);
    assert!(certified.margin.unwrap() >= -1e-12 * cert.trace);
    assert!(certified.coin.unwrap().max <= 1.0 + 1e-12);
    let gap = a.gap.clone().unwrap();
    assert_eq!(gap.upper_rule, Method::Certified);
    // The upper end is the certified trace rounded up: never below it, by at most rounding.
    assert!(gap.upper >= cert.trace && gap.upper <= cert.trace * (1.0 + 1e-14));
    assert_eq!(Some(gap.upper), cert.upper_bound());
    // A 5-state block is beyond the explorer's limit: said, not silently skipped.
    let eye = "[[1,0,0,0,0],[0,1,0,0,0],[0,0,1,0,0],[0,0,0,1,0],[0,0,0,0,1]]";
    let a = explore(&request(&format!(
        r#"{{"pa": {eye}, "pb": {eye}, "samples": 20, "region_samples": 0, "sampler": "hit_and_run"}}"#
    )))
    .unwrap();
    let certified = a.rule(Method::Certified).unwrap();
    assert!(certified.response.is_none());
    assert!(certified
        .error
        .as_ref()
        .unwrap()
        .contains("at most 4 states"));
    assert_ne!(a.gap.unwrap().upper_rule, Method::Certified);
}

#[test]
fn the_two_block_preset_is_certified_by_ci_without_a_solve() {
    // The page's two-block preset (www/state.js): each 2 × 2 cross block wholly unknown, so
    // each block takes CI's proven bound (one certificate for every direction, no sectors, no
    // iterations) and the certified trace is nmCI's up to rounding.
    let a = explore(&request(
        r#"{"pa": [[3, 0.5, 0, 0], [0.5, 1, 0, 0], [0, 0, 1, 0.2], [0, 0, 0.2, 2]],
            "pb": [[1, -0.3, 0, 0], [-0.3, 2, 0, 0], [0, 0, 4, 1], [0, 0, 1, 2]],
            "pab_unknown": [[true, true, false, false], [true, true, false, false],
                            [false, false, true, true], [false, false, true, true]]}"#,
    ))
    .unwrap();
    let certs = a.gap.clone().unwrap().certificates.unwrap();
    assert_eq!((certs.levels, certs.sectors), (vec![1, 1], vec![0, 0]));
    let cert = a.response(Method::Certified).unwrap();
    match &cert.details {
        Details::Certified(d) => assert_eq!(d.iterations, 0),
        other => panic!("not the certified rule's details: {other:?}"),
    }
    let nm = a.response(Method::Nmci).unwrap().trace;
    assert!(cert.trace >= nm * (1.0 - 1e-12) && cert.trace <= nm * (1.0 + 1e-14));
}

#[test]
fn the_memo_reuses_blocks_certified_before_and_changes_no_number() {
    common::memo::memo_sequence_matches_fresh_analyses();
}

#[test]
fn the_second_stage_proves_three_state_brackets_the_page_leaves_open() {
    // Three states, the anti-diagonal of P_ab known zero: one block, which nmCI cannot split.
    // The page's analysis (200 samples) leaves the bracket open by percent; the second stage
    // (`prove`: the cutting planes at their default tolerance, and their own rule proven)
    // narrows it by more than a thousand times, and closes it to 10⁻⁶ on these three. Both
    // brackets are proven, so they must overlap. On the third, a cone of the own rule's proof
    // the solver fails on must be cut, not left whole (`certify_rule`).
    let mut r = rng(44);
    let mut own = 0;
    for _ in 0..3 {
        let rows = |m: &DMatrix<f64>| serde_json::to_string(&common::rows(m)).unwrap();
        let (pa, pb) = (random_spd(3, &mut r), random_spd(3, &mut r));
        let req = request(&format!(
            r#"{{"pa": {}, "pb": {}, "pab_unknown": [[true,true,false],[true,false,true],[false,true,true]], "samples": 200, "sampler": "auto", "region_samples": 0}}"#,
            rows(&pa),
            rows(&pb)
        ));
        let first = explore(&req).unwrap().gap.unwrap();
        let proof = prove(&req).unwrap().unwrap();
        assert!(first.relative > 1e-2, "{first:?}");
        assert!(proof.gap.lower <= first.upper && first.lower <= proof.gap.upper);
        assert!(
            proof.gap.relative < first.relative * 1e-3,
            "{proof:?} {first:?}"
        );
        assert!(proof.gap.closed, "{proof:?}");
        assert_eq!(proof.gap.closed, proof.gap.relative <= 1e-6);
        own += proof.own_rule_proven as usize;
        if proof.own_rule_proven {
            assert_eq!(proof.gap.certificates.as_ref().unwrap().levels, vec![1]);
        }
    }
    assert!(own >= 1);
}

#[test]
fn the_second_stage_refuses_what_the_cutting_planes_refuse() {
    // The explorer's options that sdp_cuts does not take are left out, not refused...
    let ok = request(
        r#"{"pa": [[3,0],[0,1]], "pb": [[1,0],[0,4]], "pab_unknown": [[true,false],[false,true]], "samples": 50, "criterion": "logdet", "sampler": "hit_and_run"}"#,
    );
    assert!(prove(&ok).unwrap().unwrap().gap.closed);
    // ...while bad values of the ones it takes are typed errors naming the field.
    let bad = request(r#"{"pa": [[3,0],[0,1]], "pb": [[1,0],[0,4]], "time_limit": -1}"#);
    assert_eq!(
        prove(&bad).unwrap_err().field().as_deref(),
        Some("time_limit")
    );
}
