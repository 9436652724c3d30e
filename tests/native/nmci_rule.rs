//! Non-monolithic CI: the paper's example, block detection on hand-made patterns, the
//! one-block case, and conservativeness.

use crate::common;

use common::*;
use nalgebra::DMatrix;
use nmci::{check::*, rules::*, sample::*, structure::*, *};

#[test]
fn paper_example_is_diag_1_1_with_omega_0_1() {
    let p = paper_example();
    let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap();
    assert_eq!(nm.fused.P, diag(&[1.0, 1.0]));
    assert_eq!(nm.omega, vec![0.0, 1.0]);
    assert_eq!(nm.blocks, vec![vec![0], vec![1]]);
    assert_eq!(nm.fused.K_a, diag(&[0.0, 1.0]));
    assert_eq!(nm.fused.K_b, diag(&[1.0, 0.0]));
    assert_eq!(nm.fused.trace(), 2.0);
}

fn pattern(n: usize, unknown: &[(usize, usize)]) -> CrossPattern {
    let mut m = DMatrix::from_element(n, n, false);
    for &(i, j) in unknown {
        m[(i, j)] = true;
    }
    CrossPattern::from_matrix(m).unwrap()
}

#[test]
fn blocks_of_hand_made_non_contiguous_patterns() {
    let I5 = DMatrix::<f64>::identity(5, 5);
    // Links 0–3 (P_ab[0,3]) and 1–4 (P_ab[4,1], the transposed entry); 2 alone.
    let b = independent_blocks(&I5, &I5, &pattern(5, &[(0, 3), (4, 1), (2, 2)]));
    assert_eq!(b, vec![vec![0, 3], vec![1, 4], vec![2]]);
    // A chain through P_a and P_b: P_a links 0–2, P_b links 2–4, pattern links 4–1.
    let mut P_a = DMatrix::<f64>::identity(5, 5);
    P_a[(0, 2)] = 0.1;
    P_a[(2, 0)] = 0.1;
    let mut P_b = DMatrix::<f64>::identity(5, 5);
    P_b[(2, 4)] = -0.2;
    P_b[(4, 2)] = -0.2;
    let b = independent_blocks(&P_a, &P_b, &pattern(5, &[(4, 1)]));
    assert_eq!(b, vec![vec![0, 1, 2, 4], vec![3]]);
    // Diagonal-only pattern with identity covariances: every state alone.
    let b = independent_blocks(&I5, &I5, &CrossPattern::diagonal(5));
    assert_eq!(b, (0..5).map(|i| vec![i]).collect::<Vec<_>>());
    // Fully unknown: one block.
    let b = independent_blocks(&I5, &I5, &CrossPattern::fully_unknown(5));
    assert_eq!(b, vec![(0..5).collect::<Vec<_>>()]);
}

#[test]
fn a_single_entry_in_either_triangle_links_two_states() {
    // `independent_blocks` takes any matrices: one non-zero entry of P_a or P_b, above or
    // below the diagonal, or one unknown entry of P_ab, either way round, links its states.
    let I3 = DMatrix::<f64>::identity(3, 3);
    let linked = vec![vec![0, 2], vec![1]];
    for (i, j) in [(0, 2), (2, 0)] {
        let mut one = I3.clone();
        one[(i, j)] = 0.3;
        let diagonal = CrossPattern::diagonal(3);
        assert_eq!(
            independent_blocks(&one, &I3, &diagonal),
            linked,
            "P_a[{i},{j}]"
        );
        assert_eq!(
            independent_blocks(&I3, &one, &diagonal),
            linked,
            "P_b[{i},{j}]"
        );
        let p = pattern(3, &[(0, 0), (1, 1), (2, 2), (i, j)]);
        assert_eq!(independent_blocks(&I3, &I3, &p), linked, "P_ab[{i},{j}]");
        assert_eq!(p.unknown_count(), 4);
    }
    assert_eq!(CrossPattern::fully_unknown(3).unknown_count(), 9);
    assert_eq!(CrossPattern::independent(3).unknown_count(), 0);
}

#[test]
fn one_block_is_exactly_ci() {
    let mut r = rng(2);
    for n in [2, 3, 6] {
        let p = random_problem(n, CrossPattern::fully_unknown(n), &mut r);
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let ci = covariance_intersection(&p, criterion).unwrap();
            let nm = non_monolithic_ci(&p, criterion).unwrap();
            assert_eq!(nm.blocks.len(), 1);
            assert_eq!(nm.omega, vec![ci.omega]);
            assert_eq!(nm.fused, ci.fused);
        }
    }
}

#[test]
fn interleaved_blocks_fuse_independently_and_beat_ci() {
    let mut r = rng(8);
    let groups = vec![vec![0, 2, 5], vec![1, 4], vec![3]];
    let n = 6;
    let P_a = block_spd(n, &groups, &mut r);
    let P_b = block_spd(n, &groups, &mut r);
    let mut unknown = DMatrix::from_element(n, n, false);
    for g in &groups {
        for &i in g {
            for &j in g {
                unknown[(i, j)] = true;
            }
        }
    }
    let p = FusionProblem::from_covariances(P_a, P_b, CrossPattern::from_matrix(unknown).unwrap())
        .unwrap();
    let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap();
    assert_eq!(
        nm.blocks,
        groups.iter().map(|g| g.to_vec()).collect::<Vec<_>>()
    );
    assert_eq!(nm.omega.len(), 3);
    for (g, &w) in groups.iter().zip(&nm.omega) {
        let ci = covariance_intersection(&p.restrict(g), Criterion::Trace).unwrap();
        assert_eq!(ci.omega, w);
    }
    // Off-block entries are exactly zero.
    for i in 0..n {
        for j in 0..n {
            let same = groups.iter().any(|g| g.contains(&i) && g.contains(&j));
            if !same {
                assert_eq!(nm.fused.P[(i, j)], 0.0);
                assert_eq!(nm.fused.K_a[(i, j)], 0.0);
            }
        }
    }
    let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
    assert!(nm.fused.trace() <= ci.fused.trace() + 1e-12);
    let samples = sample_cross_covariances(&p, 1000, 4, SamplerSettings::default()).unwrap();
    assert!(worst_margin(&p, &nm.fused, &samples.cross).unwrap() >= -1e-10);
}

#[test]
fn nmci_is_conservative_for_sampled_admissible_cross_covariances() {
    let mut r = rng(21);
    for (n, prob) in [(2usize, 0.5), (3, 0.4), (4, 0.25), (5, 0.2)] {
        for _ in 0..3 {
            let pattern = random_pattern(n, prob, &mut r);
            let p = random_problem(n, pattern, &mut r);
            let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap();
            let samples =
                sample_cross_covariances(&p, 1000, 9, SamplerSettings::rejection(50_000_000))
                    .unwrap();
            let m = worst_margin(&p, &nm.fused, &samples.cross).unwrap();
            assert!(m >= -1e-10, "nmCI not conservative: {m}");
        }
    }
}
