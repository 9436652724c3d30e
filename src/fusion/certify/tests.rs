use super::{geometry::*, layout::*, memo::*, repair::*, rule::*, settings::*};

use nalgebra::DMatrix;

use crate::fusion::FusionProblem;

use crate::CrossPattern;
use rand::{Rng, SeedableRng};

#[test]
fn the_memo_keeps_the_last_blocks_used_and_changes_no_number() {
    // `n` one-state blocks with distinct variances (each cross block wholly unknown: CI's
    // bound, so cheap); `shift` moves every variance.
    let problem = |n: usize, shift: f64| {
        let d = |f: fn(usize) -> f64| {
            DMatrix::from_fn(n, n, |i, j| if i == j { f(i) + shift } else { 0.0 })
        };
        FusionProblem::from_covariances(
            d(|i| 1.0 + i as f64),
            d(|i| 3.0 + 0.5 * i as f64),
            CrossPattern::diagonal(n),
        )
        .unwrap()
    };
    let settings = CertifySettings::default();
    let run = |memo: &mut CertificateMemo, p: &FusionProblem| {
        let got = certified_fusion_memo(p, &settings, memo).unwrap();
        assert_eq!(got, certified_fusion(p, &settings).unwrap());
        (memo.hits(), memo.len())
    };
    let mut memo = CertificateMemo::new();
    assert!(memo.is_empty());
    // Four blocks, twice: all four kept, then all four reused.
    assert_eq!(run(&mut memo, &problem(4, 0.0)), (0, 4));
    assert!(!memo.is_empty());
    assert_eq!(run(&mut memo, &problem(4, 0.0)), (4, 4));
    // MEMO_BLOCKS + 2 new blocks: the memo holds the last MEMO_BLOCKS of them.
    let big = problem(MEMO_BLOCKS + 2, 10.0);
    assert_eq!(run(&mut memo, &big), (4, MEMO_BLOCKS));
    // The first two were evicted first (least recently used); the cyclic order then
    // evicts each block before it comes round again: no hit, the same result.
    assert_eq!(run(&mut memo, &big), (4, MEMO_BLOCKS));
    // The blocks used last are kept: the last MEMO_BLOCKS of `big` again.
    let tail = FusionProblem::from_covariances(
        big.P_a
            .view((2, 2), (MEMO_BLOCKS, MEMO_BLOCKS))
            .into_owned(),
        big.P_b
            .view((2, 2), (MEMO_BLOCKS, MEMO_BLOCKS))
            .into_owned(),
        CrossPattern::diagonal(MEMO_BLOCKS),
    )
    .unwrap();
    assert_eq!(run(&mut memo, &tail), (4 + MEMO_BLOCKS as u64, MEMO_BLOCKS));
    // With a time limit the memo is neither read nor written.
    let limited = CertifySettings {
        time_limit: Some(60.0),
        ..settings
    };
    let mut fresh = CertificateMemo::new();
    for _ in 0..2 {
        certified_fusion_memo(&tail, &limited, &mut fresh).unwrap();
    }
    assert_eq!((fresh.hits(), fresh.len()), (0, 0));
}

