//! ICI, EI and COIN against hand-derived values (derivations in each test).

use crate::common;

use common::*;
use nalgebra::{DMatrix, DVector};
use nmci::{check::*, rules::*, sample::*, structure::*, *};

/// ICI on P_a = diag(3, 1), P_b = diag(1, 4). Everything is diagonal, so with
/// Γ = ωP_a + (1−ω)P_b = diag(1 + 2ω, 4 − 3ω):
///   p₁(ω) = 1 / (1/3 + 1 − 1/(1 + 2ω)),  p₂(ω) = 1 / (1 + 1/4 − 1/(4 − 3ω)).
/// tr P = p₁ + p₂; at ω = 0 it is 3 + 1 = 4 (P = P_a), at ω = 1 it is 1 + 4 = 5 (P = P_b),
/// at ω = ½ it is 1.2 + 1.1765 = 2.3765: an interior minimum, found here by bisection on a
/// central-difference derivative of these two scalar formulas (independent of the library).
#[test]
fn ici_on_the_paper_matrices_matches_the_scalar_derivation() {
    let p1 = |w: f64| 1.0 / (4.0 / 3.0 - 1.0 / (1.0 + 2.0 * w));
    let p2 = |w: f64| 1.0 / (1.25 - 1.0 / (4.0 - 3.0 * w));
    let tr = |w: f64| p1(w) + p2(w);
    assert!((tr(0.5) - (1.2 + 1.0 / 0.85)).abs() < 1e-12);
    let (mut lo, mut hi) = (0.2, 0.8);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        let h = 1e-7;
        if tr(mid + h) - tr(mid - h) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let w = 0.5 * (lo + hi);
    let p = FusionProblem::new(
        DVector::from_vec(vec![1.0, 2.0]),
        diag(&[3.0, 1.0]),
        DVector::from_vec(vec![4.0, -1.0]),
        diag(&[1.0, 4.0]),
        CrossPattern::fully_unknown(2),
    )
    .unwrap();
    let ici = inverse_covariance_intersection(&p, Criterion::Trace).unwrap();
    assert!((ici.omega - w).abs() < 1e-6, "{} vs {w}", ici.omega);
    assert!(tr(ici.omega) <= tr(w) + 1e-14);
    // At the library's ω, P and the gains are the scalar formulas' values.
    let w = ici.omega;
    assert!((&ici.fused.P - diag(&[p1(w), p2(w)])).amax() < 1e-12);
    // Gains: K_a = P (P_a⁻¹ − ω Γ⁻¹) is diagonal too.
    let k1 = p1(w) * (1.0 / 3.0 - w / (1.0 + 2.0 * w));
    let k2 = p2(w) * (1.0 - w / (4.0 - 3.0 * w));
    assert!((&ici.fused.K_a - diag(&[k1, k2])).amax() < 1e-10);
    assert!((ici.fused.x[0] - (k1 * 1.0 + (1.0 - k1) * 4.0)).abs() < 1e-9);
    assert!((ici.fused.x[1] - (k2 * 2.0 - (1.0 - k2))).abs() < 1e-9);
    // Tighter than CI here (CI's optimum on the same pair).
    let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
    assert!(ici.fused.trace() < ci.fused.trace());
}

/// 1-D: p(ω) = 1/(1/a + 1/b − 1/(ωa + (1−ω)b)) is smallest where Γ = ωa + (1−ω)b is largest:
/// for a = 2 < b = 5 at ω = 0, giving P = a exactly (ICI takes the better estimate).
#[test]
fn ici_in_one_dimension_takes_the_better_estimate_exactly() {
    let p =
        FusionProblem::from_covariances(diag(&[2.0]), diag(&[5.0]), CrossPattern::fully_unknown(1))
            .unwrap();
    for criterion in [Criterion::Trace, Criterion::Logdet] {
        let ici = inverse_covariance_intersection(&p, criterion).unwrap();
        assert_eq!(ici.omega, 0.0);
        assert_eq!(ici.fused.P, diag(&[2.0]));
    }
}

