//! Every validation error path, in the Rust API and through the JSON contract.

use crate::common;

use common::*;
use nalgebra::{DMatrix, DVector};
use nmci::{
    certify::*, contract::*, explore::*, nway::*, rules::*, sample::*, sdp::*, structure::*, *,
};

fn problem(P_a: DMatrix<f64>, P_b: DMatrix<f64>) -> Result<FusionProblem, InputError> {
    FusionProblem::from_covariances(P_a, P_b, CrossPattern::fully_unknown(2))
}

#[test]
fn covariance_errors_name_the_problem() {
    let I = DMatrix::<f64>::identity(2, 2);
    let e = problem(DMatrix::zeros(0, 0), I.clone()).unwrap_err();
    assert_eq!(e.to_string(), "P_a is empty");

    let e = validate_covariance("P_a", &DMatrix::zeros(2, 3)).unwrap_err();
    assert_eq!(e.to_string(), "P_a is not square (2×3)");

    let mut nan = I.clone();
    nan[(1, 0)] = f64::NAN;
    let e = problem(nan, I.clone()).unwrap_err();
    assert_eq!(e.to_string(), "P_a has a non-finite entry at (1, 0)");

    let asym = DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.4, 2.0]);
    let e = problem(I.clone(), asym).unwrap_err();
    assert_eq!(
        e.to_string(),
        "P_b is not symmetric: entry (0, 1) is 0.5 but (1, 0) is 0.4"
    );

    // Within the relative tolerance: accepted and symmetrised.
    let nearly = DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.5 + 1e-12, 2.0]);
    let p = problem(I.clone(), nearly).unwrap();
    assert_eq!(p.P_b[(0, 1)], p.P_b[(1, 0)]);

    let e = problem(I.clone(), diag(&[1.0, -0.3])).unwrap_err();
    assert_eq!(
        e.to_string(),
        "P_b is not positive definite (smallest eigenvalue -3.000000e-1)"
    );
    assert!(
        matches!(e, InputError::NotPositiveDefinite { min_eigenvalue, .. } if (min_eigenvalue + 0.3).abs() < 1e-15)
    );

    let e = problem(I.clone(), diag(&[1.0, 0.0])).unwrap_err();
    assert!(e.to_string().starts_with("P_b is not positive definite"));

    // Too close to singular for the verified test (its shift is ~9e-16 here): judged by the
    // floating-point Cholesky and the computed smallest eigenvalue, on either side of zero.
    assert!(problem(I.clone(), diag(&[1.0, 5e-16])).is_ok());
    // Variances of very different orders: positive definite (proven on the matrix
    // equilibrated by powers of two) but singular to rounding as given, so refused as
    // ill-conditioned — before, as "not positive definite (smallest eigenvalue 0)", false.
    let mixed = DMatrix::from_row_slice(2, 2, &[1e10, 0.5e-3, 0.5e-3, 1e-16]); // ρ = 0.5
    for (P_a, P_b) in [
        (I.clone(), diag(&[1.0, 1e-17])),
        (diag(&[1e160, 1.0]), I.clone()),
        (I.clone(), mixed),
    ] {
        let e = problem(P_a, P_b).unwrap_err();
        assert!(matches!(e, InputError::IllConditioned { .. }), "{e}");
        assert!(
            e.to_string()
                .contains("is positive definite but too ill-conditioned"),
            "{e}"
        );
    }
    // Equilibration does not make an indefinite matrix pass: correlation 1.5.
    let bad = DMatrix::from_row_slice(2, 2, &[1e10, 1.5e-3, 1.5e-3, 1e-16]);
    let e = problem(I.clone(), bad).unwrap_err();
    assert!(matches!(e, InputError::NotPositiveDefinite { .. }), "{e}");
    // All zero: symmetric (no tolerance issue at scale 0), not positive definite.
    let e = problem(I.clone(), DMatrix::zeros(2, 2)).unwrap_err();
    assert!(matches!(e, InputError::NotPositiveDefinite { .. }), "{e}");
    // The symmetry tolerance is relative to the largest entry: 1e-4 off at scale 1e6 passes.
    let big = DMatrix::from_row_slice(2, 2, &[1e6, 5e5, 5e5 + 1e-4, 1e6]);
    assert!(problem(I.clone(), big).is_ok());
    let e = problem(I.clone(), diag(&[1.0, -5e-16])).unwrap_err();
    assert!(
        matches!(e, InputError::NotPositiveDefinite { min_eigenvalue, .. } if (min_eigenvalue + 5e-16).abs() < 1e-16),
        "{e}"
    );
    // The same judgement at a size that takes the verified test's path when the matrix is
    // well conditioned: a 6 × 6 with one eigenvalue −1e-9, and the same with +1e-9.
    let q = nalgebra::linalg::QR::new(DMatrix::from_fn(6, 6, |i, j| {
        ((i * 7 + j * 3) % 5) as f64 - 2.0 + if i == j { 4.0 } else { 0.0 }
    }))
    .q();
    let with_smallest = |l: f64| {
        let d = diag(&[l, 1.0, 2.0, 3.0, 4.0, 5.0]);
        let m = &q * d * q.transpose();
        (&m + m.transpose()) * 0.5
    };
    validate_covariance("P_b", &with_smallest(1e-9)).unwrap();
    let e = validate_covariance("P_b", &with_smallest(-1e-9)).unwrap_err();
    assert!(
        matches!(e, InputError::NotPositiveDefinite { min_eigenvalue, .. } if (min_eigenvalue + 1e-9).abs() < 1e-12),
        "{e}"
    );

    let e = problem(I.clone(), DMatrix::identity(3, 3)).unwrap_err();
    assert_eq!(
        e.to_string(),
        "P_b has size 3, expected 2 (the size of P_a)"
    );
}

