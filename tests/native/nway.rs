//! N-way CI and nmCI: pairwise results for two estimates, weights on the simplex and optimal
//! against a brute-force grid, block splitting, and typed errors.

use crate::common;

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
        assert_eq!(b.gains.as_ref().unwrap()[0], *a.ka.as_ref().unwrap());
        assert_eq!(b.gains.as_ref().unwrap()[1], *a.kb.as_ref().unwrap());
        let omega = a.omega.unwrap();
        let weights = b.weights.unwrap();
        assert_eq!(weights.len(), omega.len());
        for (w, o) in weights.iter().zip(&omega) {
            assert_eq!(w, &vec![*o, 1.0 - o]);
        }
        assert!(b.ka.is_none() && b.kb.is_none() && b.omega.is_none());
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
    assert_eq!(ci.blocks.as_ref().unwrap().len(), 1);
    assert_eq!(nm.blocks.as_ref().unwrap(), &vec![vec![0], vec![1]]);
    // Per block, the best single estimate: x1 from estimate 0, x2 from estimate 1.
    assert_eq!(
        nm.weights.as_ref().unwrap(),
        &vec![vec![1.0, 0.0, 0.0], vec![0.0, 1.0, 0.0]]
    );
    assert!((nm.trace - 2.0).abs() < 1e-12 && ci.trace > nm.trace);
    for r in [&ci, &nm] {
        for w in r.weights.as_ref().unwrap() {
            assert!(w.iter().all(|v| *v >= 0.0) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        let gains = r.gains.as_ref().unwrap();
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
    assert!(e(r#"{"method": "ci"}"#).contains("`pa` and `pb` are required"));
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