#[test]
#[allow(non_snake_case)]
fn cones_cover_space_exactly_and_their_multipliers_are_the_normals_products() {
    // The proof needs: every v ≠ 0 lies in some cone or its negative, where each q_ij is
    // ≥ 0. Checked exactly in integers over every direction of a 17³ grid (the cones'
    // generators have entries up to 4, so the grid meets every cone's interior and
    // boundary), and each multiplier matrix, evaluated exactly (dyadic entries, small
    // integer v), equals the product of its two normals' forms up to its power-of-two
    // scale.
    for count in [4u32, 16, 64] {
        let cones = cone_generators(count).unwrap();
        let mults = cone_multipliers(3, count).unwrap();
        assert_eq!(cones.len(), count as usize);
        let cross = |a: [i64; 3], b: [i64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let dot = |a: [i64; 3], b: [i64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let normals: Vec<[[i64; 3]; 3]> = cones
            .iter()
            .map(|u| [cross(u[1], u[2]), cross(u[2], u[0]), cross(u[0], u[1])])
            .collect();
        for x in -8i64..=8 {
            for y in -8i64..=8 {
                for z in -8i64..=8 {
                    let v = [x, y, z];
                    if v == [0, 0, 0] {
                        continue;
                    }
                    let inside = normals.iter().position(|nn| {
                        let d = nn.map(|n| dot(n, v));
                        d.iter().all(|&t| t >= 0) || d.iter().all(|&t| t <= 0)
                    });
                    let k = inside.unwrap_or_else(|| panic!("{count} cones miss {v:?}"));
                    let d = normals[k].map(|n| dot(n, v));
                    for (S, (i, j)) in mults[k].iter().zip([(0, 1), (0, 2), (1, 2)]) {
                        let vf = v.map(|t| t as f64);
                        let mut q = 0.0;
                        for a in 0..3 {
                            for b in 0..3 {
                                q += vf[a] * S[(a, b)] * vf[b];
                            }
                        }
                        let exact = (d[i] * d[j]) as f64;
                        assert!(q >= 0.0, "{count} cones: q < 0 at {v:?}");
                        // q = exact · 2^-e for the matrix's scale: the ratio is a power of
                        // two (or both are zero).
                        if exact == 0.0 {
                            assert_eq!(q, 0.0);
                        } else {
                            let ratio = q / exact;
                            assert_eq!(ratio, ratio.log2().round().exp2(), "{v:?}");
                        }
                    }
                }
            }
        }
    }
    assert!(cone_generators(8).is_err());
    assert!(cone_multipliers(4, 4).is_err());
}

#[test]
fn sector_multipliers_cover_the_plane_exactly() {
    // The proof needs only: every v ≠ 0 has some sector with q_k(v) ≥ 0. Checked exactly
    // (coefficients · 2¹² are integers, products in i128) on every integer direction of a
    // fine grid — a missing or inverted sector leaves an arc of π/S ≥ π/64 uncovered,
    // which holds many of them — and each q_k is positive inside its own sector's arc
    // and negative just outside both of its ends.
    for count in 2..=MAX_SECTORS {
        let q: Vec<[i128; 3]> = sector_multipliers(count)
            .unwrap()
            .iter()
            .map(|c| {
                c.map(|x| {
                    let i = x * 4096.0;
                    assert_eq!(i, i.round(), "not an integer times 2⁻¹²");
                    i as i128
                })
            })
            .collect();
        assert_eq!(q.len(), count as usize);
        let eval = |c: &[i128; 3], x: i128, y: i128| c[0] * x * x + c[1] * x * y + c[2] * y * y;
        for x in -300i128..=300 {
            for y in -300i128..=300 {
                if (x, y) != (0, 0) {
                    assert!(
                        q.iter().any(|c| eval(c, x, y) >= 0),
                        "{count} sectors miss ({x}, {y})"
                    );
                }
            }
        }
        for (k, c) in q.iter().enumerate() {
            let t = |f: f64| std::f64::consts::PI * (k as f64 + f) / count as f64;
            let at = |t: f64| ((1e6 * t.cos()) as i128, (1e6 * t.sin()) as i128);
            let (xm, ym) = at(t(0.5));
            assert!(eval(c, xm, ym) > 0, "{count}: sector {k} mid");
            for outside in [t(-0.3), t(1.3)] {
                let (x, y) = at(outside);
                assert!(eval(c, x, y) < 0, "{count}: sector {k} outside");
            }
        }
    }
    assert!(sector_multipliers(1).is_err());
}

#[test]
fn zero_groups_sum_to_exactly_zero() {
    // Every entry ends a multiple of the group's grid g, so the sum is checked exactly in
    // integers (i128 multiples of g), not in floating point.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    for len in [2usize, 3, 5, 17, 100] {
        for scale in [1e-12, 1.0, 3e7] {
            let mut x: Vec<f64> = (0..len)
                .map(|_| scale * rng.random_range(-1.0..1.0))
                .collect();
            let before = x.clone();
            let group: Vec<usize> = (0..len).collect();
            exact_zero_sum(&mut x, &group);
            assert!(sums_to_zero(&x));
            let bound = before.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let g = x
                .iter()
                .filter(|v| **v != 0.0)
                .map(|v| v.abs())
                .fold(f64::INFINITY, f64::min);
            let ints: i128 = x
                .iter()
                .map(|v| {
                    // exact multiples of the smallest power of two dividing the entries
                    let e = (g.log2().floor() as i32) - 60;
                    let q = v / 2f64.powi(e);
                    assert_eq!(q, q.round(), "not on a grid");
                    q as i128
                })
                .sum();
            assert_eq!(ints, 0, "len {len} scale {scale}");
            let moved = x
                .iter()
                .zip(&before)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f64, f64::max);
            let sum: f64 = before.iter().sum();
            assert!(moved <= sum.abs() + 1e-12 * bound, "moved {moved}");
        }
    }
}

