//! The rejection sampler: admissibility, known zeros, seeding, acceptance, budget.

use crate::common;

use common::*;
use nalgebra::DMatrix;
use nmci::{check::*, contract::*, explore::*, rules::*, sample::*, structure::*, *};

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
    // A budget with some acceptances (about 4 in 10 000): the error reports them and their rate.
    let err = sample_cross_covariances(&p, 20, 1, SamplerSettings::rejection(10_000)).unwrap_err();
    match &err {
        SampleError::BudgetExhausted {
            accepted,
            requested,
            trials,
            rate,
        } => {
            assert_eq!((*requested, *trials), (20, 10_000));
            assert!(*accepted > 0 && *accepted < 20, "{accepted}");
            assert_eq!(*rate, *accepted as f64 / 10_000.0);
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(err.to_string().contains("raise max_trials"));
    assert!(matches!(
        sample_cross_covariances(&p, 1, 1, SamplerSettings::rejection(0)),
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

/// Correlation of a cross-covariance sample: `C_ij = P_ab[i,j] / √(P_a[i,i] P_b[j,j])`.
fn correlation(p: &FusionProblem, s: &nalgebra::DMatrix<f64>, i: usize, j: usize) -> f64 {
    s[(i, j)] / (p.P_a[(i, i)] * p.P_b[(j, j)]).sqrt()
}

fn admissible(p: &FusionProblem, s: &nalgebra::DMatrix<f64>) -> bool {
    let n = p.dim();
    let zeros =
        (0..n).all(|i| (0..n).all(|j| p.cross_pattern.is_unknown(i, j) || s[(i, j)] == 0.0));
    zeros && nalgebra::Cholesky::new(p.joint_covariance(s)).is_some()
}

/// `count` samples (seed `seed`) from the paper's rejection sampler and from hit-and-run
/// (two sweeps between samples).
fn both_samplers(p: &FusionProblem, count: usize, seed: u64) -> (CrossSamples, CrossSamples) {
    let rejection = sample_cross_covariances(p, count, seed, SamplerSettings::default()).unwrap();
    let chain = sample_cross_covariances(
        p,
        count,
        seed,
        SamplerSettings {
            sweeps_per_sample: 2,
            ..SamplerSettings::hit_and_run()
        },
    )
    .unwrap();
    (rejection, chain)
}

/// The histograms of correlation `C_ij` over 10 bins of [−1, 1] agree bin by bin within `tol`
/// (fractions of the samples) between the rejection sampler's and hit-and-run's samples.
fn same_histogram(
    p: &FusionProblem,
    rejection: &CrossSamples,
    chain: &CrossSamples,
    i: usize,
    j: usize,
    tol: f64,
) {
    let histogram = |s: &CrossSamples| {
        let mut h = [0.0; 10];
        for c in &s.cross {
            let v = correlation(p, c, i, j);
            h[(((v + 1.0) / 0.2) as usize).min(9)] += 1.0 / s.cross.len() as f64;
        }
        h
    };
    let (a, b) = (histogram(rejection), histogram(chain));
    for k in 0..10 {
        assert!(
            (a[k] - b[k]).abs() < tol,
            "C_{i}{j} bin {k}: rejection {:.4} vs hit-and-run {:.4}",
            a[k],
            b[k]
        );
    }
}

#[test]
fn hit_and_run_samples_are_admissible_at_n_14_where_rejection_gets_none() {
    let mut r = rng(14);
    let p = random_problem(14, CrossPattern::fully_unknown(14), &mut r);
    let rejection = sample_cross_covariances(&p, 1, 1, SamplerSettings::rejection(200_000));
    assert!(matches!(
        rejection,
        Err(SampleError::BudgetExhausted { accepted: 0, .. })
    ));
    let s = sample_cross_covariances(&p, 300, 1, SamplerSettings::hit_and_run()).unwrap();
    assert_eq!(s.len(), 300);
    assert!(s.cross.iter().all(|c| admissible(&p, c)));
    // Steps = (burn-in + samples) sweeps over the 196 free entries.
    assert_eq!(s.trials, (50 + 300) * 196);
    // Not stuck near the start: the correlations spread over the set.
    let spread = s
        .cross
        .iter()
        .map(|c| correlation(&p, c, 3, 5))
        .fold(0.0_f64, |m, v| m.max(v.abs()));
    assert!(spread > 0.05, "max |C_35| = {spread}");
    // Patterns with known zeros: zeros respected, every sample admissible.
    for prob in [0.2, 0.5] {
        let p = random_problem(8, random_pattern(8, prob, &mut r), &mut r);
        let s = sample_cross_covariances(&p, 100, 2, SamplerSettings::hit_and_run()).unwrap();
        assert!(s.cross.iter().all(|c| admissible(&p, c)));
    }
}

#[test]
fn hit_and_run_and_rejection_cover_the_same_set_in_2d() {
    let mut r = rng(2);
    let p = random_problem(2, CrossPattern::fully_unknown(2), &mut r);
    let (rejection, chain) = both_samplers(&p, 20_000, 5);
    // Histograms of each correlation entry over 10 bins of [−1, 1]: the same law.
    for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
        same_histogram(&p, &rejection, &chain, i, j, 0.015);
    }
    // And a joint feature: how often two correlations share a sign.
    let same_sign = |s: &CrossSamples| {
        s.cross
            .iter()
            .filter(|c| correlation(&p, c, 0, 0) * correlation(&p, c, 1, 1) > 0.0)
            .count() as f64
            / s.cross.len() as f64
    };
    assert!((same_sign(&rejection) - same_sign(&chain)).abs() < 0.02);
}

#[test]
fn hit_and_run_is_reproducible_and_validated() {
    let mut r = rng(3);
    let p = random_problem(4, CrossPattern::fully_unknown(4), &mut r);
    let a = sample_cross_covariances(&p, 20, 9, SamplerSettings::hit_and_run()).unwrap();
    let b = sample_cross_covariances(&p, 20, 9, SamplerSettings::hit_and_run()).unwrap();
    let c = sample_cross_covariances(&p, 20, 10, SamplerSettings::hit_and_run()).unwrap();
    assert_eq!(a, b);
    assert_ne!(a.cross, c.cross);
    let bad = SamplerSettings {
        sweeps_per_sample: 0,
        ..SamplerSettings::hit_and_run()
    };
    assert_eq!(
        sample_cross_covariances(&p, 1, 1, bad)
            .unwrap_err()
            .to_string(),
        "invalid sampler setting: sweeps_per_sample must be at least 1"
    );
    // No free entry: the admissible set is P_ab = 0.
    let none = random_problem(3, CrossPattern::independent(3), &mut r);
    let s = sample_cross_covariances(&none, 4, 1, SamplerSettings::hit_and_run()).unwrap();
    assert!(s.cross.iter().all(|c| c.iter().all(|v| *v == 0.0)));
}

/// Hit-and-run has the paper's law at any dimension. An exact case at n = 6: diagonal `P_a`,
/// `P_b` and a diagonal pattern make the admissible set a box, `|P_ab[i,i]| ≤ √(a_i b_i)`, so
/// under the paper's law (uniform correlations, rejected when not PSD) the six correlations
/// are independent U[−1, 1]. 10 000 independent chains (one sample each, seeds 0..10 000, after
/// the default burn-in) give i.i.d. draws; a Kolmogorov–Smirnov test per coordinate at level
/// 10⁻³ (critical value `√(ln(2/10⁻³)/2)/√N = 1.95/√N`) has a family-wise false-alarm rate
/// below 0.6 % over a random choice of seeds — here the seeds are fixed, so the test is
/// deterministic.
#[test]
fn hit_and_run_has_the_exact_law_on_a_six_dimensional_box() {
    let (a, b) = (
        [3.0, 1.0, 2.0, 0.5, 4.0, 1.5],
        [1.0, 4.0, 0.25, 2.0, 1.0, 3.0],
    );
    let p = FusionProblem::from_covariances(
        nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(&a)),
        nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(&b)),
        CrossPattern::from_matrix(DMatrix::from_fn(6, 6, |i, j| i == j)).unwrap(),
    )
    .unwrap();
    let draws = 10_000;
    let mut rho: Vec<Vec<f64>> = (0..6).map(|_| Vec::with_capacity(draws)).collect();
    for seed in 0..draws as u64 {
        let s = sample_cross_covariances(&p, 1, seed, SamplerSettings::hit_and_run()).unwrap();
        for (i, r) in rho.iter_mut().enumerate() {
            r.push(correlation(&p, &s.cross[0], i, i));
        }
    }
    let critical = ((2.0f64 / 1e-3).ln() / 2.0).sqrt() / (draws as f64).sqrt();
    for (i, r) in rho.iter_mut().enumerate() {
        r.sort_by(f64::total_cmp);
        // D = sup |F_N − F| with F(x) = (x + 1)/2 on [−1, 1].
        let d = r
            .iter()
            .enumerate()
            .map(|(k, &x)| {
                let f = (x + 1.0) / 2.0;
                (f - k as f64 / draws as f64).max((k + 1) as f64 / draws as f64 - f)
            })
            .fold(0.0, f64::max);
        assert!(d < critical, "coordinate {i}: KS distance {d} ≥ {critical}");
    }
}

/// The same law with known zeros in 3-D: hit-and-run against the paper's rejection sampler,
/// histograms of every free correlation over 10 bins of [−1, 1].
#[test]
fn hit_and_run_and_rejection_agree_in_3d_with_known_zeros() {
    let mut r = rng(33);
    let pattern = CrossPattern::from_matrix(nalgebra::DMatrix::from_row_slice(
        3,
        3,
        &[true, false, true, true, true, false, false, true, true],
    ))
    .unwrap();
    let p = random_problem(3, pattern, &mut r);
    let (rejection, chain) = both_samplers(&p, 10_000, 6);
    for i in 0..3 {
        for j in 0..3 {
            if !p.cross_pattern.is_unknown(i, j) {
                assert!(chain.cross.iter().all(|c| c[(i, j)] == 0.0));
                continue;
            }
            same_histogram(&p, &rejection, &chain, i, j, 0.02);
        }
    }
}

/// `SamplerKind::Auto` with `max_trials`.
fn auto(max_trials: u64) -> SamplerSettings {
    SamplerSettings {
        kind: SamplerKind::Auto,
        ..SamplerSettings::rejection(max_trials)
    }
}

#[test]
fn auto_takes_the_rejection_sampler_where_it_works_and_draws_its_samples() {
    // The paper's example accepts every proposal: the pilot stops at AUTO_MIN_ACCEPTED.
    let p = paper_example();
    for seed in [0, 7] {
        let chosen = sample_cross_covariances(&p, 200, seed, auto(2_000_000)).unwrap();
        let alone = sample_cross_covariances(&p, 200, seed, SamplerSettings::default()).unwrap();
        assert_eq!(
            chosen.cross, alone.cross,
            "the rejection sampler's own samples"
        );
        assert_eq!(chosen.trials, alone.trials);
        assert_eq!(
            chosen.auto,
            Some(AutoChoice {
                kind: SamplerKind::Rejection,
                pilot_trials: AUTO_MIN_ACCEPTED,
                pilot_accepted: AUTO_MIN_ACCEPTED,
                fell_back: false,
            })
        );
        assert_eq!(alone.auto, None);
    }
}

#[test]
fn auto_takes_hit_and_run_where_the_rejection_sampler_dies_and_draws_its_samples() {
    // Fully unknown P_ab: acceptance ≈ 4·10⁻⁴ at n = 4 (the pilot sees a handful in 2000
    // proposals at most), none at n = 6.
    for (n, seed) in [(4, 3), (6, 5)] {
        let P = DMatrix::<f64>::identity(n, n);
        let p =
            FusionProblem::from_covariances(P.clone(), P, CrossPattern::fully_unknown(n)).unwrap();
        let chosen = sample_cross_covariances(&p, 200, seed, auto(200_000)).unwrap();
        let alone =
            sample_cross_covariances(&p, 200, seed, SamplerSettings::hit_and_run()).unwrap();
        assert_eq!(
            chosen.cross, alone.cross,
            "n = {n}: hit-and-run's own samples"
        );
        let choice = chosen.auto.unwrap();
        assert_eq!(choice.kind, SamplerKind::HitAndRun);
        assert_eq!(choice.pilot_trials, AUTO_PILOT_TRIALS);
        assert!(choice.pilot_accepted < AUTO_MIN_ACCEPTED, "{choice:?}");
        assert!(!choice.fell_back);
        assert!(chosen.cross.iter().all(|s| admissible(&p, s)));
    }
}

#[test]
fn auto_chooses_rejection_exactly_when_the_expected_trials_fit_a_quarter_of_the_budget() {
    // Acceptance 1 (the paper's example), 200 samples: after 10 of 10 accepted the expected
    // 200 trials fit a quarter of the budget iff max_trials ≥ 800. Below, the pilot runs to its
    // end (the budget, < 2000) and the estimate never improves.
    let p = paper_example();
    let at = |max_trials| {
        sample_cross_covariances(&p, 200, 1, auto(max_trials))
            .unwrap()
            .auto
            .unwrap()
    };
    let yes = at(800);
    assert_eq!((yes.kind, yes.pilot_trials), (SamplerKind::Rejection, 10));
    let no = at(799);
    assert_eq!(
        (no.kind, no.pilot_trials, no.pilot_accepted),
        (SamplerKind::HitAndRun, 799, 799)
    );
    // Fewer than AUTO_MIN_ACCEPTED acceptances never choose the rejection sampler, even when
    // the budget would allow it: a pilot capped at 9 proposals by the budget.
    let few = sample_cross_covariances(&p, 1, 1, auto(9))
        .unwrap()
        .auto
        .unwrap();
    assert_eq!((few.kind, few.pilot_trials), (SamplerKind::HitAndRun, 9));
    // Settings are still checked.
    assert!(matches!(
        sample_cross_covariances(&p, 1, 1, auto(0)),
        Err(SampleError::InvalidSettings(_))
    ));
}

#[test]
fn auto_from_a_callers_generator_is_reproducible() {
    let p = paper_example();
    let draw =
        |seed| sample_cross_covariances_with(&p, 50, &mut rng(seed), auto(2_000_000)).unwrap();
    let (a, b, c) = (draw(4), draw(4), draw(5));
    assert_eq!(a, b);
    assert_ne!(a.cross, c.cross);
    assert_eq!(a.auto.unwrap().kind, SamplerKind::Rejection);
}

#[test]
fn the_contract_and_the_explorer_report_autos_choice() {
    let unknown = vec![vec![true; 4]; 4];
    // A fully unknown 4-D P_ab, where the rejection sampler dies.
    let p = |v: f64| -> Vec<Vec<f64>> {
        (0..4)
            .map(|i| {
                (0..4)
                    .map(|j| if i == j { 1.0 + v * i as f64 } else { 0.1 })
                    .collect()
            })
            .collect()
    };
    let request = serde_json::json!({
        "pa": p(0.5), "pb": p(0.3), "pab_unknown": unknown,
        "method": "sdp", "samples": 60, "sampler": "auto", "max_trials": 200000,
    });
    let response: serde_json::Value =
        serde_json::from_str(&fuse_json(&request.to_string()).unwrap()).unwrap();
    assert_eq!(response["sampler_choice"]["kind"], "hit_and_run");
    assert_eq!(
        response["sampler_choice"]["pilot_trials"],
        AUTO_PILOT_TRIALS
    );
    assert_eq!(response["sampler_choice"]["fell_back"], false);
    // Without `auto`, no choice is reported.
    let plain = serde_json::json!({
        "pa": p(0.5), "pb": p(0.3), "pab_unknown": unknown,
        "method": "sdp", "samples": 60, "sampler": "hit_and_run",
    });
    let plain: serde_json::Value =
        serde_json::from_str(&fuse_json(&plain.to_string()).unwrap()).unwrap();
    assert!(plain.get("sampler_choice").is_none());
    let explored = explore(
        &serde_json::from_value::<ExploreRequest>(serde_json::json!({
            "pa": p(0.5), "pb": p(0.3), "pab_unknown": unknown,
            "samples": 60, "region_samples": 100, "sampler": "auto",
        }))
        .unwrap(),
    )
    .unwrap();
    assert_eq!(explored.region_count, 100);
    assert_eq!(
        explored.region_sampler_choice.map(|c| c.kind),
        Some(SamplerKind::HitAndRun)
    );
    let sdp = explored.response(Method::Sdp).expect("the SDP is computed");
    let Details::Sdp(sdp) = &sdp.details else {
        panic!("{:?}", sdp.details)
    };
    assert_eq!(
        sdp.sampler_choice.map(|c| c.kind),
        Some(SamplerKind::HitAndRun)
    );
}

#[test]
fn the_pilot_draws_its_own_proposals_per_seed() {
    // The pilot has a generator of its own, seeded from the sampler's seed: its counts vary
    // with the seed (a fixed pilot seed would give every seed the same pilot), and its
    // proposals are not the chosen sampler's (the pilot at seed s is not the rejection
    // sampler's own first proposals at s).
    let mut r = rng(3);
    let p = random_problem(3, CrossPattern::fully_unknown(3), &mut r);
    let pilots: Vec<(u64, u64)> = (0..12)
        .map(|seed| {
            let c = sample_cross_covariances(&p, 50, seed, auto(2_000_000))
                .unwrap()
                .auto
                .unwrap();
            (c.pilot_trials, c.pilot_accepted)
        })
        .collect();
    let distinct: std::collections::BTreeSet<_> = pilots.iter().collect();
    assert!(distinct.len() >= 6, "pilots {pilots:?}");
    // The pilot stops at its 10th acceptance; the rejection sampler alone at the same seed
    // needs a different number of proposals for its first 10 samples on most seeds.
    let differ = (0..12u64)
        .filter(|&seed| {
            let alone = sample_cross_covariances(
                &p,
                AUTO_MIN_ACCEPTED as usize,
                seed,
                SamplerSettings::default(),
            )
            .unwrap();
            (alone.trials, AUTO_MIN_ACCEPTED) != pilots[seed as usize]
        })
        .count();
    assert!(differ >= 6, "{differ} of 12 seeds");
}

#[test]
fn sample_sets_say_whether_they_are_empty() {
    let p = paper_example();
    let none = sample_cross_covariances(&p, 0, 0, SamplerSettings::default()).unwrap();
    assert!(none.is_empty());
    assert_eq!(none.cross.len(), 0);
    let some = sample_cross_covariances(&p, 3, 0, SamplerSettings::default()).unwrap();
    assert!(!some.is_empty() && some.len() == 3);
}

#[test]
fn hit_and_run_thins_by_sweeps_per_sample_after_its_burn_in() {
    // Every step is one free entry of one sweep: count samples spaced k sweeps apart after b
    // burn-in sweeps take exactly |free| · (b + k · count) steps.
    let p = paper_example(); // two free entries (the diagonal of P_ab)
    for (b, k, count) in [(50, 1, 10), (50, 3, 10), (7, 4, 5)] {
        let settings = SamplerSettings {
            sweeps_per_sample: k,
            burn_in_sweeps: b,
            ..SamplerSettings::hit_and_run()
        };
        let s = sample_cross_covariances(&p, count, 2, settings).unwrap();
        assert_eq!(s.len(), count);
        assert_eq!(s.trials, 2 * (b + k * count) as u64, "b {b}, k {k}");
    }
}

/// In one dimension hit-and-run is the textbook chain, replayed here step by step from the
/// same generator: from the correlation `x`, the chord of admissible moves is
/// `(−1 − x, 1 − x)` and the next state is `x + t` with `t` uniform on it; every sweep after
/// the burn-in is a sample `P_ab = x σ_a σ_b`. Checks the state and its sign (the admissible
/// set and the target law are symmetric under `P_ab → −P_ab`, so a sampler reporting the
/// negated state passes every law test).
#[test]
fn hit_and_run_in_one_dimension_is_the_textbook_chain() {
    use rand::{Rng, SeedableRng};
    let p = FusionProblem::from_covariances(
        DMatrix::from_element(1, 1, 4.0),
        DMatrix::from_element(1, 1, 9.0),
        CrossPattern::fully_unknown(1),
    )
    .unwrap();
    let settings = SamplerSettings {
        burn_in_sweeps: 3,
        sweeps_per_sample: 2,
        ..SamplerSettings::hit_and_run()
    };
    let count = 20;
    let drawn = sample_cross_covariances(&p, count, 5, settings).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let (mut x, mut expected) = (0.0_f64, Vec::new());
    for sweep in 1.. {
        let t: f64 = rng.random_range(-1.0 - x..1.0 - x);
        x += t;
        if sweep > 3 && (sweep - 3) % 2 == 0 {
            expected.push(x * 2.0 * 3.0);
            if expected.len() == count {
                break;
            }
        }
    }
    let got: Vec<f64> = drawn.cross.iter().map(|m| m[(0, 0)]).collect();
    for (g, e) in got.iter().zip(&expected) {
        assert!((g - e).abs() <= 1e-12, "{got:?}\nvs\n{expected:?}");
    }
    assert_eq!(got.len(), count);
    assert!(expected.iter().any(|&e| e > 0.5) && expected.iter().any(|&e| e < -0.5));
}

/// One call draws at most `MAX_SAMPLE_COUNT` samples and `MAX_SAMPLE_ENTRIES` entries, refused
/// before anything is allocated: a count of 10⁹ aborted the process (and a Python interpreter
/// with it) on a 40 GB allocation. Both samplers, and the generic entry point, check it.
#[test]
fn the_count_of_one_call_is_limited_before_allocating() {
    let p = paper_example();
    for settings in [SamplerSettings::default(), SamplerSettings::hit_and_run()] {
        let e = sample_cross_covariances(&p, 1_000_000_000, 1, settings).unwrap_err();
        assert!(
            e.to_string()
                .contains("count 1000000000 is above the limit of 1000000 samples per call"),
            "{e}"
        );
        let mut r = rng(2);
        let e =
            sample_cross_covariances_with(&p, MAX_SAMPLE_COUNT + 1, &mut r, settings).unwrap_err();
        assert!(matches!(e, SampleError::InvalidSettings(_)), "{e}");
    }
    // 12 states: 694 445 samples are 100 000 080 entries, one past the limit.
    let big = random_problem(12, CrossPattern::fully_unknown(12), &mut rng(3));
    let count = MAX_SAMPLE_ENTRIES / 144 + 1;
    let e = sample_cross_covariances(&big, count, 1, SamplerSettings::default()).unwrap_err();
    assert!(
        e.to_string().contains(&format!(
            "count × n² = {count} × 144 entries is above the limit of {MAX_SAMPLE_ENTRIES}"
        )),
        "{e}"
    );
}
