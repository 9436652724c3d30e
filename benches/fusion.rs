//! Fusion benchmarks (criterion). IDs and targets (issue 2):
//! `ci/trace/{2,14,112}`, `eigen/symmetric/112` (the cost floor: one nalgebra `SymmetricEigen`
//! of a 112×112 SPD matrix), `nmci/112x8` (8 blocks of 14), `ci_blocks/112x8` (monolithic CI
//! on the same block-diagonal problem), `sdp/paper/{10,100,1000}`.
//! Targets: `ci/trace/112` ≤ 2× `eigen/symmetric/112`; `sdp/paper/100` ≤ 10 ms,
//! `sdp/paper/1000` ≤ 150 ms.
//! Issue 6: `ici/trace/112`, `ci_nway/5x14`.
//! The contract's path at `n = 112`: `validate/112` (one covariance's check), `min_eigenvalue/112`,
//! `fuse/ci/112` (CI with the checks and the response), `response_json/ci/112`.
//! Issue 5: `sample/hit_and_run/14x1000` (≥ 1000 samples/s), `sdp_cuts/paper` (the paper's
//! example by cutting planes) and `sdp_cuts/random6` (a random 6-D problem, each entry of
//! `P_ab` unknown with probability 0.6: no independent blocks); the certified rule per level
//! `certified/<level>/paper_one_zero`, `certified/<level>/random3`, `certified/1/random4`, and
//! on sectors `certified/sectors<count>/paper_one_zero`; method `"sdp"` through the contract at
//! 1000 samples, `fuse/sdp/{paper,paper_one_zero}/1000` (issue 15: `nmci.optimal` ≥ 100× cvxpy).
//! Issue 17: `explore/{paper,twoblock,twoblock_full,twoblock_one_zero}`, the explorer's
//! computation natively (the page runs it in wasm): every rule, the bracket and 300 region
//! samples, for the page's opening example (n = 2), its two-block preset (n = 4, two 2 × 2
//! blocks), the same covariances with `P_ab` fully unknown, and with one known zero in each
//! block's cross block (the presets' values, as `www/state.js` sets them);
//! `explore/twoblock_one_zero/edit_one_block`: the last with a new value in block 1 at every
//! call and block 2's certificate from the memo, as an edit in the page.
//! Issue 42: `stack/{ci,nmci}/4x10000` ([`fuse_stack`] over 10⁴ pairs of 4-state estimates, one
//! thread), the same `/parallel` (rayon's default pool), and `eigen/symmetric/4x10000`, the
//! floor: one 4 × 4 symmetric eigendecomposition per pair.
#![allow(non_snake_case)]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion as Bench};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use nmci::{
    certify::*, check::*, contract::*, explore::*, nway::*, rules::*, sample::*, sdp::*,
    structure::*, *,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

fn random_spd(n: usize, rng: &mut ChaCha8Rng) -> DMatrix<f64> {
    let g = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
    &g * g.transpose() / n as f64 + DMatrix::identity(n, n) * 0.5
}

fn block_diagonal(blocks: usize, size: usize, rng: &mut ChaCha8Rng) -> DMatrix<f64> {
    let n = blocks * size;
    let mut m = DMatrix::zeros(n, n);
    for b in 0..blocks {
        m.view_mut((b * size, b * size), (size, size))
            .copy_from(&random_spd(size, rng));
    }
    m
}