/// A 2 × 2 covariance (row-major) that is positive definite as floats (smallest eigenvalue
/// 1.1044 with 60 digits) but too close to singular for the floating-point checks to decide.
const UNDECIDABLE: [f64; 4] = [
    1.5547804921864044e16,
    -2.2527755614633864e16,
    -2.2527755614633864e16,
    3.264124907555265e16,
];

/// Matrices whose definiteness the floating-point checks cannot decide (condition numbers near 1/ε,
/// rotated away from the axes) are called singular to working precision. Both below are
/// positive definite as floats (smallest eigenvalues 1.1044 and 5696.21, computed with 60
/// digits); they were refused as "not positive definite (smallest eigenvalue 0)" and
/// "(… −32768)". A vector with `vᵀ P v ≤ 0` is proven before a matrix is called indefinite.
#[test]
fn matrices_floating_point_cannot_decide_are_called_singular_not_indefinite() {
    let I = DMatrix::<f64>::identity(2, 2);
    for m in [
        UNDECIDABLE,
        [
            6.99001839616835e18,
            -5.88638978442722e19,
            -5.88638978442722e19,
            4.9570090850122354e20,
        ],
    ] {
        let e = problem(I.clone(), DMatrix::from_row_slice(2, 2, &m)).unwrap_err();
        assert!(matches!(e, InputError::Singular { .. }), "{e}");
        assert!(
            e.to_string()
                .starts_with("P_b is singular to working precision"),
            "{e}"
        );
    }
    // A clearly indefinite matrix of the same size and scale is still called indefinite.
    let e = problem(
        I.clone(),
        DMatrix::from_row_slice(2, 2, &[1.5e16, 3.0e16, 3.0e16, 3.2e16]),
    )
    .unwrap_err();
    assert!(matches!(e, InputError::NotPositiveDefinite { .. }), "{e}");
}

/// A covariance whose factorization fails inside a rule (here N-way CI's inverses, reached with
/// estimates built without [`Estimate::new`]'s checks) gets the checks' own refusal: called
/// not positive definite only when that is proven. The first matrix of the test above was
/// called "estimates[2].p is not positive definite (smallest eigenvalue 0)" here before.
#[test]
fn a_covariance_that_fails_to_factor_inside_a_rule_is_not_called_indefinite_unless_proven() {
    let I = DMatrix::<f64>::identity(2, 2);
    let estimate = |P: DMatrix<f64>| Estimate {
        x: DVector::zeros(2),
        P,
    };
    let undecidable = DMatrix::from_row_slice(2, 2, &UNDECIDABLE);
    let indefinite = DMatrix::from_row_slice(2, 2, &[1.5e16, 3.0e16, 3.0e16, 3.2e16]);
    let fuse = |third: DMatrix<f64>| {
        covariance_intersection_nway(
            &[estimate(I.clone()), estimate(&I * 2.0), estimate(third)],
            Criterion::Trace,
        )
        .unwrap_err()
    };
    let e = fuse(undecidable);
    assert!(matches!(e, InputError::Singular { .. }), "{e}");
    assert!(
        e.to_string()
            .starts_with("estimates[2].p is singular to working precision"),
        "{e}"
    );
    let e = fuse(indefinite);
    assert!(matches!(e, InputError::NotPositiveDefinite { .. }), "{e}");
    assert!(
        e.to_string()
            .starts_with("estimates[2].p is not positive definite"),
        "{e}"
    );
}

