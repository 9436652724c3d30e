//! The registry of rules (`nmci::rules::RULES`) against what the code does: names are the JSON
//! contract's, the options and criteria it lists are exactly the ones a request may set, the
//! N-way flag is what `estimates` accepts, every response states the registry's guarantee,
//! and the guarantees are true — the conservative rules hold over drawn admissible
//! cross-covariances, each of the others has a drawn counterexample.

use nalgebra::DMatrix;
use nmci::{check::*, contract::*, rules::*, sample::*, structure::*, *};
use serde_json::json;

use crate::common::*;

#[test]
fn one_row_per_method_in_variant_order_with_distinct_names_labels_and_colours() {
    for (i, rule) in RULES.iter().enumerate() {
        assert_eq!(rule.method as usize, i);
        assert_eq!(rule.method.info(), rule);
        assert_eq!(
            serde_json::to_value(rule.method).unwrap(),
            json!(rule.name),
            "JSON form of {:?}",
            rule.method
        );
        let back: Method = serde_json::from_value(json!(rule.name)).unwrap();
        assert_eq!(back, rule.method);
        assert_eq!(Method::from_name(rule.name), Some(rule.method));
        let c = rule.colour;
        assert!(
            c.len() == 7 && c.starts_with('#') && c[1..].chars().all(|h| h.is_ascii_hexdigit()),
            "{c}"
        );
        for other in &RULES[..i] {
            assert_ne!(other.name, rule.name);
            assert_ne!(other.label, rule.label);
            assert_ne!(other.colour, rule.colour);
        }
    }
    let err = serde_json::from_value::<Method>(json!("best")).unwrap_err();
    assert!(err
        .to_string()
        .contains("unknown variant `best`, expected one of `ci`"));
    assert_eq!(rules().len(), RULES.len());
}

/// Serialised for the page and Python: every field, the legend and `unguaranteed`.
#[test]
fn the_serialised_registry() {
    let v = serde_json::to_value(RULES).unwrap();
    let ici = &v[Method::Ici as usize];
    assert_eq!(ici["name"], "ici");
    assert_eq!(ici["guarantee"], "common_information");
    assert_eq!(ici["legend"], "ICI (common information only)");
    assert_eq!(ici["unguaranteed"], true);
    assert_eq!(v[Method::Sdp as usize]["options"][0], "samples");
    assert_eq!(v[Method::Nmci as usize]["legend"], "nmCI");
    assert_eq!(v[Method::Nmci as usize]["criteria"], "both");
    assert_eq!(v[Method::Ci as usize]["nway"], true);
}

fn two_estimates(method: &str, extra: serde_json::Value) -> String {
    let mut r = json!({
        "pa": [[3.0, 0.5], [0.5, 1.0]], "pb": [[1.0, 0.0], [0.0, 4.0]],
        "pab_unknown": [[true, false], [true, true]], "method": method,
    });
    for (k, v) in extra.as_object().unwrap() {
        r[k] = v.clone();
    }
    r.to_string()
}

/// A request sets exactly the options its rule lists; the others are refused naming the field.
#[test]
fn the_options_a_rule_lists_are_the_ones_a_request_may_set() {
    let value = |o: RequestOption| match o {
        RequestOption::Samples => json!(20),
        RequestOption::MaxTrials => json!(1_000_000),
        RequestOption::Sampler => json!("hit_and_run"),
        RequestOption::Seed => json!(3),
        RequestOption::TimeLimit => json!(60.0),
        RequestOption::Level => json!(1),
        RequestOption::Sectors => json!(8),
        RequestOption::Cones => json!(4),
        RequestOption::MaxCones => json!(8),
        RequestOption::CutsTolerance => json!(1e-6),
    };
    for rule in &RULES {
        for option in RequestOption::ALL {
            let request = two_estimates(rule.name, json!({ option.field(): value(option) }));
            let result = fuse_json(&request);
            if rule.options.contains(&option) {
                assert!(result.is_ok(), "{}: {request}: {result:?}", rule.name);
            } else {
                let e = result.unwrap_err();
                assert_eq!(e.field().as_deref(), Some(option.field()), "{}", rule.name);
                assert!(e.to_string().contains("applies to"), "{e}");
            }
        }
    }
}

#[test]
fn the_criteria_a_rule_lists_are_the_ones_a_request_may_ask_for() {
    for rule in &RULES {
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let request = two_estimates(rule.name, json!({ "criterion": criterion }));
            let result = fuse_json(&request);
            assert_eq!(
                result.is_ok(),
                rule.criteria.allows(criterion),
                "{} {criterion:?}: {result:?}",
                rule.name
            );
            if let Err(e) = result {
                assert_eq!(e.field().as_deref(), Some("criterion"));
            }
        }
    }
}

