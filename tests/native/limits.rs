//! The request contract's size limits (`Limits` in the rule registry, `MAX_SAMPLES`,
//! `MAX_TRIALS`, `MAX_ESTIMATES`, `MAX_REQUEST_BYTES`): one past each limit is refused with
//! an error naming the field and the limit; at the limit the request is accepted. Also the
//! time limits that could not be represented (`1e30` s), which used to panic.

use nmci::{certify::*, contract::*, explore::*, rules::*, sample::*, *};

fn identity_rows(n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect()
}

fn request(method: Method, n: usize) -> FuseRequest {
    let pb = identity_rows(n)
        .iter()
        .map(|r| r.iter().map(|v| 2.0 * v).collect())
        .collect();
    FuseRequest::new(method, identity_rows(n), pb)
}

/// The pattern with unknown entries on the diagonal only (every state its own block).
fn diagonal_pattern(n: usize) -> Option<Vec<Vec<bool>>> {
    Some((0..n).map(|i| (0..n).map(|j| i == j).collect()).collect())
}

fn refused(req: &FuseRequest) -> (String, String) {
    match fuse(req) {
        Err(e @ RequestError::Invalid { .. }) => (e.field().unwrap(), e.to_string()),
        other => panic!(
            "{:?} n = {}: expected a refusal, got {other:?}",
            req.method,
            req.pair.pa.len()
        ),
    }
}

#[test]
fn one_state_past_each_rules_dimension_limit_is_refused_by_name() {
    for rule in RULES {
        let max = rule.limits.max_dim;
        let (field, message) = refused(&request(rule.method, max + 1));
        assert_eq!(field, "pa", "{message}");
        assert!(
            message.contains(&format!(
                "method \"{}\" accepts at most {max} states",
                rule.name
            )) && message.contains(&format!("has {}", max + 1)),
            "{message}"
        );
    }
    // Each input is checked, not only P_a: a long x_b, a wide pattern.
    let mut req = request(Method::Ci, 2);
    req.pair.xb = Some(vec![0.0; 1001]);
    assert_eq!(refused(&req).0, "xb");
    let mut req = request(Method::Sdp, 2);
    req.pair.pab_unknown = Some(vec![vec![true; 13]; 2]);
    assert_eq!(refused(&req).0, "pab_unknown");
    let mut req = request(Method::Ci, 2);
    req.pair.pb = identity_rows(1001);
    assert_eq!(refused(&req).0, "pb");
    let mut req = request(Method::Nmci, 0);
    req.estimates = Some(vec![
        NwayEstimate {
            x: None,
            p: identity_rows(2),
        },
        NwayEstimate {
            x: None,
            p: identity_rows(1001),
        },
    ]);
    assert_eq!(refused(&req).0, "estimates[1].p");
}

#[test]
fn the_sdp_rules_accept_their_dimension_limit_in_small_blocks() {
    // At max_dim with one-state blocks, the SDP rules run (no refusal).
    for method in [Method::Sdp, Method::SdpCuts, Method::Certified] {
        let n = method.info().limits.max_dim.min(12);
        let mut req = request(method, n);
        req.pair.pab_unknown = diagonal_pattern(n);
        if method == Method::Sdp {
            req.options.samples = Some(20);
        }
        let r = fuse(&req).unwrap_or_else(|e| panic!("{method}: {e}"));
        assert!(r.trace.is_finite());
    }
    // The closed-form rules at their limit (naive: one factorization).
    let r = fuse(&request(
        Method::Naive,
        RULES[Method::Naive as usize].limits.max_dim,
    ))
    .unwrap();
    assert!((r.trace - 1000.0 * 2.0 / 3.0).abs() < 1e-9);
}

#[test]
fn one_state_past_a_block_limit_is_refused_naming_the_pattern() {
    for method in [Method::Sdp, Method::SdpCuts, Method::Certified] {
        let max = method.info().limits.max_block;
        let (field, message) = refused(&request(method, max + 1));
        assert_eq!(field, "pab_unknown", "{message}");
        assert!(
            message.contains(&format!("of at most {max} states"))
                && message.contains(&format!("one block of {}", max + 1)),
            "{message}"
        );
        // At the block limit the request is not refused by it (a time limit bounds the solve:
        // a time-limit error is fine here, a refusal is not).
        let mut req = request(method, max);
        req.options.time_limit = Some(2.0);
        if method == Method::Sdp {
            req.options.samples = Some(20);
            req.options.sampler = Some(SamplerKind::HitAndRun);
        }
        match fuse(&req) {
            Ok(_) | Err(RequestError::Solve(SolveError::TimeLimit { .. })) => {}
            Err(e) => panic!("{method} at its block limit: {e}"),
        }
    }
    assert_eq!(MAX_BLOCK_DIM, CertifySettings::default().max_block_dim);
}

#[test]
fn counts_past_their_limits_are_refused_by_name() {
    let mut req = request(Method::Sdp, 2);
    req.options.samples = Some(MAX_SAMPLES + 1);
    let (field, message) = refused(&req);
    assert_eq!(field, "samples");
    assert!(
        message.contains(&format!("at most {MAX_SAMPLES}")),
        "{message}"
    );
    let mut req = request(Method::Sdp, 2);
    req.options.max_trials = Some(MAX_TRIALS + 1);
    assert_eq!(refused(&req).0, "max_trials");
    let mut req = request(Method::Sdp, 2);
    req.options.max_trials = Some(MAX_TRIALS);
    req.options.samples = Some(5);
    assert!(fuse(&req).is_ok());

    let estimate = NwayEstimate {
        x: None,
        p: identity_rows(2),
    };
    let mut req = request(Method::Ci, 0);
    req.pair.pa.clear();
    req.pair.pb.clear();
    req.estimates = Some(vec![estimate.clone(); MAX_ESTIMATES + 1]);
    let (field, message) = refused(&req);
    assert_eq!(field, "estimates");
    assert!(
        message.contains(&format!("at most {MAX_ESTIMATES}")),
        "{message}"
    );
    req.estimates = Some(vec![estimate; MAX_ESTIMATES]);
    let r = fuse(&req).unwrap();
    assert!((r.trace - 2.0).abs() < 1e-9, "{}", r.trace);
}