/// Common information: estimate a fuses private information I_a with shared I_c
/// (P_a⁻¹ = I_a + I_c), estimate b fuses I_b with the same I_c; then P_ab = P_a I_c P_b.
/// ICI is conservative for every such pair (COIN ≤ 1), and never looser than CI's trace.
#[test]
fn ici_is_conservative_under_common_information_and_tighter_than_ci() {
    let mut r = rng(11);
    for n in [2usize, 3, 5] {
        for _ in 0..10 {
            let inv = |m: DMatrix<f64>| m.try_inverse().unwrap();
            let (I_a, I_b, I_c) = (
                random_spd(n, &mut r),
                random_spd(n, &mut r),
                random_spd(n, &mut r),
            );
            let P_a = inv(&I_a + &I_c);
            let P_b = inv(&I_b + &I_c);
            let P_ab = &P_a * &I_c * &P_b;
            let p =
                FusionProblem::from_covariances(P_a, P_b, CrossPattern::fully_unknown(n)).unwrap();
            for criterion in [Criterion::Trace, Criterion::Logdet] {
                let ici = inverse_covariance_intersection(&p, criterion).unwrap();
                let coin = fused_coin(&p, &ici.fused, &P_ab).unwrap();
                assert!(coin <= 1.0 + 1e-9, "n={n}: COIN {coin}");
                let ci = covariance_intersection(&p, criterion).unwrap();
                assert!(ici.fused.criterion(criterion) <= ci.fused.criterion(criterion) + 1e-9);
                let sum = &ici.fused.K_a + &ici.fused.K_b;
                assert!((sum - DMatrix::identity(n, n)).amax() < 1e-9);
            }
        }
    }
}

/// EI on P_a = [[2, 1], [1, 2]], P_b = 2I. P_b ∝ I, so the common principal axes are P_a's
/// eigenvectors u₁ = (1, 1)/√2 (variance 3 in a, 2 in b) and u₂ = (1, −1)/√2 (1 in a, 2 in b).
/// EI keeps the smaller variance per axis: P = 2 u₁u₁ᵀ + 1 u₂u₂ᵀ = [[1.5, 0.5], [0.5, 1.5]].
/// Mean, x_a = (1, 0), x_b = (0, 2): along u₁ b's coordinate 2/√2, along u₂ a's 1/√2, so
/// x = (1, 1) + (½, −½) = (1.5, 0.5).
#[test]
fn ei_matches_the_principal_axis_derivation() {
    let p = FusionProblem::new(
        DVector::from_vec(vec![1.0, 0.0]),
        DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0]),
        DVector::from_vec(vec![0.0, 2.0]),
        diag(&[2.0, 2.0]),
        CrossPattern::fully_unknown(2),
    )
    .unwrap();
    let ei = ellipsoidal_intersection(&p).unwrap();
    let expected = DMatrix::from_row_slice(2, 2, &[1.5, 0.5, 0.5, 1.5]);
    assert!((&ei.P - expected).amax() < 1e-12, "{}", ei.P);
    assert!(
        (ei.x[0] - 1.5).abs() < 1e-12 && (ei.x[1] - 0.5).abs() < 1e-12,
        "{}",
        ei.x
    );
}

/// EI is not a bound: on the paper's matrices with a fully unknown P_ab it returns
/// diag(1, 1), which CI (optimal for that case) cannot reach — some admissible P_ab breaks it.
#[test]
fn ei_is_not_conservative_for_a_fully_unknown_cross_covariance() {
    let p = FusionProblem::from_covariances(
        diag(&[3.0, 1.0]),
        diag(&[1.0, 4.0]),
        CrossPattern::fully_unknown(2),
    )
    .unwrap();
    let ei = ellipsoidal_intersection(&p).unwrap();
    assert!((&ei.P - diag(&[1.0, 1.0])).amax() < 1e-12);
    let samples = sample_cross_covariances(&p, 2000, 3, SamplerSettings::hit_and_run()).unwrap();
    assert!(worst_margin(&p, &ei, &samples.cross).unwrap() < -0.05);
    let worst_coin = samples
        .cross
        .iter()
        .map(|c| fused_coin(&p, &ei, c).unwrap())
        .fold(0.0, f64::max);
    assert!(worst_coin > 1.05, "{worst_coin}");
}