#[test]
fn cone_sizes_and_monomials() {
    assert_eq!(CertifySettings::cone_size(2, 1), 9);
    assert_eq!(CertifySettings::cone_size(3, 3), 66);
    assert_eq!(CertifySettings::cone_size(4, 2), 84);
    assert_eq!(monomials(3, 2).len(), 6);
    assert_eq!(multinomial(&[2, 1]), 3.0);
}

#[test]
#[allow(non_snake_case)]
fn bisected_cones_still_cover_space_and_their_multipliers_stay_exact() {
    // The adaptive cones' proof needs: each bisection is an exact subdivision (every
    // direction of the parent cone is in a child, every direction of a child in the parent),
    // so every refinement of the octants covers space with the cones and their negatives; and
    // each cone's multipliers are exactly its normals' products (up to a power of two) while
    // `bisect` accepts the cone. Checked in integers on random directions and a grid, over a
    // refinement that cuts cones in a fixed scattered order and one cone down to the limit.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(44);
    let (cones, depth, _) =
        refine_checked(cone_generators(4).unwrap(), 120, 1 << 12, 5000, &mut rng);
    assert!(depth >= 12, "cut the first cone {depth} times");
    for x in -8i64..=8 {
        for y in -8i64..=8 {
            for z in -8i64..=8 {
                let v = [x, y, z];
                if v != [0, 0, 0] {
                    assert!(cones.iter().any(|u| in_cone_n(u, v)), "{v:?} uncovered");
                }
            }
        }
    }
    for u in &cones {
        let normals = [cross(u[1], u[2]), cross(u[2], u[0]), cross(u[0], u[1])];
        for (S, (i, j)) in cone_piece(u).iter().zip([(0, 1), (0, 2), (1, 2)]) {
            let twice =
                |r: usize, c: usize| normals[i][r] * normals[j][c] + normals[j][r] * normals[i][c];
            let (r0, c0) = (0..9)
                .map(|e| (e / 3, e % 3))
                .find(|&(r, c)| twice(r, c) != 0)
                .expect("two independent normals");
            let ratio = S[(r0, c0)] / twice(r0, c0) as f64;
            assert_eq!(ratio, ratio.log2().round().exp2(), "{u:?}");
            for r in 0..3 {
                for c in 0..3 {
                    assert_eq!(S[(r, c)], twice(r, c) as f64 * ratio, "{u:?} ({r}, {c})");
                }
            }
        }
    }
}

