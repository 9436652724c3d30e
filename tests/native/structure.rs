//! Structure that survives round-off (`structure::absorb`): declared blocks, near-zero
//! couplings absorbed into a proven block-diagonal bound, never a silent fall back to CI.
//!
//! - a constant-velocity pair from a Riccati recursion with round-off couplings keeps nmCI's
//!   per-axis bound (within the reported cost), not CI's;
//! - the absorbed bound is conservative for the *given* (coupled) covariances, against sampled
//!   cross-covariances and an exact worst case per direction (an SDP written here, not the
//!   library's), on random near-block problems at n = 2..8 and couplings 1e-15..1e-3;
//! - the reported inflation is the trace difference of the covariances;
//! - exact zeros come back bit for bit; declared blocks imply the pattern;
//! - each refusal is a typed error naming its field.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use nmci::{check::*, contract::*, rules::*, sample::*, sdp::*, structure::*, *};
use rand::Rng;

use crate::common::{self, block_spd, diag, rng, rows};

/// A steady-state Kalman covariance of a 2-axis constant-velocity model (states
/// `[x, vx, y, vy]`) with a position sensor of variances `r` per axis, computed in a frame
/// rotated by `theta` and rotated back: the cross-axis entries are the recursion's round-off.
fn cv_covariance(r: [f64; 2], theta: f64) -> DMatrix<f64> {
    let t = 1.0;
    let q = 0.5;
    let f1 = DMatrix::from_row_slice(2, 2, &[1.0, t, 0.0, 1.0]);
    let q1 = DMatrix::from_row_slice(2, 2, &[t * t * t / 3.0, t * t / 2.0, t * t / 2.0, t]) * q;
    let mut f = DMatrix::zeros(4, 4);
    let mut qm = DMatrix::zeros(4, 4);
    for a in 0..2 {
        f.view_mut((2 * a, 2 * a), (2, 2)).copy_from(&f1);
        qm.view_mut((2 * a, 2 * a), (2, 2)).copy_from(&q1);
    }
    let (c, s) = (theta.cos(), theta.sin());
    // The rotation of (x, y) and (vx, vy) together.
    let rot = DMatrix::from_row_slice(
        4,
        4,
        &[
            c, 0.0, -s, 0.0, 0.0, c, 0.0, -s, s, 0.0, c, 0.0, 0.0, s, 0.0, c,
        ],
    );
    let h = DMatrix::from_row_slice(2, 4, &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let h_rot = &h * rot.transpose();
    let rm = diag(&r);
    let mut p = DMatrix::identity(4, 4) * 100.0;
    for _ in 0..500 {
        let pp = &f * &p * f.transpose() + &qm;
        let s_cov = &h_rot * &pp * h_rot.transpose() + &rm;
        let k = &pp * h_rot.transpose() * s_cov.try_inverse().unwrap();
        let i_kh = DMatrix::identity(4, 4) - &k * &h_rot;
        // Joseph form.
        p = &i_kh * &pp * i_kh.transpose() + &k * &rm * k.transpose();
        p = (&p + p.transpose()) * 0.5;
    }
    rot.transpose() * p * rot
}

/// The pair of the issue: two axis-aligned sensors, each precise on one axis.
fn cv_pair(theta: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    (
        cv_covariance([1.0, 100.0], theta),
        cv_covariance([100.0, 1.0], theta),
    )
}

fn per_axis_pattern() -> Vec<Vec<bool>> {
    let axis = [0, 0, 1, 1];
    (0..4)
        .map(|i| (0..4).map(|j| axis[i] == axis[j]).collect())
        .collect()
}

#[test]
fn round_off_couplings_keep_nmcis_per_axis_bound() {
    let (pa, pb) = cv_pair(0.3);
    let cross = [(0, 2), (0, 3), (1, 2), (1, 3)]
        .iter()
        .map(|&(i, j)| pa[(i, j)].abs().max(pb[(i, j)].abs()))
        .fold(0.0, f64::max);
    assert!(
        cross > 0.0 && cross < 1e-11,
        "the recursion leaves round-off across axes: {cross:e}"
    );
    // The same model without rotation: exact zeros, the per-axis bound.
    let (ea, eb) = cv_pair(0.0);
    assert_eq!(ea[(0, 2)], 0.0);
    let request = |pa: &DMatrix<f64>, pb: &DMatrix<f64>, method: Method| {
        let mut r = FuseRequest::new(method, rows(pa), rows(pb));
        r.pair.pab_unknown = Some(per_axis_pattern());
        r
    };
    let exact = fuse(&request(&ea, &eb, Method::Nmci)).unwrap();
    assert_eq!(exact.structure, None, "exact zeros: nothing to say");
    let ci = fuse(&request(&pa, &pb, Method::Ci)).unwrap();
    let nm = fuse(&request(&pa, &pb, Method::Nmci)).unwrap();
    let s = nm.structure.as_ref().expect("the absorption is reported");
    assert_eq!(s.blocks, vec![vec![0, 1], vec![2, 3]]);
    assert_eq!(s.exact_blocks, 1);
    assert!(s.absorbed && !s.couplings.is_empty());
    assert!(
        s.note.as_deref().unwrap().contains("absorbed"),
        "{:?}",
        s.note
    );
    let cost = s.nmci_trace_cost.unwrap();
    assert!((0.0..1e-9 * exact.trace).contains(&cost), "{cost:e}");
    // The per-axis bound within the reported cost (and the two models' own round-off).
    assert!(
        (nm.trace - exact.trace).abs() <= cost + 1e-9 * exact.trace,
        "nmCI {} against per-axis {} (cost {cost:e})",
        nm.trace,
        exact.trace
    );
    assert!(
        ci.trace > 1.2 * nm.trace,
        "CI {} nmCI {}",
        ci.trace,
        nm.trace
    );
    // Without absorption (coupling_tol 0) nmCI is CI, and the note says how to keep the blocks.
    let mut strict = request(&pa, &pb, Method::Nmci);
    strict.pair.coupling_tol = Some(0.0);
    let strict = fuse(&strict).unwrap();
    assert!((strict.trace - ci.trace).abs() <= 1e-12 * ci.trace);
    let note = strict.structure.unwrap().note.unwrap();
    assert!(
        note.contains("keeps blocks merged") && note.contains("2 blocks"),
        "{note}"
    );
}

/// `max_{P_ab} vᵀ K J Kᵀ v` over admissible joints `J` of `problem` (pattern and `J ⪰ 0`):
/// `vᵀ D v + 2 u_aᵀ P_ab u_b` at the worst `P_ab` for `u = Kᵀ v` (`common::worst`).
fn worst_in_direction(problem: &FusionProblem, fused: &Fused, v: &DVector<f64>) -> f64 {
    let (u_a, u_b) = (fused.K_a.tr_mul(v), fused.K_b.tr_mul(v));
    let P_ab = common::worst::worst_cross(problem, &u_a, &u_b);
    u_a.dot(&(&problem.P_a * &u_a))
        + u_b.dot(&(&problem.P_b * &u_b))
        + 2.0 * u_a.dot(&(&P_ab * &u_b))
}

/// A near-block problem: `groups` of states, block-diagonal covariances plus couplings of
/// relative size up to `c` between groups, `P_ab` unknown within groups.
fn near_block(n: usize, c: f64, seed: u64) -> (FusionProblem, Vec<Vec<usize>>) {
    let mut r = rng(seed);
    let k = if n == 2 {
        2
    } else {
        r.random_range(2..=3.min(n))
    };
    let mut groups = vec![Vec::new(); k];
    for i in 0..n {
        groups[if i < k { i } else { r.random_range(0..k) }].push(i);
    }
    let mut of = vec![0; n];
    for (g, group) in groups.iter().enumerate() {
        for &i in group {
            of[i] = g;
        }
    }
    let mut couple = |m: DMatrix<f64>| {
        let mut out = m.clone();
        for i in 0..n {
            for j in i + 1..n {
                if of[i] != of[j] {
                    let e = c * (m[(i, i)] * m[(j, j)]).sqrt() * r.random_range(-1.0..1.0);
                    out[(i, j)] = e;
                    out[(j, i)] = e;
                }
            }
        }
        out
    };
    let P_a = couple(block_spd(n, &groups, &mut rng(seed + 1000)));
    let P_b = couple(block_spd(n, &groups, &mut rng(seed + 2000)));
    let pattern = CrossPattern::from_fn(n, |i, j| of[i] == of[j]);
    let p = FusionProblem::from_covariances(P_a, P_b, pattern).unwrap();
    groups.sort();
    (p, groups)
}

#[test]
fn the_absorbed_bound_is_conservative_for_the_coupled_covariances() {
    for n in 2..=8 {
        for (ci, &c) in [1e-15, 1e-12, 1e-9, 1e-6, 1e-3].iter().enumerate() {
            let seed = (100 * n + ci) as u64;
            let (given, _) = near_block(n, c, seed);
            let settings = StructureSettings {
                coupling_tol: c.max(DEFAULT_COUPLING_TOL),
                ..StructureSettings::default()
            };
            let absorbed = absorb_couplings(&given, &settings).unwrap();
            assert!(absorbed.structure.blocks.len() >= 2, "n {n} c {c:e}");
            let nm = non_monolithic_ci(&absorbed.problem, Criterion::Trace).unwrap();
            let scale = nm.fused.P.amax();
            // The inflation reported is the trace difference of the covariances.
            let added = absorbed.problem.P_a.trace() + absorbed.problem.P_b.trace()
                - given.P_a.trace()
                - given.P_b.trace();
            let reported = absorbed.structure.trace_added();
            let ulps = 4.0 * n as f64 * f64::EPSILON * given.P_a.amax().max(given.P_b.amax());
            assert!(
                (added - reported).abs() <= ulps + 1e-12 * reported,
                "n {n} c {c:e}: added {added:e}, reported {reported:e}"
            );
            // Each coupling's `norm_bound` is at least its spectral norm (computed here by SVD).
            for coupling in &absorbed.structure.couplings {
                let P = if coupling.matrix == "pa" {
                    &given.P_a
                } else {
                    &given.P_b
                };
                let (rows, cols) = (
                    &absorbed.structure.blocks[coupling.blocks[0]],
                    &absorbed.structure.blocks[coupling.blocks[1]],
                );
                let E = DMatrix::from_fn(rows.len(), cols.len(), |i, j| P[(rows[i], cols[j])]);
                let sigma = E.singular_values().max();
                assert!(
                    coupling.norm_bound >= sigma,
                    "n {n} c {c:e}: {coupling:?} {sigma:e}"
                );
            }
            // Sampled admissible cross-covariances of the given problem.
            let samples = sample_cross_covariances(
                &given,
                200,
                seed,
                SamplerSettings {
                    kind: SamplerKind::HitAndRun,
                    ..SamplerSettings::default()
                },
            )
            .unwrap();
            let margin = worst_margin(&given, &nm.fused, &samples.cross).unwrap();
            assert!(
                margin >= -1e-12 * scale,
                "n {n} c {c:e}: sampled margin {margin:e}"
            );
            // The exact worst case along the directions where the bound is tightest.
            let slack = &nm.fused.P
                - &nm.fused.K_a * &given.P_a * nm.fused.K_a.transpose()
                - &nm.fused.K_b * &given.P_b * nm.fused.K_b.transpose();
            let eig = SymmetricEigen::new((&slack + slack.transpose()) * 0.5);
            let mut directions: Vec<DVector<f64>> = eig
                .eigenvectors
                .column_iter()
                .map(|v| v.into_owned())
                .collect();
            directions.extend((0..n).map(|i| DVector::from_fn(n, |k, _| f64::from(k == i))));
            for v in &directions {
                let worst = worst_in_direction(&given, &nm.fused, v);
                let bound = v.dot(&(&nm.fused.P * v));
                assert!(
                    worst <= bound + 1e-8 * scale,
                    "n {n} c {c:e}: worst {worst:e} above the bound {bound:e}"
                );
            }
        }
    }
}

/// Without the inflation (the couplings dropped, nothing added) the worst-case search above
/// finds the bound violated: the check can fail.
#[test]
fn dropping_couplings_without_inflation_is_caught() {
    let mut caught = 0;
    for seed in 0..6u64 {
        let (given, groups) = near_block(4, 1e-3, 7000 + seed);
        let n = given.dim();
        let mut of = vec![0; n];
        for (g, group) in groups.iter().enumerate() {
            for &i in group {
                of[i] = g;
            }
        }
        let drop = |m: &DMatrix<f64>| {
            DMatrix::from_fn(n, n, |i, j| if of[i] == of[j] { m[(i, j)] } else { 0.0 })
        };
        let dropped = FusionProblem {
            P_a: drop(&given.P_a),
            P_b: drop(&given.P_b),
            ..given.clone()
        };
        let nm = non_monolithic_ci(&dropped, Criterion::Trace).unwrap();
        let scale = nm.fused.P.amax();
        let violated = (0..n).any(|i| {
            let v = DVector::from_fn(n, |k, _| f64::from(k == i));
            let slack = &nm.fused.P
                - &nm.fused.K_a * &given.P_a * nm.fused.K_a.transpose()
                - &nm.fused.K_b * &given.P_b * nm.fused.K_b.transpose();
            let eig = SymmetricEigen::new((&slack + slack.transpose()) * 0.5);
            eig.eigenvectors
                .column_iter()
                .map(|c| c.into_owned())
                .chain([v])
                .any(|v| {
                    worst_in_direction(&given, &nm.fused, &v)
                        > v.dot(&(&nm.fused.P * &v)) + 1e-8 * scale
                })
        });
        caught += usize::from(violated);
    }
    assert!(
        caught > 0,
        "the worst-case check never fails without inflation"
    );
}

#[test]
fn exact_zeros_come_back_bit_for_bit() {
    let p = crate::common::paper_example();
    let absorbed = absorb_couplings(&p, &StructureSettings::default()).unwrap();
    assert_eq!(absorbed.problem, p);
    assert!(absorbed.structure.couplings.is_empty());
    let req: FuseRequest = serde_json::from_str(
        r#"{"pa": [[3,0],[0,1]], "pb": [[1,0],[0,4]], "pab_unknown": [[true,false],[false,true]], "method": "nmci"}"#,
    )
    .unwrap();
    let res = fuse(&req).unwrap();
    assert_eq!(res.p, vec![vec![1.0, 0.0], vec![0.0, 1.0]]);
    assert_eq!(res.structure, None);
    assert!(!fuse_json(&serde_json::to_string(&req).unwrap())
        .unwrap()
        .contains("structure"));
}

#[test]
fn declared_blocks_imply_the_pattern() {
    let (pa, pb) = cv_pair(0.3);
    let mut declared = FuseRequest::new(Method::Nmci, rows(&pa), rows(&pb));
    declared.pair.blocks = Some(vec![vec![0, 1], vec![2, 3]]);
    let mut patterned = FuseRequest::new(Method::Nmci, rows(&pa), rows(&pb));
    patterned.pair.pab_unknown = Some(per_axis_pattern());
    let (d, p) = (fuse(&declared).unwrap(), fuse(&patterned).unwrap());
    assert_eq!(d.p, p.p);
    assert_eq!(
        d.structure.as_ref().unwrap().blocks,
        vec![vec![0, 1], vec![2, 3]]
    );
    // Given with the pattern, they agree: the same numbers.
    patterned.pair.blocks = declared.pair.blocks.clone();
    assert_eq!(fuse(&patterned).unwrap().p, d.p);
    // The certified rule keeps the blocks too; the sampled SDP solves the deflated problem (its
    // blocks kept) and says so.
    let mut cert = declared.clone();
    cert.method = Method::Certified;
    let cert = fuse(&cert).unwrap();
    assert!(cert.structure.as_ref().unwrap().absorbed);
    assert!(
        cert.trace <= d.trace * (1.0 + 1e-6),
        "{} {}",
        cert.trace,
        d.trace
    );
    let mut sdp = declared.clone();
    sdp.method = Method::Sdp;
    sdp.options.samples = Some(50);
    let sdp = fuse(&sdp).unwrap();
    let s = sdp.structure.as_ref().unwrap();
    assert!(s.absorbed && !s.couplings.is_empty());
    assert!(
        s.note.as_deref().unwrap().contains("diagonal lowered"),
        "{:?}",
        s.note
    );
    let Details::Sdp(details) = &sdp.details else {
        panic!("sdp details")
    };
    assert_eq!(details.blocks.len(), 2);
    let bracket = details.bracket.unwrap();
    assert!(bracket.lower <= bracket.upper);
    // The cutting planes stop on their own bracket: they solve the covariances as given.
    let mut cuts = declared.clone();
    cuts.method = Method::SdpCuts;
    let cuts = fuse(&cuts).unwrap();
    let s = cuts.structure.unwrap();
    assert!(!s.absorbed && s.couplings.is_empty());
    assert!(s.note.unwrap().contains("not absorbed"));
}

/// The sampled SDP's lower end on the deflated problem is a lower bound for the *given*
/// coupled problem: below the cutting planes' proven upper end on the given problem (a 2-state
/// problem, where their bracket closes). The same SDP on the absorbed (inflated) problem would
/// not be: its lower end is above that upper end, so the check can fail.
#[test]
fn the_deflated_lower_end_holds_for_the_coupled_problem() {
    let c = 1e-3;
    let pa = DMatrix::from_row_slice(2, 2, &[3.0, c * 3f64.sqrt(), c * 3f64.sqrt(), 1.0]);
    let pb = DMatrix::from_row_slice(2, 2, &[1.0, -c * 2.0, -c * 2.0, 4.0]);
    let given =
        FusionProblem::from_covariances(pa.clone(), pb.clone(), CrossPattern::diagonal(2)).unwrap();
    let mut req = FuseRequest::new(Method::Sdp, rows(&pa), rows(&pb));
    req.pair.pab_unknown = Some(vec![vec![true, false], vec![false, true]]);
    req.pair.coupling_tol = Some(2.0 * c);
    req.options.samples = Some(100);
    let sdp = fuse(&req).unwrap();
    let Details::Sdp(details) = &sdp.details else {
        panic!("sdp details")
    };
    assert_eq!(details.blocks.len(), 2);
    let lower = details.bracket.unwrap().lower;
    let cuts = optimal_fusion_cuts(&given, &CutsSettings::default()).unwrap();
    let upper_given = cuts.certified_trace.unwrap();
    assert!(lower <= upper_given, "{lower} above {upper_given}");
    let settings = StructureSettings {
        coupling_tol: 2.0 * c,
        ..StructureSettings::default()
    };
    let absorbed = absorb_couplings(&given, &settings).unwrap();
    let inflated = optimal_fusion(
        &absorbed.problem,
        &SdpSettings {
            samples: 100,
            ..SdpSettings::default()
        },
    )
    .unwrap();
    assert!(
        inflated.lower_bound > upper_given,
        "the inflated problem's lower end {} is not above the given optimum's upper end {upper_given}",
        inflated.lower_bound
    );
}

#[test]
fn n_way_nmci_absorbs_per_estimate() {
    let (pa, pb) = cv_pair(0.3);
    let (pc, _) = cv_pair(0.7);
    let estimates: Vec<NwayEstimate> = [&pa, &pb, &pc]
        .iter()
        .map(|p| NwayEstimate {
            p: rows(p),
            x: None,
        })
        .collect();
    let mut req = FuseRequest::new(Method::Nmci, vec![], vec![]);
    req.estimates = Some(estimates);
    req.pair.blocks = Some(vec![vec![0, 1], vec![2, 3]]);
    let res = fuse(&req).unwrap();
    let s = res.structure.unwrap();
    assert_eq!(s.blocks, vec![vec![0, 1], vec![2, 3]]);
    assert!(!s.couplings.is_empty());
    assert!(s.couplings.iter().any(|c| c.matrix == "estimates[2].p"));
    let Details::Nway { blocks, .. } = res.details else {
        panic!("N-way details")
    };
    assert_eq!(blocks.len(), 2);
    // Without declared blocks, pairs not listed are wholly unknown: one block, as before.
    req.pair.blocks = None;
    let res = fuse(&req).unwrap();
    let Details::Nway { blocks, .. } = res.details else {
        panic!("N-way details")
    };
    assert_eq!(blocks.len(), 1);
}

/// Each refusal names its field, through the JSON contract.
#[test]
fn refusals_name_their_field() {
    let run = |extra: &str| {
        let text = format!(
            r#"{{"pa": [[2,0,0,0.4],[0,1,0,0],[0,0,1,0],[0.4,0,0,1]], "pb": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], "method": "nmci", {extra}}}"#
        );
        let req: FuseRequest = serde_json::from_str(&text).unwrap();
        let e = fuse(&req).unwrap_err();
        (e.field(), e.to_string())
    };
    let (field, message) = run(r#""blocks": [[0,1],[2,3]]"#);
    assert_eq!(field.as_deref(), Some("pa"));
    assert!(
        message.contains("pa[0][3] = 0.4 couples blocks 0 and 1"),
        "{message}"
    );
    for (blocks, says) in [
        ("[[0,1],[2]]", "state 3 is in no block"),
        ("[[0,1],[1,2,3]]", "state 1 is in two blocks"),
        ("[[0,1,2,3,4]]", "state 4 does not exist"),
    ] {
        let (field, message) = run(&format!(r#""blocks": {blocks}"#));
        assert_eq!(field.as_deref(), Some("blocks"), "{message}");
        assert!(message.contains(says), "{message}");
    }
    let (field, message) = run(
        r#""blocks": [[0,3],[1],[2]], "pab_unknown": [[true,true,false,false],[false,true,false,false],[false,false,true,false],[false,false,false,true]]"#,
    );
    assert_eq!(field.as_deref(), Some("pab_unknown"));
    assert!(message.contains("pab_unknown[0][1]"), "{message}");
    for tol in ["-1", "2"] {
        let (field, message) = run(&format!(r#""coupling_tol": {tol}"#));
        assert_eq!(field.as_deref(), Some("coupling_tol"), "{message}");
    }
}

/// The note's advice works when followed (the audit's request: a coupling of 1.0368e-9
/// relative, just above the default tolerance, once printed "1.0e-9", advice that still
/// gave one block): the suggested `coupling_tol` gives the blocks the note promises, and the
/// coupling is never printed at or below the tolerance beside it; the declared blocks'
/// refusal prints its coupling the same way.
#[test]
fn the_structure_notes_advice_works_when_followed() {
    let request = |extra: &str| {
        let text = format!(
            r#"{{"pa":[[3,1.8e-9],[1.8e-9,1]],"pb":[[1,0],[0,4]],"pab_unknown":[[true,false],[false,true]],"method":"nmci"{extra}}}"#
        );
        let req: FuseRequest = serde_json::from_str(&text).unwrap();
        fuse(&req)
    };
    let r = request("").unwrap();
    assert_eq!(r.blocks().map(|b| b.len()), Some(1));
    let note = r.structure.as_ref().unwrap().note.clone().unwrap();
    // The word after `marker` in `text`.
    let word = |text: &str, marker: &str| -> String {
        text.split(marker)
            .nth(1)
            .and_then(|rest| rest.split(' ').next())
            .unwrap_or_else(|| panic!("no {marker:?} in {text}"))
            .to_string()
    };
    let advice = word(&note, "coupling_tol = ");
    let promised: usize = word(&note, "would give ").parse().unwrap();
    let coupling: f64 = word(&note, "a coupling of ").parse().unwrap();
    assert!(coupling > 1e-9, "{note}");
    let followed = request(&format!(r#","coupling_tol":{advice}"#)).unwrap();
    assert_eq!(followed.blocks().map(|b| b.len()), Some(promised), "{note}");
    assert_eq!(promised, 2, "{note}");
    // Declared blocks at the default tolerance: refused, the coupling printed above it.
    let e = request(r#","blocks":[[0],[1]]"#).unwrap_err().to_string();
    let shown: f64 = word(&e, "(").parse().unwrap();
    assert!(shown > 1e-9, "{e}");
}