#[test]
fn coin_is_one_for_the_exact_covariance_and_below_one_when_inflated() {
    let mut r = rng(3);
    for n in [1usize, 3, 6] {
        let E = random_spd(n, &mut r);
        assert!((conservativeness_index(&E, &E).unwrap() - 1.0).abs() < 1e-10);
        let inflated = &E * 1.5 + DMatrix::identity(n, n) * 0.1;
        let coin = conservativeness_index(&inflated, &E).unwrap();
        assert!(coin < 1.0 / 1.5 + 1e-12 && coin > 0.0, "{coin}");
        let shrunk = &E * 0.8;
        assert!((conservativeness_index(&shrunk, &E).unwrap() - 1.25).abs() < 1e-10);
    }
    // Exact fusion with the true P_ab (the known-correlation optimum) has COIN 1.
    let p = paper_example();
    let P_ab = diag(&[0.5, -0.3]);
    let exact = known_correlation_fusion(&p, &P_ab).unwrap();
    assert!((fused_coin(&p, &exact, &P_ab).unwrap() - 1.0).abs() < 1e-10);
    let bad = conservativeness_index(&diag(&[1.0, -1.0]), &diag(&[1.0, 1.0])).unwrap_err();
    assert!(bad.to_string().contains("not positive definite"), "{bad}");
}

/// Bad input to the COIN is refused by name, as every covariance is; before, a NaN or infinite
/// `E` gave `Ok(NaN)` and an asymmetric one the index of its symmetric part. An overflow inside
/// (a tiny `P` against a huge `E`) is computed again at unit scale: the index below is
/// `−10³⁰⁸` exactly in real arithmetic (`L⁻¹ E L⁻ᵀ`'s entries, `2·10³⁰⁸`, overflow), and one
/// beyond the largest float is `+∞`, where it was NaN.
#[test]
fn the_coin_refuses_bad_input_by_name_and_survives_overflow() {
    let I = DMatrix::<f64>::identity(2, 2);
    let mut nan = I.clone();
    nan[(1, 0)] = f64::NAN;
    let e = conservativeness_index(&I, &nan).unwrap_err();
    assert_eq!(e.to_string(), "E has a non-finite entry at (1, 0)");
    let mut asym = I.clone();
    asym[(1, 0)] = 5.0;
    let e = conservativeness_index(&I, &asym).unwrap_err();
    assert!(e.to_string().starts_with("E is not symmetric"), "{e}");
    let e = conservativeness_index(&I, &DMatrix::identity(3, 3)).unwrap_err();
    assert!(matches!(e, InputError::SizeMismatch { .. }), "{e}");
    let e = conservativeness_index(&nan, &I).unwrap_err();
    assert_eq!(e.to_string(), "P has a non-finite entry at (1, 0)");

    let E = DMatrix::from_row_slice(2, 2, &[-2.0, 1.0, 1.0, -2.0]) * 1e298;
    let coin = conservativeness_index(&(&I * 1e-10), &E).unwrap();
    assert!((coin / -1e308 - 1.0).abs() < 1e-14, "{coin}");
    let coin = conservativeness_index(&(&I * 1e-300), &(&I * 1e300)).unwrap();
    assert_eq!(coin, f64::INFINITY);
    // The recomputation is exact: bit for bit the index of the same matrices scaled into range
    // by hand (P by a power of four), here with P's largest entry of odd binary exponent.
    let mut r = rng(12);
    for n in [2, 3, 5] {
        let P = random_spd(n, &mut r) * 2e-10;
        // Eigenvalues −1 and −(n + 1) times 10²⁹⁸: L⁻¹ E L⁻ᵀ overflows, its index does not.
        let E = (DMatrix::identity(n, n) * -(n as f64 + 1.0) + DMatrix::from_element(n, n, 1.0))
            * 1e298;
        let by_hand = conservativeness_index(&(&P * 2f64.powi(40)), &(&E * 2f64.powi(-1000)))
            .unwrap()
            * 2f64.powi(520)
            * 2f64.powi(520);
        let coin = conservativeness_index(&P, &E).unwrap();
        assert!(coin.is_finite() && coin < -1e300, "n = {n}: {coin}");
        assert_eq!(
            coin.to_bits(),
            by_hand.to_bits(),
            "n = {n}: {coin} vs {by_hand}"
        );
    }
    // Scaling P by a power of four and E by a power of two scales the index exactly, bit for
    // bit (what the recomputation at unit scale relies on), in closed form (n = 2) and by the
    // QR iteration (n = 4).
    let mut r = rng(8);
    for n in [2, 4] {
        let P = random_spd(n, &mut r);
        let E = random_spd(n, &mut r) - DMatrix::identity(n, n) * 0.5;
        let coin = conservativeness_index(&P, &E).unwrap();
        let scaled = conservativeness_index(&(&P * 2f64.powi(-200)), &(&E * 2f64.powi(301)));
        assert_eq!(scaled.unwrap(), coin * 2f64.powi(501), "n = {n}");
    }
}