/// A pair that passes validation but whose ratios the balanced pencil cannot resolve (found by
/// a random search over condition numbers 10¹²…10¹⁷): a typed error naming the pair, not a
/// false "not positive definite".
#[test]
fn a_pair_beyond_what_the_pencil_resolves_is_refused_by_name() {
    let P_a = DMatrix::from_row_slice(
        3,
        3,
        &[
            9456971981890842.0,
            1.7970854623290732e16,
            -79469921559937.75,
            1.7970854623290732e16,
            3.414957949555273e16,
            -151014876330897.53,
            -79469921559937.75,
            -151014876330897.53,
            668006874683.9958,
        ],
    );
    let P_b = DMatrix::from_row_slice(
        3,
        3,
        &[
            2.594663738022037e18,
            -8.031768188167049e18,
            -6.773475233204289e18,
            -8.031768188167049e18,
            2.4862324743716143e19,
            2.096726153391973e19,
            -6.773475233204289e18,
            2.096726153391973e19,
            1.7682433190657229e19,
        ],
    );
    let p = FusionProblem::from_covariances(P_a, P_b, CrossPattern::fully_unknown(3)).unwrap();
    for e in [
        covariance_intersection(&p, Criterion::Trace).unwrap_err(),
        inverse_covariance_intersection(&p, Criterion::Trace).unwrap_err(),
        ellipsoidal_intersection(&p).unwrap_err(),
    ] {
        assert!(matches!(e, InputError::UnresolvedPair { .. }), "{e}");
        assert!(e.to_string().contains("rescale the states"), "{e}");
    }
}

#[test]
fn vector_and_pattern_errors() {
    let I = DMatrix::<f64>::identity(2, 2);
    let e = FusionProblem::new(
        DVector::zeros(3),
        I.clone(),
        DVector::zeros(2),
        I.clone(),
        CrossPattern::diagonal(2),
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "x_a has size 3, expected 2 (the size of P_a)"
    );
    let e = FusionProblem::new(
        DVector::zeros(2),
        I.clone(),
        DVector::from_vec(vec![0.0, f64::INFINITY]),
        I.clone(),
        CrossPattern::diagonal(2),
    )
    .unwrap_err();
    assert_eq!(e.to_string(), "x_b[1] is not finite (NaN or ±∞)");
    let e = FusionProblem::new(
        DVector::zeros(2),
        I.clone(),
        DVector::zeros(2),
        I.clone(),
        CrossPattern::diagonal(3),
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "pab_unknown has size 3, expected 2 (the size of P_a)"
    );
    let e = CrossPattern::from_rows(&[vec![true, false], vec![true]]).unwrap_err();
    assert_eq!(e.to_string(), "pab_unknown is not square (2×1)");
}

fn run(json: &str) -> Result<String, String> {
    fuse_json(json).map_err(|e| e.to_string())
}

