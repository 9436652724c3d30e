//! N-way CI and nmCI: pairwise results for two estimates, weights on the simplex and optimal
//! against a brute-force grid, block splitting, and typed errors.

use crate::common;

use common::*;
use nalgebra::{DMatrix, DVector};
use nmci::{contract::*, nway::*, rules::*, structure::*, *};

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

/// The JSON contract: `estimates` with two entries answer exactly what `pa`/`pb` answer (same
/// `x`, `p`, trace; `weights` = `[ω, 1 − ω]` per block), for CI and nmCI.
#[test]
fn json_two_estimates_equal_the_pairwise_request() {
    for (method, pattern) in [
        ("ci", "true,true],[true,true"),
        ("nmci", "true,false],[false,true"),
    ] {
        let pairwise = fuse_json(&format!(
            r#"{{"pa": [[3,0.5],[0.5,1]], "pb": [[1,0],[0,4]], "xa": [1,2], "xb": [3,-1],
                "pab_unknown": [[{pattern}]], "method": "{method}"}}"#
        ))
        .unwrap();
        let nway = fuse_json(&format!(
            r#"{{"estimates": [{{"x": [1,2], "p": [[3,0.5],[0.5,1]]}}, {{"x": [3,-1], "p": [[1,0],[0,4]]}}],
                "patterns": [{{"i": 0, "j": 1, "pab_unknown": [[{pattern}]]}}], "method": "{method}"}}"#
        ))
        .unwrap();
        let (a, b): (FuseResponse, FuseResponse) = (
            serde_json::from_str(&pairwise).unwrap(),
            serde_json::from_str(&nway).unwrap(),
        );
        assert_eq!((&a.x, &a.p, a.trace), (&b.x, &b.p, b.trace), "{method}");
        let (ka, kb) = a.pair_gains().unwrap();
        let Gains::Nway(gains) = &b.gains else {
            panic!("N-way gains")
        };
        assert_eq!((&gains[0], &gains[1]), (ka, kb));
        let omega = a.omega().unwrap();
        let Details::Nway { weights, .. } = &b.details else {
            panic!("{:?}", b.details)
        };
        assert_eq!(weights.len(), omega.len());
        for (w, o) in weights.iter().zip(&omega) {
            assert_eq!(w, &vec![*o, 1.0 - o]);
        }
        assert!(b.pair_gains().is_none() && b.omega().is_none());
        assert!(!nway.contains("\"ka\""));
    }
}

/// Three estimates through the contract: weights on the simplex per block, gains summing to
/// the identity, the fused mean their combination, nmCI never looser than CI.
#[test]
fn json_three_estimates() {
    let request = |method: &str| {
        format!(
            r#"{{"estimates": [{{"x": [1,0], "p": [[1,0],[0,9]]}}, {{"x": [0,1], "p": [[9,0],[0,1]]}},
                              {{"p": [[4,0],[0,4]]}}],
                "patterns": [{{"i": 0, "j": 1, "pab_unknown": [[true,false],[false,true]]}},
                             {{"i": 0, "j": 2, "pab_unknown": [[true,false],[false,true]]}},
                             {{"i": 1, "j": 2, "pab_unknown": [[true,false],[false,true]]}}],
                "method": "{method}"}}"#
        )
    };
    let ci: FuseResponse = serde_json::from_str(&fuse_json(&request("ci")).unwrap()).unwrap();
    let nm: FuseResponse = serde_json::from_str(&fuse_json(&request("nmci")).unwrap()).unwrap();
    assert_eq!(ci.blocks().unwrap().len(), 1);
    assert_eq!(nm.blocks().unwrap(), &vec![vec![0], vec![1]]);
    let weights = |r: &FuseResponse| match &r.details {
        Details::Nway { weights, .. } => weights.clone(),
        other => panic!("{other:?}"),
    };
    // Per block, the best single estimate: x1 from estimate 0, x2 from estimate 1.
    assert_eq!(weights(&nm), vec![vec![1.0, 0.0, 0.0], vec![0.0, 1.0, 0.0]]);
    assert!((nm.trace - 2.0).abs() < 1e-12 && ci.trace > nm.trace);
    for r in [&ci, &nm] {
        for w in &weights(r) {
            assert!(w.iter().all(|v| *v >= 0.0) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        let Gains::Nway(gains) = &r.gains else {
            panic!("N-way gains")
        };
        let xs = [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]];
        for (row, fused) in r.x.iter().enumerate() {
            let sum: f64 = gains.iter().map(|g| g[row][row]).sum();
            assert!((sum - 1.0).abs() < 1e-12);
            let x: f64 = gains
                .iter()
                .zip(&xs)
                .map(|(g, x)| g[row].iter().zip(x).map(|(k, v)| k * v).sum::<f64>())
                .sum();
            assert!((x - fused).abs() < 1e-12);
        }
    }
}