/// The analysis functions take the caller's matrices: a wrong size or a non-finite entry is an
/// error naming it (each of these panicked in a matrix product before).
#[test]
fn the_analysis_functions_refuse_a_wrong_matrix_by_name() {
    let p = paper_example();
    let ci = covariance_intersection(&p, Criterion::Trace).unwrap().fused;
    let good = diag(&[0.5, -0.3]);
    let big = DMatrix::<f64>::zeros(3, 3);
    let mut nan = good.clone();
    nan[(0, 1)] = f64::NAN;
    let msg = |e: InputError| e.to_string();
    assert_eq!(
        msg(known_correlation_fusion(&p, &big).unwrap_err()),
        "P_ab has size 3, expected 2 (the size of P_a)"
    );
    assert_eq!(
        msg(conservativeness_margin(&p, &ci, &nan).unwrap_err()),
        "P_ab has a non-finite entry at (0, 1)"
    );
    assert_eq!(
        msg(fused_coin(&p, &ci, &DMatrix::zeros(2, 3)).unwrap_err()),
        "P_ab is not square (2×3)"
    );
    assert_eq!(
        msg(worst_margin(&p, &ci, &[good.clone(), big.clone()]).unwrap_err()),
        "cross[1] has size 3, expected 2 (the size of P_a)"
    );
    assert_eq!(
        msg(fused_coins(&p, &ci, std::slice::from_ref(&nan)).unwrap_err()),
        "cross[0] has a non-finite entry at (0, 1)"
    );
    let mut wrong = ci.clone();
    wrong.K_a = big.clone();
    assert_eq!(
        msg(worst_margin(&p, &wrong, std::slice::from_ref(&good)).unwrap_err()),
        "K_a has size 3, expected 2 (the size of P_a)"
    );
    let mut wrong = ci.clone();
    wrong.x = DVector::zeros(1);
    assert!(msg(fused_coin(&p, &wrong, &good).unwrap_err()).starts_with("x has size 1"));
    assert_eq!(
        msg(fused_error_covariance(&p, &ci.K_a, &big, &good).unwrap_err()),
        "K_b has size 3, expected 2 (the size of P_a)"
    );
    // Good input still gives the margin.
    assert!(worst_margin(&p, &ci, std::slice::from_ref(&good)).unwrap() >= 0.0);
}