#[test]
fn a_request_text_past_the_byte_limit_is_refused_before_parsing() {
    // Not even JSON: the length is checked first.
    let text = " ".repeat(MAX_REQUEST_BYTES + 1);
    match fuse_json(&text) {
        Err(RequestError::TooLarge { bytes, limit }) => {
            assert_eq!((bytes, limit), (MAX_REQUEST_BYTES + 1, MAX_REQUEST_BYTES))
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_explorer_has_the_sampled_sdps_limits() {
    let max = Method::Sdp.info().limits.max_dim;
    let mut req = ExploreRequest {
        pair: PairInput::new(identity_rows(max + 1), identity_rows(max + 1)),
        options: Options::default(),
        region_samples: Some(MAX_SAMPLES + 1),
    };
    let field = |r: Result<Exploration, RequestError>| r.unwrap_err().field().unwrap();
    assert_eq!(field(explore(&req)), "pa");
    req.pair = PairInput::new(identity_rows(2), identity_rows(2));
    assert_eq!(field(explore(&req)), "region_samples");
    req.region_samples = None;
    req.options.samples = Some(MAX_SAMPLES + 1);
    assert_eq!(field(explore(&req)), "samples");
}

#[test]
fn time_limits_beyond_the_clock_are_no_limit() {
    // `Duration` cannot hold 1e30 s, and now + 1e19 s is no instant: both used to panic.
    for t in [1e19, 1e30, f64::MAX] {
        for method in [Method::Sdp, Method::SdpCuts, Method::Certified] {
            let mut req = request(method, 2);
            req.pair.pab_unknown = Some(vec![vec![true, false], vec![false, true]]);
            req.options.time_limit = Some(t);
            let r = fuse(&req).unwrap_or_else(|e| panic!("{method} {t}: {e}"));
            assert!((r.trace - 2.0).abs() < 1e-6, "{method} {t}: {}", r.trace);
        }
    }
}

/// The study's sizes (`sim::MAX_AGENTS`, `MAX_DIM`, `MAX_COIN_SIZE`, `MAX_RUN_STEPS`): one past
/// each is refused by name before anything is allocated (a scenario of 4·10¹² agents and a
/// study of 10⁸ runs aborted on a failed allocation before), the paper's study and a scenario
/// at the limits are accepted.
#[test]
fn the_studys_sizes_are_limited_by_name() {
    use nmci::study::{
        run_shard, Model, StudyConfig, MAX_AGENTS, MAX_COIN_SIZE, MAX_DIM, MAX_RUN_STEPS,
    };
    let config = |groups: usize, agents: usize, targets: usize, coin: bool| {
        let mut c = StudyConfig {
            agent: 1,
            watched: 2,
            coin,
            ..StudyConfig::default()
        };
        c.scenario.groups = groups;
        c.scenario.agents_per_group = agents;
        c.scenario.targets_per_group = targets;
        c.scenario.bridges = Vec::new();
        c
    };
    let refusal = |c: &StudyConfig| c.validate().unwrap_err().to_string();
    assert!(StudyConfig::default().validate().is_ok());
    assert!(
        refusal(&config(1_000_000_000_000, 4, 5, false)).contains(&format!(
            "4000000000000 agents, above the limit of {MAX_AGENTS}"
        ))
    );
    assert!(refusal(&config(usize::MAX, 4, 5, false)).contains("must stay within"));
    assert!(
        refusal(&config(1, MAX_AGENTS + 1, MAX_AGENTS + 2, false)).contains(&format!(
            "{} agents, above the limit of {MAX_AGENTS}",
            MAX_AGENTS + 1
        ))
    );
    // 60 agents and 100 targets: 4·100 + 2·60 = 520 states.
    assert!(refusal(&config(1, 60, 100, false))
        .contains(&format!("520 dimensions, above the limit of {MAX_DIM}")));
    // At the agent and state limits without the COIN: 64 agents, 4·96 + 2·64 = 512 states.
    let at_limits = config(1, MAX_AGENTS, 96, false);
    assert_eq!(at_limits.scenario.dim(), MAX_DIM);
    assert!(at_limits.validate().is_ok());
    // The COIN: 64 × 388 error states refused, 32 × 512 = 16 384 accepted.
    assert!(refusal(&config(1, 64, 65, true)).contains(&format!(
        "agents × dim = 64 × 388 = 24832 error states, above the limit of {MAX_COIN_SIZE}"
    )));
    let coin_limit = config(1, 32, 112, true);
    assert_eq!(
        coin_limit.scenario.agents() * coin_limit.scenario.dim(),
        MAX_COIN_SIZE
    );
    assert!(coin_limit.validate().is_ok());
    // Runs × steps: refused by the study itself, before any run.
    let mut many = StudyConfig::default();
    many.runs = MAX_RUN_STEPS / many.steps + 1;
    let model = Model::new(&many.scenario).unwrap();
    let e = run_shard(&many, &model, 0, || {}).unwrap_err().to_string();
    assert!(
        e.contains(&format!("above the limit of {MAX_RUN_STEPS} run-steps")),
        "{e}"
    );
    many.runs = MAX_RUN_STEPS / many.steps;
    assert!(many.validate_run_steps().is_ok());
}