/// Wrong N-way requests are typed errors with what to change.
#[test]
fn json_nway_errors() {
    let e = |json: &str| fuse_json(json).unwrap_err().to_string();
    let two = r#"[{"p": [[1]]}, {"p": [[2]]}]"#;
    assert!(e(&format!(
        r#"{{"estimates": {two}, "pa": [[1]], "method": "ci"}}"#
    ))
    .contains("not both"));
    assert!(e(&format!(r#"{{"estimates": {two}, "method": "sdp"}}"#))
        .contains("supports methods \"ci\" and \"nmci\""));
    assert!(
        e(r#"{"pa": [[1]], "pb": [[1]], "patterns": [], "method": "ci"}"#)
            .contains("`patterns` applies to N-way fusion only")
    );
    assert!(e(r#"{"method": "ci"}"#).contains("`pa` and `pb` are missing or empty"));
    assert!(
        e(r#"{"method": "ci", "pa": [], "pb": []}"#).contains("`pa` and `pb` are missing or empty")
    );
    assert!(e(r#"{"estimates": [{"p": [[1]]}], "method": "ci"}"#).contains("at least 2 estimates"));
    assert!(
        e(r#"{"estimates": [{"p": [[1]]}, {"p": [[1,0],[0,1]]}], "method": "ci"}"#)
            .contains("estimates[1] has size 2")
    );
    assert!(
        e(r#"{"estimates": [{"p": [[1]]}, {"p": [[-1]]}], "method": "ci"}"#)
            .contains("estimates[1].p")
    );
    assert!(e(&format!(
        r#"{{"estimates": {two}, "patterns": [{{"i": 0, "j": 3, "pab_unknown": [[true]]}}], "method": "nmci"}}"#
    ))
    .contains("pair (0, 3)"));
    assert!(
        e(r#"{"estimates": [{"p": [[1]], "q": 1}, {"p": [[1]]}], "method": "ci"}"#)
            .contains("unknown field `q`")
    );
}

/// N-way fusion of estimates that share information, checked where it matters: 4 states in
/// two independent blocks ({0, 1} and {2, 3}), three estimates built from one common prior and
/// overlapping sets of measurements (each measurement sees one block), so their errors are
/// correlated within blocks and independent across them. For trace and log-det:
/// - nmCI equals N-way CI run on each block separately (P, x and weights to 1e-12);
/// - each block's weights satisfy the KKT conditions of `min f(ω)` on the simplex, with the
///   gradient computed here (`∂ tr P/∂ωᵢ = −tr(P Pᵢ⁻¹ P)`, `∂ log det P/∂ωᵢ = −tr(Pᵢ⁻¹ P)`):
///   equal on the support, not smaller off it, to 1e-10 relative;
/// - the reported `P` is `(Σ ωᵢ Pᵢ⁻¹)⁻¹` per block, and `x = Σ Kᵢ xᵢ`;
/// - the fused `P` bounds the true error covariance `Σᵢⱼ Kᵢ Cᵢⱼ Kⱼᵀ` (`C` the exact joint
///   covariance of the three estimates' errors) — for nmCI and for monolithic CI.
#[test]
fn shared_information_three_estimates_in_two_blocks() {
    use nalgebra::SymmetricEigen;
    let n = 4;
    let inv = |m: &DMatrix<f64>| m.clone().try_inverse().unwrap();
    // Truth x ~ N(0, P0); measurements z = h x + v, v ~ N(0, r); each sees one block.
    let P0 = diag(&[4.0, 2.0, 3.0, 5.0]);
    let rows: [([f64; 4], f64); 6] = [
        ([1.0, 0.5, 0.0, 0.0], 0.5),
        ([0.0, 1.0, 0.0, 0.0], 1.0),
        ([0.3, -1.0, 0.0, 0.0], 0.8),
        ([0.0, 0.0, 1.0, 0.2], 0.6),
        ([0.0, 0.0, 0.4, 1.0], 1.5),
        ([0.0, 0.0, 1.0, -0.7], 0.4),
    ];
    // Which measurements each estimate used (overlaps: shared information).
    let used: [&[usize]; 3] = [&[0, 1, 3], &[1, 2, 4], &[0, 2, 4, 5]];
    // Estimate i: information filter from the prior and its measurements. Its error is
    // e_i = A_i x − Σ_m B_im v_m, linear in (x, v): the joint covariance is exact.
    let mut P = Vec::new();
    let mut A = Vec::new(); // e_i = A_i x + Σ_m B[i][m] v_m
    let mut B = Vec::new();
    for set in used {
        let mut info = inv(&P0);
        for &m in set {
            let h = DMatrix::from_row_slice(1, n, &rows[m].0);
            info += h.transpose() * &h / rows[m].1;
        }
        let Pi = inv(&info);
        // x̂_i = Pi Σ hᵀ z / r, so e_i = (I − Pi Σ hᵀh/r) x − Σ Pi hᵀ v / r.
        let mut Ai = DMatrix::identity(n, n);
        let mut Bi = vec![DMatrix::zeros(n, 1); rows.len()];
        for &m in set {
            let h = DMatrix::from_row_slice(1, n, &rows[m].0);
            Ai -= &Pi * h.transpose() * &h / rows[m].1;
            Bi[m] = -(&Pi * h.transpose()) / rows[m].1;
        }
        P.push(Pi);
        A.push(Ai);
        B.push(Bi);
    }
    let C = |i: usize, j: usize| -> DMatrix<f64> {
        let mut c = &A[i] * &P0 * A[j].transpose();
        for (m, (_, r)) in rows.iter().enumerate() {
            c += &B[i][m] * B[j][m].transpose() * *r;
        }
        c
    };
    // Sanity: each estimate is consistent (its P is its error covariance) and the blocks are
    // independent in every C_ij.
    for (i, P_i) in P.iter().enumerate() {
        assert!((C(i, i) - P_i).amax() < 1e-12);
        for j in 0..3 {
            let c = C(i, j);
            for (a, b) in [(0, 2), (0, 3), (1, 2), (1, 3)] {
                assert!(c[(a, b)].abs() < 1e-14 && c[(b, a)].abs() < 1e-14);
            }
        }
    }
    let x: Vec<DVector<f64>> = (0..3)
        .map(|i| DVector::from_fn(n, |k, _| (i * n + k) as f64 * 0.1 - 0.3))
        .collect();
    let es: Vec<Estimate> = (0..3)
        .map(|i| estimate(x[i].clone(), P[i].clone()))
        .collect();
    let block_pattern = CrossPattern::from_fn(n, |a, b| (a < 2) == (b < 2));
    let pairs: Vec<PairPattern> = [(0, 1), (0, 2), (1, 2)]
        .into_iter()
        .map(|(i, j)| PairPattern {
            i,
            j,
            pattern: block_pattern.clone(),
        })
        .collect();
    let restrict =
        |m: &DMatrix<f64>, b: &[usize]| DMatrix::from_fn(b.len(), b.len(), |i, j| m[(b[i], b[j])]);
    for criterion in [Criterion::Trace, Criterion::Logdet] {
        let nm = non_monolithic_ci_nway(&es, &pairs, criterion).unwrap();
        assert_eq!(nm.blocks, vec![vec![0, 1], vec![2, 3]]);
        for (k, block) in nm.blocks.iter().enumerate() {
            // Per-block N-way CI.
            let sub: Vec<Estimate> = (0..3)
                .map(|i| {
                    estimate(
                        DVector::from_fn(2, |r, _| x[i][block[r]]),
                        restrict(&P[i], block),
                    )
                })
                .collect();
            let alone = covariance_intersection_nway(&sub, criterion).unwrap();
            assert!((restrict(&nm.P, block) - &alone.P).amax() < 1e-12);
            assert!((DVector::from_fn(2, |r, _| nm.x[block[r]]) - &alone.x).amax() < 1e-12);
            let w = &nm.omega[k];
            assert!(w
                .iter()
                .zip(&alone.omega[0])
                .all(|(a, b)| (a - b).abs() < 1e-12));
            // P = (Σ ωᵢ Pᵢ⁻¹)⁻¹ per block, from the reported weights.
            let Pb_inv: Vec<DMatrix<f64>> = sub.iter().map(|e| inv(&e.P)).collect();
            let mut info = DMatrix::zeros(2, 2);
            for (wi, pinv) in w.iter().zip(&Pb_inv) {
                info += pinv * *wi;
            }
            let Pf = inv(&info);
            assert!((&Pf - restrict(&nm.P, block)).amax() < 1e-10 * Pf.amax());
            // KKT on the simplex.
            let g: Vec<f64> = Pb_inv
                .iter()
                .map(|pinv| match criterion {
                    Criterion::Trace => -(&Pf * pinv * &Pf).trace(),
                    Criterion::Logdet => -(pinv * &Pf).trace(),
                })
                .collect();
            let scale = g.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            let support: Vec<usize> = (0..3).filter(|&i| w[i] > 0.0).collect();
            let lambda = g[support[0]];
            for i in 0..3 {
                if w[i] > 0.0 {
                    assert!(
                        (g[i] - lambda).abs() <= 1e-10 * scale,
                        "{criterion:?} block {k}: {g:?} {w:?}"
                    );
                } else {
                    assert!(
                        g[i] >= lambda - 1e-10 * scale,
                        "{criterion:?} block {k}: {g:?} {w:?}"
                    );
                }
            }
        }
        // Conservative against the true joint error covariance, nmCI and monolithic CI.
        let mono = covariance_intersection_nway(&es, criterion).unwrap();
        for fused in [&nm, &mono] {
            let mut E = DMatrix::zeros(n, n);
            for i in 0..3 {
                for j in 0..3 {
                    E += &fused.gains[i] * C(i, j) * fused.gains[j].transpose();
                }
            }
            let D = &fused.P - &E;
            let min = SymmetricEigen::new((&D + D.transpose()) * 0.5)
                .eigenvalues
                .min();
            assert!(min >= -1e-12 * fused.P.amax(), "{criterion:?}: λ_min {min}");
            // And x = Σ Kᵢ xᵢ.
            let mut xf = DVector::zeros(n);
            for (K_i, x_i) in fused.gains.iter().zip(&x) {
                xf += K_i * x_i;
            }
            assert!((xf - &fused.x).amax() < 1e-12);
        }
        assert!(nm.P.trace() <= mono.P.trace() + 1e-12);
    }
}
