//! Probe (temporary): the cutting planes' rule proven on refined cones.
#![allow(non_snake_case)]
use nalgebra::DMatrix;
use nmci::{bounds::*, certify::*, rules::*, sdp::*, structure::*, *};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

#[path = "../tests/common/mod.rs"]
mod common;
use common::random_spd;

fn pattern(class: &str, n: usize, rng: &mut ChaCha8Rng) -> CrossPattern {
    let zero = (rng.random_range(0..n), rng.random_range(0..n));
    let coins = DMatrix::from_fn(n, n, |_, _| rng.random_bool(0.6));
    CrossPattern::from_fn(n, |i, j| match class {
        "anti-diagonal" => j == n - 1 - i,
        "chain" => j == i || j == i + 1,
        "random 0.6" => coins[(i, j)],
        "one zero" => (i, j) != zero,
        _ => unreachable!(),
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let class = args[1].clone();
    let count: usize = args[2].parse()?;
    let budget: usize = args[3].parse()?;
    let n = 3;
    let c = ["anti-diagonal", "chain", "random 0.6", "one zero"].iter().position(|x| *x == class).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1000 * n as u64 + c as u64);
    let mut done = 0;
    let mut closed = 0;
    while done < count {
        let pat = pattern(&class, n, &mut rng);
        let p = FusionProblem::from_covariances(random_spd(n, &mut rng), random_spd(n, &mut rng), pat)?;
        if independent_blocks(&p.P_a, &p.P_b, &p.cross_pattern).len() > 1
            || p.cross_pattern.unknown_count() == n * n
        {
            continue;
        }
        let t0 = Instant::now();
        let cuts = match optimal_fusion_cuts(&p, &CutsSettings { tolerance: 1e-10, max_iterations: 200, own_rule_cones: 0, ..CutsSettings::default() }) {
            Ok(c) => c,
            Err(e) => { eprintln!("cuts failed {e}"); continue; }
        };
        let tc = t0.elapsed().as_secs_f64();
        done += 1;
        let lower = cuts.lower_bound;
        let old = cuts.certified_trace.unwrap_or(f64::NAN);
        let Q0 = &cuts.fused.P;
        let slack = 1e-6 * lower - (Q0.trace() - lower);
        let target = (0.5 * slack / 3.0).max(0.0);
        let t1 = Instant::now();
        let _ = target;
        let r = certify_rule(&p, &cuts.fused, budget as u32, 1e-6, &CertifySettings::default()).map(|r| { let r = r.unwrap(); (r.fused.P, r.sectors[0], r.iterations, r.repair) });
        let tp = t1.elapsed().as_secs_f64();
        match r {
            Ok((P, cones, it, repair)) => {
                let up = trace_upper_bound(&P);
                let gap = (up - lower) / up;
                let oldgap = (old - lower) / old;
                if gap <= 1e-6 { closed += 1; }
                println!("{class} #{done}: lower {lower:.10} primal-lower {:.1e} old gap {oldgap:.1e} new gap {gap:.1e} cones {cones} splits {it} repair {repair:.1e} cuts {tc:.2}s point {tp:.2}s", (Q0.trace()-lower)/lower);
            }
            Err(e) => println!("{class} #{done}: point failed {e} ({tp:.2}s)\nPa {}Pb {}K {}Q0 {}", p.P_a, p.P_b, cuts.fused.K_a, Q0),
        }
    }
    println!("{class}: closed {closed}/{count}");
    Ok(())
}