#[test]
fn adaptive_cones_never_looser_than_their_first_round_and_stop_at_the_budget() {
    // The refinement's first round is the program of 4 cones (the same pieces in the same
    // order), and it keeps the smallest proven trace of its rounds: never above the 4-cone
    // certificate's, exactly. It uses between 4 and `budget` cones, and a time limit ends it
    // with the best proof found so far (or the time-limit error before any).
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let spd = |rng: &mut rand_chacha::ChaCha8Rng| {
        let g = DMatrix::from_fn(3, 3, |_, _| rng.random_range(-1.0..1.0));
        &g * g.transpose() + DMatrix::identity(3, 3) * 0.3
    };
    let p = FusionProblem::from_covariances(
        spd(&mut rng),
        spd(&mut rng),
        CrossPattern::from_fn(3, |i, j| i + j != 2),
    )
    .unwrap();
    let settings = CertifySettings::default();
    let four = super::block::certify_block(&p, None, Family::Cones(4), &settings).unwrap();
    // The cones' shares of the dual sum to n (stationarity in Q's diagonal), as the cut
    // rule reads them.
    let pieces: Vec<super::assemble::Piece> = cone_generators(4)
        .unwrap()
        .iter()
        .map(|u| super::assemble::Piece {
            multipliers: cone_piece(u),
        })
        .collect();
    let (same, shares) = super::sos::certify_pieces(&p, None, 1, &pieces, &settings).unwrap();
    assert_eq!(same.P, four.P);
    assert!(shares.iter().all(|&s| s > -1e-8), "{shares:?}");
    assert!(
        (shares.iter().sum::<f64>() - 3.0).abs() < 1e-6,
        "{shares:?}"
    );
    let budget = 10;
    let adaptive =
        super::block::certify_block(&p, None, Family::Adaptive(budget), &settings).unwrap();
    assert!(
        (4..=budget).contains(&adaptive.pieces),
        "{}",
        adaptive.pieces
    );
    let trace = |m: &DMatrix<f64>| crate::fusion::upper::trace_upper_bound(m);
    assert!(
        trace(&adaptive.P) <= trace(&four.P),
        "{} > {}",
        trace(&adaptive.P),
        trace(&four.P)
    );
    let limited = CertifySettings {
        time_limit: Some(0.5),
        ..settings
    };
    let start = std::time::Instant::now();
    match super::block::certify_block(
        &p,
        None,
        Family::Adaptive(crate::certify::MAX_CONES),
        &limited,
    ) {
        Ok(c) => assert!(c.pieces < crate::certify::MAX_CONES),
        Err(e) => assert!(matches!(e, crate::SolveError::TimeLimit { .. }), "{e}"),
    }
    // Without the limit, 256 cones take minutes.
    assert!(start.elapsed().as_secs_f64() < 10.0);
}

/// `det` of `N × N` integer rows by the Leibniz formula (a sum over permutations), written
/// apart from `geometry`'s Laplace expansion.
fn leibniz<const N: usize>(rows: &[[i64; N]; N]) -> i128 {
    fn permutations(rest: Vec<usize>) -> Vec<Vec<usize>> {
        if rest.len() <= 1 {
            return vec![rest];
        }
        (0..rest.len())
            .flat_map(|k| {
                let mut others = rest.clone();
                let first = others.remove(k);
                permutations(others).into_iter().map(move |mut p| {
                    p.insert(0, first);
                    p
                })
            })
            .collect()
    }
    permutations((0..N).collect())
        .into_iter()
        .map(|p| {
            let inversions = (0..N)
                .flat_map(|i| (i + 1..N).map(move |j| (i, j)))
                .filter(|&(i, j)| p[i] > p[j])
                .count();
            let product: i128 = (0..N).map(|r| i128::from(rows[r][p[r]])).product();
            if inversions % 2 == 0 {
                product
            } else {
                -product
            }
        })
        .sum()
}

/// `v` in the closed cone spanned by the rows of `u` or its negative, exactly (Cramer: the
/// coordinates `λ_i = det(u with row i replaced by v) / det u` share a sign).
fn in_cone_n<const N: usize>(u: &[[i64; N]; N], v: [i64; N]) -> bool {
    let d: Vec<i128> = (0..N)
        .map(|i| {
            let mut w = *u;
            w[i] = v;
            leibniz(&w)
        })
        .collect();
    d.iter().all(|&t| t >= 0) || d.iter().all(|&t| t <= 0)
}