#[test]
fn the_nway_flag_is_what_estimates_accepts() {
    for rule in &RULES {
        let request = json!({
            "estimates": [{"p": [[2.0, 0.0], [0.0, 1.0]]}, {"p": [[1.0, 0.0], [0.0, 3.0]]}],
            "method": rule.name,
        })
        .to_string();
        let result = fuse_json(&request);
        assert_eq!(result.is_ok(), rule.nway, "{}: {result:?}", rule.name);
        if let Err(e) = result {
            assert_eq!(e.field().as_deref(), Some("method"));
        }
    }
}

/// The response of a rule as a `Fused` (gains and bound) for the margin checks.
fn fused_of(problem: &FusionProblem, rule: &RuleInfo, extra: serde_json::Value) -> Fused {
    let rows = |m: &DMatrix<f64>| -> Vec<Vec<f64>> {
        (0..m.nrows())
            .map(|i| m.row(i).iter().copied().collect())
            .collect()
    };
    let n = problem.dim();
    let pattern: Vec<Vec<bool>> = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| problem.cross_pattern.is_unknown(i, j))
                .collect()
        })
        .collect();
    let mut request = json!({
        "pa": rows(&problem.P_a), "pb": rows(&problem.P_b), "pab_unknown": pattern,
        "method": rule.name,
    });
    for (k, v) in extra.as_object().unwrap() {
        request[k] = v.clone();
    }
    let response: FuseResponse =
        serde_json::from_str(&fuse_json(&request.to_string()).unwrap()).unwrap();
    assert_eq!(response.guarantee(), rule.guarantee, "{}", rule.name);
    if rule.guarantee == Guarantee::Relaxation {
        // What a relaxation carries instead of a guarantee: the proven bracket.
        assert!(response.bracket().unwrap().lower <= response.upper_bound().unwrap());
    }
    let m = |rows: &Vec<Vec<f64>>| DMatrix::from_fn(n, n, |i, j| rows[i][j]);
    Fused {
        x: nalgebra::DVector::from_vec(response.x.clone()),
        P: m(&response.p),
        K_a: m(response.pair_gains().unwrap().0),
        K_b: m(response.pair_gains().unwrap().1),
    }
}

/// Every rule on the same problems and the same drawn admissible cross-covariances: the
/// conservative ones never below `K P' Kᵀ` (beyond `10⁻⁹` of `tr P`), every other one below it
/// by more than `10⁻⁶` for some drawn `P'` on some problem (the sampled SDP with 5 samples).
/// The cutting-plane SDP is a relaxation too, but its loop runs until the worst case it can
/// find is violated by at most its tolerance: no drawn `P'` beats that by more than `10⁻⁶`
/// (a tolerance-level statement, not a guarantee).
#[test]
fn the_guarantees_are_true() {
    let mut r = rng(41);
    let mut problems = vec![FusionProblem::from_covariances(
        diag(&[3.0, 1.0]),
        diag(&[1.0, 4.0]),
        CrossPattern::fully_unknown(2),
    )
    .unwrap()];
    for n in [2, 3] {
        for _ in 0..3 {
            problems.push(random_problem(n, random_pattern(n, 0.7, &mut r), &mut r));
        }
    }
    let draws: Vec<Vec<DMatrix<f64>>> = problems
        .iter()
        .enumerate()
        .map(|(k, p)| {
            sample_cross_covariances(p, 1500, k as u64, SamplerSettings::hit_and_run())
                .unwrap()
                .cross
        })
        .collect();
    for rule in &RULES {
        let extra = match rule.method {
            Method::Sdp => json!({"samples": 5, "sampler": "hit_and_run"}),
            _ => json!({}),
        };
        let worst: Vec<f64> = problems
            .iter()
            .zip(&draws)
            .map(|(p, cross)| {
                let f = fused_of(p, rule, extra.clone());
                worst_margin(p, &f, cross).unwrap() / f.P.trace()
            })
            .collect();
        let lowest = worst.iter().copied().fold(f64::INFINITY, f64::min);
        if rule.guarantee.for_every_cross_covariance() {
            assert!(lowest >= -1e-9, "{}: {worst:?}", rule.name);
        } else if rule.method == Method::SdpCuts {
            assert!(lowest >= -1e-6, "{}: {worst:?}", rule.name);
        } else {
            assert!(lowest < -1e-6, "{}: no counterexample {worst:?}", rule.name);
        }
    }
}