fn benches(c: &mut Bench) {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut group = c.benchmark_group("ci/trace");
    for n in [2usize, 14, 112] {
        let p = FusionProblem::from_covariances(
            random_spd(n, &mut rng),
            random_spd(n, &mut rng),
            CrossPattern::fully_unknown(n),
        )
        .unwrap();
        group.bench_with_input(BenchmarkId::from_parameter(n), &p, |b, p| {
            b.iter(|| covariance_intersection(black_box(p), Criterion::Trace).unwrap())
        });
    }
    group.finish();

    // Issue 6: ICI at n = 112 (same cost class as CI: one pencil) and N-way CI of 5
    // estimates of size 14 (simplex Newton).
    let p112 = FusionProblem::from_covariances(
        random_spd(112, &mut rng),
        random_spd(112, &mut rng),
        CrossPattern::fully_unknown(112),
    )
    .unwrap();
    c.bench_function("ici/trace/112", |b| {
        b.iter(|| inverse_covariance_intersection(black_box(&p112), Criterion::Trace).unwrap())
    });
    let five: Vec<Estimate> = (0..5)
        .map(|i| {
            Estimate::new(
                &format!("e{i}"),
                DVector::zeros(14),
                random_spd(14, &mut rng),
            )
            .unwrap()
        })
        .collect();
    c.bench_function("ci_nway/5x14", |b| {
        b.iter(|| covariance_intersection_nway(black_box(&five), Criterion::Trace).unwrap())
    });

    let s = random_spd(112, &mut rng);
    c.bench_function("eigen/symmetric/112", |b| {
        b.iter(|| SymmetricEigen::new(black_box(s.clone())))
    });
    // The contract's input check of one covariance (a verified Cholesky test) and the smallest
    // eigenvalue it computed for every matrix before 2026-11-25 (now only near singular).
    c.bench_function("validate/112", |b| {
        b.iter(|| validate_covariance("P", black_box(&s)).unwrap())
    });
    c.bench_function("min_eigenvalue/112", |b| {
        b.iter(|| min_eigenvalue(black_box(&s)))
    });
    // CI through the contract (checks, CI, response) and the response as a JSON value (what
    // the Python layer built before numpy until 2026-11-25).
    let rows = |m: &DMatrix<f64>| -> Vec<Vec<f64>> {
        m.row_iter().map(|r| r.iter().copied().collect()).collect()
    };
    let request: FuseRequest = serde_json::from_value(serde_json::json!({
        "pa": rows(&p112.P_a), "pb": rows(&p112.P_b), "method": "ci"
    }))
    .unwrap();
    c.bench_function("fuse/ci/112", |b| {
        b.iter(|| fuse(black_box(&request)).unwrap())
    });
    let response = fuse(&request).unwrap();
    c.bench_function("response_json/ci/112", |b| {
        b.iter(|| serde_json::to_value(black_box(&response)).unwrap())
    });

    // 8 blocks of 14 states, cross pattern block-diagonal (the tracking study's structure).
    let (blocks, size) = (8, 14);
    let n = blocks * size;
    let pattern =
        CrossPattern::from_matrix(DMatrix::from_fn(n, n, |i, j| i / size == j / size)).unwrap();
    let p = FusionProblem::new(
        DVector::zeros(n),
        block_diagonal(blocks, size, &mut rng),
        DVector::zeros(n),
        block_diagonal(blocks, size, &mut rng),
        pattern,
    )
    .unwrap();
    c.bench_function("nmci/112x8", |b| {
        b.iter(|| non_monolithic_ci(black_box(&p), Criterion::Trace).unwrap())
    });
    // Monolithic CI (one ω) on the same block-diagonal problem, exploiting the blocks.
    let groups: Vec<Vec<usize>> = (0..blocks)
        .map(|b| (b * size..(b + 1) * size).collect())
        .collect();
    c.bench_function("ci_blocks/112x8", |b| {
        b.iter(|| covariance_intersection_blocks(black_box(&p), &groups, Criterion::Trace).unwrap())
    });

    let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
    let paper =
        FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]), CrossPattern::diagonal(2))
            .unwrap();
    let mut group = c.benchmark_group("sdp/paper");
    for samples in [10usize, 100, 1000] {
        let settings = SdpSettings {
            samples,
            ..Default::default()
        };
        group.bench_with_input(BenchmarkId::from_parameter(samples), &settings, |b, s| {
            b.iter(|| optimal_fusion(black_box(&paper), s).unwrap())
        });
    }
    group.finish();

    // Hit-and-run at n = 14 with a fully unknown P_ab (the rejection sampler accepts none in
    // 2·10⁶ trials there): 1000 samples, one sweep over the 196 free entries each, after the
    // default 50 burn-in sweeps. Target ≥ 1000 samples per second, i.e. ≤ 1 s here.
    let p14 = FusionProblem::from_covariances(
        random_spd(14, &mut rng),
        random_spd(14, &mut rng),
        CrossPattern::fully_unknown(14),
    )
    .unwrap();
    c.bench_function("sample/hit_and_run/14x1000", |b| {
        b.iter(|| {
            sample_cross_covariances(black_box(&p14), 1000, 1, SamplerSettings::hit_and_run())
                .unwrap()
        })
    });
}

fn cut_benches(c: &mut Bench) {
    let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
    let paper =
        FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]), CrossPattern::diagonal(2))
            .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let unknown = DMatrix::from_fn(6, 6, |_, _| rng.random_bool(0.6));
    // Random orientation, eigenvalues in [0.2, 5] (as in tests/common): cases with the
    // flatter spectra of `random_spd` converge far more slowly (see `fusion::cuts`).
    let mut spread_spd = || {
        let g = DMatrix::from_fn(6, 6, |_, _| rng.random_range(-1.0..1.0));
        let q = g.qr().q();
        let d = DVector::from_fn(6, |_, _| rng.random_range(0.2..5.0));
        let m = &q * DMatrix::from_diagonal(&d) * q.transpose();
        (&m + m.transpose()) * 0.5
    };
    let random6 = FusionProblem::from_covariances(
        spread_spd(),
        spread_spd(),
        CrossPattern::from_matrix(unknown).unwrap(),
    )
    .unwrap();
    assert_eq!(
        independent_blocks(&random6.P_a, &random6.P_b, &random6.cross_pattern).len(),
        1,
        "random6 must not split"
    );
    let settings = CutsSettings::default();
    for (name, problem) in [("sdp_cuts/paper", &paper), ("sdp_cuts/random6", &random6)] {
        let run = optimal_fusion_cuts(problem, &settings).unwrap();
        assert!(run.converged, "{name}: violation {}", run.violation);
        eprintln!(
            "{name}: {} iterations, {} constraints ({} generated), tr {:.9}",
            run.iterations,
            run.constraints,
            run.constraints_generated,
            run.fused.trace()
        );
        c.bench_function(name, |b| {
            b.iter(|| optimal_fusion_cuts(black_box(problem), &settings).unwrap())
        });
    }
}