#[test]
#[allow(non_snake_case)]
fn four_state_cones_cover_space_and_their_multipliers_stay_exact() {
    // `certify_rule` on four states needs what three need: the eight orthants of `v₄ ≥ 0`
    // and their negatives cover ℝ⁴, every bisection is an exact subdivision, and each cone's
    // six multipliers are exactly its normals' products (up to a power of two) while
    // `bisect` accepts it, refusing only at the limit of exact multipliers (2⁷). Checked in
    // integers with a determinant written here, on random directions and a grid.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let cones = orthants::<4>();
    assert_eq!(cones.len(), 8);
    assert!(cones.iter().all(|u| leibniz(u) != 0));
    let (cones, depth, mut refused) = refine_checked(cones, 150, 128, 3000, &mut rng);
    // One cone cut again and again (always its first half) until `bisect` refuses it.
    let mut thin = orthants::<4>()[5];
    for _ in 0..10_000 {
        match bisect(&thin) {
            Some([a, _]) => thin = a,
            None => {
                refused += 1;
                break;
            }
        }
    }
    assert!(
        depth >= 8 && refused > 0,
        "depth {depth}, refused {refused}"
    );
    let u = thin;
    assert!(
        (0..4).any(|i| (i + 1..4).any(|j| (0..4).any(|e| (u[i][e] + u[j][e]).abs() >= 128))),
        "{u:?} refused below the limit"
    );
    let range = -4i64..=4;
    for x in range.clone() {
        for y in range.clone() {
            for z in range.clone() {
                for w in range.clone() {
                    let v = [x, y, z, w];
                    if v != [0; 4] {
                        assert!(cones.iter().any(|u| in_cone_n(u, v)), "{v:?} uncovered");
                    }
                }
            }
        }
    }
    for u in &cones {
        let normals: Vec<[i128; 4]> = (0..4)
            .map(|i| {
                std::array::from_fn(|c| {
                    let mut w = *u;
                    w[i] = std::array::from_fn(|e| i64::from(e == c));
                    leibniz(&w)
                })
            })
            .collect();
        let pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
        let pieces = cone_piece(u);
        assert_eq!(pieces.len(), pairs.len());
        for (S, (i, j)) in pieces.iter().zip(pairs) {
            let twice =
                |r: usize, c: usize| normals[i][r] * normals[j][c] + normals[j][r] * normals[i][c];
            assert!((0..16).all(|e| twice(e / 4, e % 4).abs() < 1 << 53));
            let (r0, c0) = (0..16)
                .map(|e| (e / 4, e % 4))
                .find(|&(r, c)| twice(r, c) != 0)
                .expect("two independent normals");
            let ratio = S[(r0, c0)] / twice(r0, c0) as f64;
            assert_eq!(ratio, ratio.log2().round().exp2(), "{u:?}");
            for r in 0..4 {
                for c in 0..4 {
                    assert_eq!(S[(r, c)], twice(r, c) as f64 * ratio, "{u:?} ({r}, {c})");
                }
            }
        }
    }
}

/// Cuts `cones` `steps` times — most steps the first cone (deep, thin cones), the others a
/// scattered one — and checks each cut: the halves are non-degenerate and exactly subdivide
/// the parent (on 300 random integer directions with entries up to `spread`), and `bisect`
/// refuses a cone only where a new generator would reach `limit`. Returns the cones, how
/// often the first one was cut and how many cuts were refused.
fn refine_checked<const N: usize>(
    mut cones: Vec<[[i64; N]; N]>,
    steps: usize,
    limit: i64,
    spread: i64,
    rng: &mut rand_chacha::ChaCha8Rng,
) -> (Vec<[[i64; N]; N]>, usize, usize) {
    let (mut depth, mut refused) = (0, 0);
    for step in 0..steps {
        let k = if step % 3 == 0 {
            0
        } else {
            (step * 37) % cones.len()
        };
        let Some([a, b]) = bisect(&cones[k]) else {
            let u = cones[k];
            assert!(
                (0..N).any(|i| (i + 1..N)
                    .any(|j| (0..N).any(|e| (u[i][e] + u[j][e]).abs() >= limit))),
                "{u:?} refused below the limit"
            );
            refused += 1;
            continue;
        };
        let parent = cones[k];
        assert!(leibniz(&a) != 0 && leibniz(&b) != 0);
        for _ in 0..300 {
            let v = [0; N].map(|_| rng.random_range(-spread..=spread));
            let in_child = in_cone_n(&a, v) || in_cone_n(&b, v);
            assert_eq!(
                in_cone_n(&parent, v),
                in_child,
                "{parent:?} → {a:?}, {b:?} at {v:?}"
            );
        }
        cones[k] = a;
        cones.push(b);
        if k == 0 {
            depth += 1;
        }
    }
    (cones, depth, refused)
}