/// Over many cross-covariances, `worst_margin` and `fused_coins` compute the `P_ab`-free
/// parts once; they agree with the per-sample `conservativeness_margin` and `fused_coin`
/// (summed in the textbook order) to rounding, for n = 1, 2, 3, 5 and rules whose gains are
/// not those of CI (the SDP's, EI's).
#[test]
fn region_margins_and_coins_match_the_per_sample_ones() {
    let mut r = rng(31);
    for n in [1, 2, 3, 5] {
        let p = random_problem(n, random_pattern(n, 0.7, &mut r), &mut r);
        let cross = sample_cross_covariances(&p, 60, 3, SamplerSettings::hit_and_run())
            .unwrap()
            .cross;
        let rules = [
            covariance_intersection(&p, Criterion::Trace).unwrap().fused,
            ellipsoidal_intersection(&p).unwrap(),
            naive_fusion(&p),
        ];
        for fused in &rules {
            let scale = fused.P.amax();
            let each: Vec<f64> = cross
                .iter()
                .map(|c| conservativeness_margin(&p, fused, c).unwrap())
                .collect();
            let worst = each.iter().copied().fold(f64::INFINITY, f64::min);
            let got = worst_margin(&p, fused, &cross).unwrap();
            assert!(
                (got - worst).abs() <= 1e-12 * scale,
                "n {n}: {got} vs {worst}"
            );
            let coins = fused_coins(&p, fused, &cross).unwrap();
            for (c, P_ab) in coins.iter().zip(&cross) {
                let one = fused_coin(&p, fused, P_ab).unwrap();
                assert!(
                    (c - one).abs() <= 1e-11 * one.max(1.0),
                    "n {n}: {c} vs {one}"
                );
            }
            assert_eq!(coins.len(), cross.len());
        }
    }
    let p = random_problem(2, CrossPattern::fully_unknown(2), &mut r);
    assert_eq!(
        worst_margin(&p, &naive_fusion(&p), &[]).unwrap(),
        f64::INFINITY
    );
}

/// With independent blocks (here interleaved: {0, 2, 4} and {1, 3}, and {0, 3}, {1, 4}, {2, 5})
/// and a rule that respects them, `worst_margin` and `fused_coins` work block by block (module
/// docs of `fusion::check`); they still agree with the per-sample textbook computations on the
/// whole state. So do they when a gain couples two blocks (one off-block entry of `K_a` and
/// `K_b`): then they work on the whole state.
#[test]
fn region_margins_and_coins_of_independent_blocks_match_the_per_sample_ones() {
    let mut r = rng(37);
    for groups in [
        vec![vec![0, 2, 4], vec![1, 3]],
        vec![vec![0, 3], vec![1, 4], vec![2, 5]],
    ] {
        let n = groups.iter().map(Vec::len).sum();
        let group_of = |i: usize| groups.iter().position(|g| g.contains(&i)).unwrap();
        let pattern = CrossPattern::from_fn(n, |i, j| group_of(i) == group_of(j));
        let p = FusionProblem::from_covariances(
            block_spd(n, &groups, &mut r),
            block_spd(n, &groups, &mut r),
            pattern,
        )
        .unwrap();
        assert_eq!(
            independent_blocks(&p.P_a, &p.P_b, &p.cross_pattern).len(),
            groups.len()
        );
        let cross = sample_cross_covariances(&p, 60, 5, SamplerSettings::hit_and_run())
            .unwrap()
            .cross;
        let coupled = |mut f: Fused| {
            let (i, j) = (groups[0][0], groups[1][0]);
            f.K_a[(i, j)] += 0.05;
            f.K_b[(i, j)] -= 0.05;
            f
        };
        let ci = covariance_intersection(&p, Criterion::Trace).unwrap().fused;
        let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap().fused;
        for fused in [
            ci.clone(),
            nm.clone(),
            naive_fusion(&p),
            coupled(ci),
            coupled(nm),
        ] {
            let scale = fused.P.amax();
            let worst = cross
                .iter()
                .map(|c| conservativeness_margin(&p, &fused, c).unwrap())
                .fold(f64::INFINITY, f64::min);
            let got = worst_margin(&p, &fused, &cross).unwrap();
            assert!(
                (got - worst).abs() <= 1e-12 * scale,
                "{groups:?}: {got} vs {worst}"
            );
            let coins = fused_coins(&p, &fused, &cross).unwrap();
            assert_eq!(coins.len(), cross.len());
            for (c, P_ab) in coins.iter().zip(&cross) {
                let one = fused_coin(&p, &fused, P_ab).unwrap();
                assert!(
                    (c - one).abs() <= 1e-11 * one.max(1.0),
                    "{groups:?}: {c} vs {one}"
                );
            }
        }
    }
}