criterion_group! {
    name = cuts;
    config = Bench::default().sample_size(10).measurement_time(std::time::Duration::from_secs(10));
    targets = cut_benches
}

criterion_group! {
    name = fusion;
    config = Bench::default().sample_size(20).measurement_time(std::time::Duration::from_secs(3));
    targets = benches
}
/// The certified rule per level: the paper's example with only `P_ab[2,1]` known to be zero
/// (nmCI = CI = 3.088; certified 2.000, proven optimal), a random non-separable 3-D problem
/// (`P_ab` entries unknown with probability 0.6) and a random 4-D one (level 1); the 2-D
/// example also with the sector certificates.
fn certified_benches(c: &mut Bench) {
    let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
    let one_zero = FusionProblem::from_covariances(
        d(&[3.0, 1.0]),
        d(&[1.0, 4.0]),
        CrossPattern::from_fn(2, |i, j| !(i == 1 && j == 0)),
    )
    .unwrap();
    let level = |l: u32| CertifySettings {
        level: Some(l),
        ..CertifySettings::default()
    };
    for l in 1..=5 {
        c.bench_function(&format!("certified/{l}/paper_one_zero"), |b| {
            b.iter(|| certified_fusion(black_box(&one_zero), &level(l)).unwrap())
        });
    }
    // Two states: level 1 on each of 16, 24 (the default, `DEFAULT_SECTORS`) or 32 sectors of
    // directions.
    for count in [16, DEFAULT_SECTORS, 32] {
        let settings = CertifySettings {
            sectors: Some(count),
            ..CertifySettings::default()
        };
        c.bench_function(&format!("certified/sectors{count}/paper_one_zero"), |b| {
            b.iter(|| certified_fusion(black_box(&one_zero), &settings).unwrap())
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let random3 = loop {
        let unknown = DMatrix::from_fn(3, 3, |_, _| rng.random_bool(0.6));
        let p = FusionProblem::from_covariances(
            random_spd(3, &mut rng),
            random_spd(3, &mut rng),
            CrossPattern::from_matrix(unknown).unwrap(),
        )
        .unwrap();
        if independent_blocks(&p.P_a, &p.P_b, &p.cross_pattern).len() == 1
            && p.cross_pattern.unknown_count() < 9
        {
            break p;
        }
    };
    for l in 1..=3 {
        c.bench_function(&format!("certified/{l}/random3"), |b| {
            b.iter(|| certified_fusion(black_box(&random3), &level(l)).unwrap())
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let unknown = DMatrix::from_fn(4, 4, |_, _| rng.random_bool(0.6));
    let random4 = FusionProblem::from_covariances(
        random_spd(4, &mut rng),
        random_spd(4, &mut rng),
        CrossPattern::from_matrix(unknown).unwrap(),
    )
    .unwrap();
    // The row's premise: one 4-D block, partially known (else the rule would split it, or
    // take CI's bound without a solve).
    assert_eq!(
        independent_blocks(&random4.P_a, &random4.P_b, &random4.cross_pattern).len(),
        1
    );
    assert!(random4.cross_pattern.unknown_count() < 16);
    c.bench_function("certified/1/random4", |b| {
        b.iter(|| certified_fusion(black_box(&random4), &level(1)).unwrap())
    });
    // Method "sdp" through the contract at N = 1000 (what `nmci.optimal` runs): the sampled
    // SDP, the bracket (with the certified rule) and the bound for the SDP's own gain, on the
    // paper's example and with one known zero.
    for (name, pattern) in [
        ("paper", "[[true, false], [false, true]]"),
        ("paper_one_zero", "[[true, true], [false, true]]"),
    ] {
        let request: FuseRequest = serde_json::from_str(&format!(
            r#"{{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]], "pab_unknown": {pattern},
                "method": "sdp", "samples": 1000}}"#
        ))
        .unwrap();
        c.bench_function(&format!("fuse/sdp/{name}/1000"), |b| {
            b.iter(|| fuse(black_box(&request)).unwrap())
        });
    }
}

fn explorer_benches(c: &mut Bench) {
    let twoblock = r#""pa": [[3, 0.5, 0, 0], [0.5, 1, 0, 0], [0, 0, 1, 0.2], [0, 0, 0.2, 2]],
        "pb": [[1, -0.3, 0, 0], [-0.3, 2, 0, 0], [0, 0, 4, 1], [0, 0, 1, 2]]"#;
    let (t, f) = (true, false);
    let requests = [
        (
            "paper",
            r#""pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]]"#,
            vec![vec![t, f], vec![f, t]],
        ),
        (
            "twoblock",
            twoblock,
            (0..4)
                .map(|i| (0..4).map(|j| i / 2 == j / 2).collect())
                .collect(),
        ),
        ("twoblock_full", twoblock, vec![vec![t; 4]; 4]),
        // One known zero in each block's cross block (P_ab[1][0], P_ab[3][2]): the blocks
        // stay two 2 × 2 blocks, partially known, so each needs the 24-sector proof.
        (
            "twoblock_one_zero",
            twoblock,
            (0..4)
                .map(|i| {
                    (0..4)
                        .map(|j| i / 2 == j / 2 && !(i % 2 == 1 && j % 2 == 0))
                        .collect()
                })
                .collect(),
        ),
    ];
    for (name, covariances, unknown) in requests {
        let json = format!(
            "{{{covariances}, \"pab_unknown\": {}}}",
            serde_json::to_string(&unknown).unwrap()
        );
        let request: ExploreRequest = serde_json::from_str(&json).unwrap();
        c.bench_function(&format!("explore/{name}"), |b| {
            b.iter(|| explore(black_box(&request)).unwrap())
        });
        if name == "twoblock_one_zero" {
            // What an edit of the page costs: P_a[0][0] (block 1) new at every call, block 2
            // taken from the worker's memo of certified blocks.
            let mut memo = CertificateMemo::new();
            let mut edited = request.clone();
            let mut k = 0u32;
            c.bench_function("explore/twoblock_one_zero/edit_one_block", |b| {
                b.iter(|| {
                    k += 1;
                    edited.pair.pa[0][0] = 3.0 + f64::from(k) * 1e-6;
                    explore_with_memo(black_box(&edited), &mut memo).unwrap()
                })
            });
        }
    }
}

/// Issue 42: `k = 10⁴` pairs of 4-state estimates through [`fuse_stack`] by CI and by nmCI
/// (diagonal pattern: 4 blocks), and the floor every exact CI of a pair pays, one 4 × 4
/// symmetric eigendecomposition per pair (`eigen/symmetric/4x10000`).
fn stack_benches(c: &mut Bench) {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let (n, k) = (4usize, 10_000usize);
    let mut pa = Vec::with_capacity(k * n * n);
    let mut pb = Vec::with_capacity(k * n * n);
    let mut spd = Vec::with_capacity(k);
    for _ in 0..k {
        let a = random_spd(n, &mut rng);
        let b = random_spd(n, &mut rng);
        pa.extend(a.transpose().iter());
        pb.extend(b.transpose().iter());
        spd.push(a);
    }
    let diagonal: Vec<bool> = (0..n * n).map(|i| i / n == i % n).collect();
    for (method, pattern) in [(Method::Ci, None), (Method::Nmci, Some(&diagonal[..]))] {
        let request = StackRequest {
            method,
            options: Options::default(),
            n,
            pa: &pa,
            pb: &pb,
            xa: None,
            xb: None,
            pab_unknown: pattern,
            blocks: None,
            coupling_tol: None,
        };
        // One thread, as the issue's benchmark asks; then rayon's default pool (every core).
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        c.bench_function(&format!("stack/{}/4x10000", method.name()), |b| {
            b.iter(|| one.install(|| fuse_stack(black_box(&request)).unwrap()))
        });
        c.bench_function(&format!("stack/{}/4x10000/parallel", method.name()), |b| {
            b.iter(|| fuse_stack(black_box(&request)).unwrap())
        });
    }
    c.bench_function("eigen/symmetric/4x10000", |b| {
        b.iter(|| {
            spd.iter()
                .map(|a| SymmetricEigen::new(black_box(a.clone())).eigenvalues[0])
                .sum::<f64>()
        })
    });
}

criterion_group! {
    name = stack;
    config = Bench::default().sample_size(10).measurement_time(std::time::Duration::from_secs(5));
    targets = stack_benches
}

criterion_group! {
    name = explorer;
    config = Bench::default().sample_size(10).measurement_time(std::time::Duration::from_secs(5));
    targets = explorer_benches
}

criterion_group! {
    name = certified;
    config = Bench::default().sample_size(10).measurement_time(std::time::Duration::from_secs(5));
    targets = certified_benches
}

criterion_main!(fusion, cuts, certified, explorer, stack);