#[test]
fn request_errors() {
    let ok = r#""pa": [[1, 0], [0, 1]], "pb": [[2, 0], [0, 2]]"#;
    assert!(run(&format!(r#"{{{ok}, "method": "ci"}}"#)).is_ok());
    let cases: [(&str, &str, Option<&str>); 33] = [
        (r#"{"pa": [[1]], "pb": [[1]], "method": "ci", "extra": 1}"#,
            "unknown field `extra`", Some("extra")),
        (r#"{"pa": [[1]], "pb": [[1]]}"#, "missing field `method`", Some("method")),
        (r#"{"pa": [[1]], "pb": [[1]], "method": "best"}"#,
            "`method`: unknown method `best`; the methods are ci, nmci", Some("method")),
        (r#"{"pa": [[1]], "pb": [[1]], "method": "ci", "criterion": "max"}"#,
            "unknown variant `max`", None),
        (r#"{"pa": [[1, 0], [0]], "pb": [[1]], "method": "ci"}"#,
            "P_a is not square (2×1)", Some("pa")),
        (r#"{"pa": [], "pb": [[1]], "method": "ci"}"#, "P_a is empty", Some("pa")),
        (r#"{"pa": [["a"]], "pb": [[1]], "method": "ci"}"#,
            "invalid request", None),
        ("not json", "invalid request", None),
        (&format!(r#"{{{ok}, "method": "ci", "samples": 10}}"#),
            "`samples` applies to method \"sdp\" only", Some("samples")),
        (&format!(r#"{{{ok}, "method": "nmci", "seed": 1}}"#),
            "`seed` applies to methods \"sdp\" and \"sdp_cuts\" only", Some("seed")),
        (&format!(r#"{{{ok}, "method": "sdp", "samples": 0}}"#),
            "`samples` must be at least 1", Some("samples")),
        (&format!(r#"{{{ok}, "method": "sdp", "max_trials": 0}}"#),
            "`max_trials` must be at least 1", Some("max_trials")),
        (&format!(r#"{{{ok}, "method": "sdp", "criterion": "logdet"}}"#),
            "not available", Some("criterion")),
        (&format!(r#"{{{ok}, "method": "ci", "xa": [1, 2, 3]}}"#),
            "x_a has size 3", Some("xa")),
        (&format!(r#"{{{ok}, "method": "ci", "pab_unknown": [[true]]}}"#),
            "pab_unknown has size 1", Some("pab_unknown")),
        (r#"{"pa": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], "pb": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], "method": "sdp", "samples": 50, "max_trials": 100}"#,
            "rejection sampler accepted only", None),
        (&format!(r#"{{{ok}, "method": "ci", "time_limit": 5}}"#),
            "`time_limit` applies to methods \"certified\", \"sdp\" and \"sdp_cuts\" only", Some("time_limit")),
        (&format!(r#"{{{ok}, "method": "nmci", "level": 2}}"#),
            "`level` applies to methods", Some("level")),
        (&format!(r#"{{{ok}, "method": "sdp", "time_limit": -1}}"#),
            "`time_limit` must be a positive number of seconds (got -1)", Some("time_limit")),
        (&format!(r#"{{{ok}, "method": "certified", "time_limit": 0}}"#),
            "`time_limit` must be a positive number of seconds (got 0)", Some("time_limit")),
        (&format!(r#"{{{ok}, "method": "certified", "level": 7}}"#),
            "`level` must be in 1..=6 (got 7)", Some("level")),
        (&format!(r#"{{{ok}, "method": "certified", "level": 0}}"#),
            "`level` must be in 1..=6 (got 0)", Some("level")),
        (&format!(r#"{{{ok}, "method": "certified", "sectors": 1}}"#),
            "`sectors` must be in 2..=64 (got 1)", Some("sectors")),
        (&format!(r#"{{{ok}, "method": "sdp_cuts", "sectors": 65}}"#),
            "`sectors` must be in 2..=64 (got 65)", Some("sectors")),
        (&format!(r#"{{{ok}, "method": "ci", "sectors": 16}}"#),
            "`sectors` applies to methods", Some("sectors")),
        (&format!(r#"{{{ok}, "method": "certified", "cones": 8}}"#),
            "`cones` must be 4, 16 or 64 (got 8)", Some("cones")),
        (&format!(r#"{{{ok}, "method": "nmci", "cones": 16}}"#),
            "`cones` applies to methods", Some("cones")),
        (&format!(r#"{{{ok}, "method": "nmci", "max_cones": 16}}"#),
            "`max_cones` applies to methods", Some("max_cones")),
        (&format!(r#"{{{ok}, "method": "sdp", "cuts_tolerance": 1e-9}}"#),
            "`cuts_tolerance` applies to method \"sdp_cuts\" only", Some("cuts_tolerance")),
        (&format!(r#"{{{ok}, "method": "sdp_cuts", "cuts_tolerance": 0}}"#),
            "`cuts_tolerance` must be positive and finite (got 0)", Some("cuts_tolerance")),
        (&format!(r#"{{{ok}, "method": "sdp_cuts", "cuts_tolerance": -1e-9}}"#),
            "`cuts_tolerance` must be positive and finite (got -0.000000001)", Some("cuts_tolerance")),
        (r#"{"pa": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], "pb": [[2,0,0,0],[0,2,0,0],[0,0,2,0],[0,0,0,2]], "pab_unknown": [[true,true,true,true],[true,true,true,true],[true,true,true,true],[true,true,true,false]], "method": "certified", "level": 4}"#,
            "the level-4 certificate of a 4-state block needs a PSD cone of 300 rows, above the limit of 90 (max_cone)", None),
        (r#"{"pa": [[3,1,0],[1,2,0.5],[0,0.5,1]], "pb": [[2,0,0.3],[0,1,0],[0.3,0,2]], "pab_unknown": [[true,false,true],[true,true,false],[false,true,true]], "method": "certified", "level": 3, "time_limit": 0.001}"#,
            "the certified bound's SDP stopped at its time limit of 0.001 s", None),
    ];
    // Each error names the request field at fault where one is (the page places its
    // messages by it; `None` where no single field is).
    for (json, expected, field) in cases {
        let error = fuse_json(json).unwrap_err();
        assert_eq!(error.field().as_deref(), field, "{json}: {error}");
        let err = error.to_string();
        assert!(
            err.contains(expected),
            "{json}\n  gave: {err}\n  expected to contain: {expected}"
        );
        assert!(!err.contains('\n'), "one-line message: {err}");
    }
}

#[test]
fn response_fields_per_method() {
    let base = r#""pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]], "pab_unknown": [[true, false], [false, true]], "xa": [1, 2], "xb": [3, 4]"#;
    let ci: FuseResponse =
        serde_json::from_str(&run(&format!(r#"{{{base}, "method": "ci"}}"#)).unwrap()).unwrap();
    assert!(matches!(ci.details, Details::Omega(_)));
    assert!(ci.blocks().is_none());
    let ci_json = run(&format!(r#"{{{base}, "method": "ci"}}"#)).unwrap();
    assert!(!ci_json.contains("blocks") && !ci_json.contains("status"));
    let nm: FuseResponse =
        serde_json::from_str(&run(&format!(r#"{{{base}, "method": "nmci"}}"#)).unwrap()).unwrap();
    assert_eq!(nm.x, vec![3.0, 2.0]);
    assert_eq!(nm.blocks(), Some(&vec![vec![0], vec![1]]));
    assert_eq!(nm.det, 1.0);
    let text = run(&format!(
        r#"{{{base}, "method": "sdp", "samples": 60, "seed": 4}}"#
    ))
    .unwrap();
    let sdp: FuseResponse = serde_json::from_str(&text).unwrap();
    assert!(sdp.omega().is_none() && !text.contains("omega"));
    let Details::Sdp(d) = &sdp.details else {
        panic!("{:?}", sdp.details)
    };
    assert_eq!(d.samples, 60);
    assert!(d.iterations > 0 && d.acceptance_rate == 1.0);
    assert!((sdp.x[0] - 3.0).abs() < 1e-6 && (sdp.x[1] - 2.0).abs() < 1e-6);
}

/// The request parts are flattened into one JSON object, so serde's `deny_unknown_fields`
/// cannot apply: the wire structs collect what no part took. The error names the field and
/// lists exactly the fields a request has (read from a serialised request, so the list cannot
/// drift from the parts), for both kinds of request; a request with every field set survives
/// the round trip through JSON.
#[test]
fn unknown_fields_are_named_and_the_known_ones_listed() {
    let listed = |err: &str| -> std::collections::BTreeSet<String> {
        let list = err.split("expected one of ").nth(1).expect(err);
        list.split(", ")
            .map(|f| f.trim_matches('`').to_string())
            .collect()
    };
    let full: FuseRequest = serde_json::from_str(
        r#"{"pa": [[2]], "pb": [[3]], "xa": [1], "xb": [0], "pab_unknown": [[true]],
            "method": "sdp", "criterion": "trace", "samples": 20, "seed": 3, "max_trials": 5000,
            "sampler": "auto", "time_limit": 30, "level": 2, "sectors": 8, "cones": 16}"#,
    )
    .unwrap();
    assert_eq!(full.pair.xa, Some(vec![1.0]));
    assert_eq!(full.options.sampler, Some(SamplerKind::Auto));
    let again: FuseRequest = serde_json::from_value(serde_json::to_value(&full).unwrap()).unwrap();
    assert_eq!(again, full);
    let err = fuse_json(r#"{"pa": [[1]], "pb": [[1]], "method": "ci", "speed": 1}"#).unwrap_err();
    assert_eq!(err.field().as_deref(), Some("speed"));
    let fuse_fields = listed(&err.to_string());
    let expected: std::collections::BTreeSet<String> = [
        "pa",
        "pb",
        "xa",
        "xb",
        "pab_unknown",
        "blocks",
        "coupling_tol",
        "method",
        "criterion",
        "samples",
        "seed",
        "max_trials",
        "sampler",
        "time_limit",
        "level",
        "sectors",
        "cones",
        "max_cones",
        "cuts_tolerance",
        "estimates",
        "patterns",
    ]
    .map(String::from)
    .into();
    assert_eq!(fuse_fields, expected);
    // The explorer: the same parts, no method, the region instead of N-way.
    let err = serde_json::from_str::<ExploreRequest>(r#"{"pa": [[1]], "pb": [[1]], "bogus": 1}"#)
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("unknown field `bogus`"), "{err}");
    let mut explore_fields = expected.clone();
    for f in ["method", "estimates", "patterns"] {
        explore_fields.remove(f);
    }
    explore_fields.insert("region_samples".into());
    assert_eq!(listed(&err), explore_fields);
    // A field of a nested object is still checked by that object (`deny_unknown_fields`).
    let err = fuse_json(r#"{"estimates": [{"p": [[1]], "q": 1}, {"p": [[1]]}], "method": "ci"}"#)
        .unwrap_err()
        .to_string();
    assert!(err.contains("unknown field `q`"), "{err}");
}

/// One set of defaults: `Options::plan` of an empty request is every settings type's
/// `Default`, and the explorer's SDP with no options is `fuse`'s SDP with none.
#[test]
fn fuse_and_explore_run_one_plan_with_one_set_of_defaults() {
    let plan = Options::default().plan().unwrap();
    assert_eq!(plan.sdp, SdpSettings::default());
    assert_eq!(plan.certify, CertifySettings::default());
    assert_eq!(plan.cuts, CutsSettings::default());
    assert_eq!(plan.criterion, Criterion::Trace);
    // Options reach every settings type that takes them.
    let plan = Options {
        seed: Some(9),
        time_limit: Some(4.0),
        sectors: Some(8),
        max_trials: Some(1000),
        ..Default::default()
    }
    .plan()
    .unwrap();
    assert_eq!((plan.sdp.seed, plan.cuts.seed), (9, 9));
    assert_eq!(plan.sdp.sampler.max_trials, 1000);
    assert_eq!(plan.cuts.certify_settings, plan.certify);
    assert_eq!(plan.certify.sectors, Some(8));
    for t in [
        plan.sdp.time_limit,
        plan.certify.time_limit,
        plan.cuts.time_limit,
    ] {
        assert_eq!(t, Some(4.0));
    }
    let pair = r#""pa": [[3, 0.5], [0.5, 1]], "pb": [[1, 0], [0, 4]], "pab_unknown": [[true, false], [true, true]]"#;
    let fused: FuseResponse =
        serde_json::from_str(&fuse_json(&format!(r#"{{{pair}, "method": "sdp"}}"#)).unwrap())
            .unwrap();
    let explored = explore(
        &serde_json::from_str::<ExploreRequest>(&format!(r#"{{{pair}, "region_samples": 0}}"#))
            .unwrap(),
    )
    .unwrap();
    let sdp = explored.response(Method::Sdp).unwrap();
    assert_eq!((&sdp.x, &sdp.p), (&fused.x, &fused.p));
    let samples = |r: &FuseResponse| match &r.details {
        Details::Sdp(d) => d.samples,
        other => panic!("{other:?}"),
    };
    assert_eq!(samples(sdp), SdpSettings::default().samples);
    assert_eq!(samples(&fused), samples(sdp));
}

#[test]
fn covariances_out_of_the_float_range_are_named_so_not_called_indefinite() {
    // diag(1e308) is positive definite, but its symmetrisation and eigenvalues overflow;
    // diag(5e-324) is too, but nothing about a subnormal matrix can be judged. Before, both
    // were "not positive definite" (smallest eigenvalue NaN, resp. 0).
    for v in [1e308, 5e-324] {
        let e = FusionProblem::from_covariances(
            diag(&[v, v]),
            diag(&[1.0, 1.0]),
            CrossPattern::fully_unknown(2),
        )
        .unwrap_err();
        assert!(
            matches!(&e, InputError::OutOfRange { name, largest } if name == "P_a" && *largest == v),
            "{e}"
        );
        assert!(e
            .to_string()
            .starts_with("P_a is out of the range nmci computes in"));
    }
    // Below half the largest float the symmetrisation does not overflow: judged as usual.
    assert!(FusionProblem::from_covariances(
        diag(&[8e307, 8e307]),
        diag(&[1.0, 1.0]),
        CrossPattern::fully_unknown(2)
    )
    .is_ok());
}

/// Semi-definite covariances through the contract: `ci`, `nmci`, `ei` and `naive` fuse them in
/// the pseudo-inverse form (`fusion::semidefinite`), `ici` falls back to CI's, and the note
/// says so with the guarantee that holds; the certified rule and the SDPs refuse them as
/// before, and an indefinite matrix keeps its refusal.
#[test]
fn semidefinite_covariances_are_fused_in_the_pseudo_inverse_form_by_the_closed_form_rules() {
    let run = |pa: &str, method: &str| {
        fuse_json(&format!(
            r#"{{"pa": {pa}, "pb": [[2,0],[0,3]], "xa": [1, 2], "xb": [0, 0], "pab_unknown": [[true,false],[false,true]], "method": "{method}"}}"#
        ))
    };
    for pa in ["[[1,0],[0,0]]", "[[1,0],[0,1e-24]]"] {
        for method in ["ci", "nmci", "naive", "ei", "ici"] {
            let v: serde_json::Value = serde_json::from_str(&run(pa, method).unwrap()).unwrap();
            let note = v["structure"]["note"].as_str().unwrap();
            assert!(note.contains("pseudo-inverse form"), "{method}: {note}");
            // The rule that fused, and only a conservative one claims to be.
            let used = if method == "ici" { "ci" } else { method };
            assert_eq!(v["method"], used, "{method}: {v}");
            assert_eq!(
                note.contains("conservative for every cross-covariance"),
                ["ci", "nmci", "ici"].contains(&method),
                "{method}: {note}"
            );
            if pa.contains("1e-24") && method == "nmci" {
                // nmCI truncates each block on its own: in its block 1e-24 is a variance like
                // any other, and a's (the smaller) is taken, mean and all.
                assert_eq!(v["p"][1][1].as_f64(), Some(1e-24), "{v}");
                assert_eq!(v["x"][1].as_f64(), Some(2.0), "{v}");
                continue;
            }
            // State 1 is b's alone (a's claim of certainty is not trusted): its mean, and at
            // least b's variance.
            assert!(
                v["x"][1].as_f64().unwrap().abs() <= 1e-12,
                "{method} {pa}: {v}"
            );
            assert!(
                v["p"][1][1].as_f64().unwrap() >= 3.0 * (1.0 - 1e-12),
                "{method} {pa}: {v}"
            );
        }
        for method in ["certified", "sdp", "sdp_cuts"] {
            let e = run(pa, method).unwrap_err();
            assert_eq!(e.field().as_deref(), Some("pa"), "{method}: {e}");
        }
    }
    // nmCI: one weight per block, state 0 fused as CI of (1, 2) would be.
    let v: serde_json::Value =
        serde_json::from_str(&run("[[1,0],[0,0]]", "nmci").unwrap()).unwrap();
    assert_eq!(v["blocks"], serde_json::json!([[0], [1]]));
    assert_eq!(v["omega"][0], 1.0);
    let e = run("[[1,2],[2,1]]", "ci").unwrap_err();
    assert_eq!(
        e.to_string(),
        "P_a is not positive definite (smallest eigenvalue -1.000000e0)"
    );
}
