//! The bracket tables of docs/benchmarks.md (read in docs/methods.md): the proven bracket
//! `[lower, upper]` around the robust optimum, per state dimension, pattern class and
//! certificate (a level, or for two states a number of sectors), over random problems (fixed
//! seeds): median and worst relative gap, fraction closed (`gap ≤ 10⁻⁶ · upper`), median and worst time of the certificate, and how
//! many blocks the certified rule certified with a lower family (its fallback when a solve
//! fails, or ends `AlmostSolved` with a large repair and the lower family's bound is smaller).
//!
//! The lower end is the cutting planes' proven Lagrangian bound (`sdp_cuts` with the default
//! certificate as its guide, and a tolerance of `10⁻¹⁰`); the upper end for a certificate is
//! the smaller of nmCI's proven trace and that certified rule's. Both are rigorous, so the gap
//! is too.
//!
//! `cargo run --release --example certify_levels -- [--dims 2,3] [--count 50] [--levels 1,2,3] [--sectors 16,32] [--cones 16,64] [--adaptive 32] [--own-rule 64] [--classes "chain,one zero"] [--cuts-tol 1e-10] [--time-limit 30] [--bracket-rtol 1e-6] [--tolerance 1e-10] [--problems 3,17] [--verbose]`
//!
//! `--own-rule 64` (three or four states) adds a row for the cutting planes' proven upper end.
//! At three states it is `sdp_cuts` itself, run with `own_rule_cones` 64 (its guide, the
//! default certified rule, else its own rule proven on at most that many cones, restarts
//! from the proof's directions and the finer loop included), timed end to end. At four
//! states, where `sdp_cuts` stops at its guide (`fusion::cuts`, "Its own rule, proven"), the
//! loop's rule is proven by `certify_rule` where the guide leaves the bracket open: the row's
//! times are the proof's alone, where it ran, and the notes give the cutting planes' and the
//! end-to-end times. At three states a last row sums up `sdp_cuts` over the classes run:
//! closed, the median and worst end-to-end time, how many closed within 0.5, 1, 2, 5, 10 and
//! 30 s, and how many problems stopped at `--time-limit`.
//!
//! Pattern classes (`P_ab[i][j]` unknown where listed, known zero elsewhere):
//! - `anti-diagonal`: `j = n − 1 − i`;
//! - `chain`: `j = i` or `j = i + 1`;
//! - `random 0.6`: each entry unknown with probability 0.6;
//! - `one zero`: all unknown except one random entry.
//!
//! Problems whose pattern is separable (more than one independent block) or fully unknown are
//! redrawn: nmCI, resp. CI, is optimal there.
#![allow(non_snake_case)]
use nalgebra::DMatrix;
use nmci::{bounds::*, certify::*, rules::*, sdp::*, structure::*, *};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

#[path = "../tests/common/mod.rs"]
mod common;
use common::random_spd;

/// `sdp_cuts` end to end on one class at three states: problems, how many stopped at the time
/// limit, and (gap, time) per problem.
struct ClassRuns {
    count: usize,
    timed_out: usize,
    runs: Vec<(f64, f64)>,
}

fn arg_list(args: &[String], name: &str, default: &[usize]) -> Vec<usize> {
    match args.iter().position(|a| a == name) {
        Some(i) => args[i + 1]
            .split(',')
            .map(|x| x.parse().expect("a number"))
            .collect(),
        None => default.to_vec(),
    }
}

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

fn name(family: Family) -> String {
    match family {
        Family::Global(level) => format!("level {level}"),
        Family::Sectors(count) => format!("{count} sectors"),
        Family::Cones(count) => format!("{count} cones"),
        Family::Adaptive(budget) => format!("adaptive, ≤ {budget} cones"),
    }
}

fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let dims = arg_list(&args, "--dims", &[2, 3]);
    let count = arg_list(&args, "--count", &[50])[0];
    let verbose = args.iter().any(|a| a == "--verbose");
    // `--problems 3,17`: solve only those problems of each class (numbered from 1, as
    // `--verbose` numbers them; the others are drawn and skipped, so the seeds stay the same
    // where no solve fails).
    let problems: Option<Vec<usize>> = args
        .iter()
        .position(|a| a == "--problems")
        .map(|i| args[i + 1].split(',').map(str::parse).collect())
        .transpose()?;
    // `--classes "random 0.6,one zero"`: only those pattern classes (same seeds).
    let classes: Option<Vec<String>> = args
        .iter()
        .position(|a| a == "--classes")
        .map(|i| args[i + 1].split(',').map(str::to_string).collect());
    // Certificates: `--levels 1,2,3` (one certificate of that level for every direction)
    // and `--sectors 16,32` (two states: level 1 on that many sectors).
    let mut families: Vec<Family> = arg_list(&args, "--levels", &[1, 2, 3])
        .into_iter()
        .map(|l| Family::Global(l as u32))
        .collect();
    families.extend(
        arg_list(&args, "--sectors", &[])
            .into_iter()
            .map(|s| Family::Sectors(s as u32)),
    );
    // `--cones 4,16` (three states: level 1 on that many cones of directions).
    families.extend(
        arg_list(&args, "--cones", &[])
            .into_iter()
            .map(|c| Family::Cones(c as u32)),
    );
    // `--adaptive 32,48` (three states: cones cut where the bound is tight, at most that many).
    families.extend(
        arg_list(&args, "--adaptive", &[])
            .into_iter()
            .map(|c| Family::Adaptive(c as u32)),
    );
    // `--own-rule 64`: the cutting planes' own rule proven on at most that many cones.
    let own_rule = arg_list(&args, "--own-rule", &[])
        .first()
        .map(|&c| c as u32);
    // The cutting planes stop when the worst violation is below this times tr P̄ (the
    // library default is 1e-7; the lower end needs less to close brackets to 1e-6).
    let cuts_tol = match args.iter().position(|a| a == "--cuts-tol") {
        Some(i) => args[i + 1].parse()?,
        None => 1e-10,
    };
    // `--time-limit 30`: the cutting planes' time limit in seconds (`CutsSettings::time_limit`;
    // none by default; the explorer's second stage runs with 30).
    let time_limit = match args.iter().position(|a| a == "--time-limit") {
        Some(i) => Some(args[i + 1].parse::<f64>()?),
        None => None,
    };
    // `--bracket-rtol 1e-6`: the cutting planes also stop as soon as the bracket is closed to
    // this (`CutsSettings::bracket_rtol`; none by default; the explorer's second stage runs
    // with `CLOSED_RTOL`).
    let bracket_rtol = match args.iter().position(|a| a == "--bracket-rtol") {
        Some(i) => Some(args[i + 1].parse::<f64>()?),
        None => None,
    };
    // The certificate's solver tolerance (`CertifySettings::tolerance`; default the library's).
    let tolerance = match args.iter().position(|a| a == "--tolerance") {
        Some(i) => args[i + 1].parse()?,
        None => CertifySettings::default().tolerance,
    };
    println!("| n | pattern | certificate | median gap | worst gap | closed (≤ 1e-6) | median time | worst time | notes |");
    println!("|---|---|---|---|---|---|---|---|---|");
    // `sdp_cuts` at three states: its row's name, and the note on the time limit.
    let cuts_row = |budget: u32| {
        let limit = time_limit.map_or(String::new(), |t| format!(", time limit {t} s"))
            + &bracket_rtol.map_or(String::new(), |r| {
                format!(", stopped at a bracket of {r:.0e}")
            });
        format!(
            "`sdp_cuts`: level {}, else its own rule proven on ≤ {budget} cones (cutting planes to {cuts_tol:.0e}{limit})",
            CertifySettings::auto_level(3)
        )
    };
    let limit_note = |timed_out: usize| match time_limit {
        Some(_) => format!("; stopped at the time limit: {timed_out}"),
        None => String::new(),
    };
    for &n in &dims {
        // Per class at three states: `sdp_cuts` end to end.
        let mut all: Vec<ClassRuns> = Vec::new();
        for (c, class) in ["anti-diagonal", "chain", "random 0.6", "one zero"]
            .into_iter()
            .enumerate()
            .filter(|(_, class)| {
                classes
                    .as_ref()
                    .is_none_or(|l| l.iter().any(|x| x == class))
            })
        {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 * n as u64 + c as u64);
            let mut gaps = vec![Vec::new(); families.len()];
            let mut lowered = vec![0; families.len()];
            let mut times = vec![Vec::new(); families.len()];
            let mut done = 0;
            let mut failed = 0;
            // The own rule: gaps, proof times where it ran, and the cutting planes' times.
            // End to end: the cutting planes, then the proof where it runs (what `sdp_cuts` does).
            let (mut own_gaps, mut own_times, mut cuts_times, mut total_times) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            // Three states: problems whose bound is the loop's own rule, and whose loop the
            // proof restarted.
            let (mut proven_in_loop, mut restarted, mut timed_out) = (0, 0, 0);
            while done < count {
                let pat = pattern(class, n, &mut rng);
                let p = FusionProblem::from_covariances(
                    random_spd(n, &mut rng),
                    random_spd(n, &mut rng),
                    pat,
                )?;
                if independent_blocks(&p.P_a, &p.P_b, &p.cross_pattern).len() > 1
                    || p.cross_pattern.unknown_count() == n * n
                {
                    continue;
                }
                if problems.as_ref().is_some_and(|l| !l.contains(&(done + 1))) {
                    done += 1;
                    continue;
                }
                let cuts_start = Instant::now();
                let cuts = match optimal_fusion_cuts(
                    &p,
                    &CutsSettings {
                        tolerance: cuts_tol,
                        max_iterations: 200,
                        time_limit,
                        bracket_rtol,
                        certify_settings: CertifySettings {
                            tolerance,
                            ..CertifySettings::default()
                        },
                        // Three states: `sdp_cuts` proves its own rule itself (and restarts
                        // from the proof's short directions); four: below, by hand.
                        own_rule_cones: own_rule.filter(|_| n == 3).unwrap_or(0),
                        ..CutsSettings::default()
                    },
                ) {
                    Ok(c) => c,
                    Err(e) => {
                        // Counted (the table's "failed" column), never hidden.
                        eprintln!("{class}: sdp_cuts failed: {e}");
                        failed += 1;
                        continue;
                    }
                };
                done += 1;
                if verbose {
                    eprintln!(
                        "{class} #{done}: {:.2} s lower {:.10} (dual {:.10}) stop {:?} it {} cons {} upper {:?} own rule {} proof rounds {}",
                        cuts_start.elapsed().as_secs_f64(),
                        cuts.lower_bound,
                        cuts.dual_objective,
                        cuts.stop,
                        cuts.iterations,
                        cuts.constraints,
                        cuts.certified_trace,
                        cuts.own_rule_proven,
                        cuts.proof_rounds
                    );
                }
                cuts_times.push(cuts_start.elapsed().as_secs_f64());
                let nm = non_monolithic_ci(&p, Criterion::Trace)?;
                let nm_upper = nmci_upper_bound(&p, &nm).unwrap_or(f64::INFINITY);
                if let Some(budget) = own_rule.filter(|_| (3..=4).contains(&n)) {
                    let guide = cuts.certified_trace.unwrap_or(f64::INFINITY).min(nm_upper);
                    let gap = |upper| {
                        Bracket {
                            lower: cuts.lower_bound,
                            upper,
                            upper_rule: UpperRule::Certified,
                        }
                        .gap_relative()
                    };
                    let mut upper = guide;
                    let mut total = *cuts_times.last().expect("timed above");
                    if n == 3 {
                        proven_in_loop += usize::from(cuts.own_rule_proven);
                        restarted += usize::from(cuts.proof_rounds > 0);
                        timed_out += usize::from(cuts.stop == CutsStop::TimeLimit);
                    } else if gap(guide) > CLOSED_RTOL {
                        let start = Instant::now();
                        let settings = CertifySettings {
                            tolerance,
                            ..CertifySettings::default()
                        };
                        match certify_rule(&p, &cuts.fused, budget, CLOSED_RTOL, &settings) {
                            Ok(Some(proven)) => {
                                upper = upper.min(trace_upper_bound(&proven.fused.P));
                                if verbose {
                                    eprintln!(
                                        "  own rule: upper {:.10} cones {:?} cuts {} repair {:.1e}",
                                        trace_upper_bound(&proven.fused.P),
                                        proven.sectors,
                                        proven.iterations,
                                        proven.repair
                                    );
                                }
                            }
                            Ok(None) => {}
                            Err(e) => eprintln!("{class}: the own rule's proof failed: {e}"),
                        }
                        own_times.push(start.elapsed().as_secs_f64());
                        total += start.elapsed().as_secs_f64();
                    }
                    total_times.push(total);
                    own_gaps.push(gap(upper));
                }
                for (k, &family) in families.iter().enumerate() {
                    if matches!(family, Family::Sectors(_)) && n != 2
                        || matches!(family, Family::Cones(_) | Family::Adaptive(_)) && n != 3
                    {
                        continue;
                    }
                    let start = Instant::now();
                    let settings = match family {
                        Family::Global(level) => CertifySettings {
                            level: Some(level),
                            tolerance,
                            ..CertifySettings::default()
                        },
                        Family::Sectors(count) => CertifySettings {
                            sectors: Some(count),
                            tolerance,
                            ..CertifySettings::default()
                        },
                        Family::Cones(count) => CertifySettings {
                            cones: Some(count),
                            tolerance,
                            ..CertifySettings::default()
                        },
                        Family::Adaptive(budget) => CertifySettings {
                            max_cones: Some(budget),
                            tolerance,
                            ..CertifySettings::default()
                        },
                    };
                    let cert = certified_fusion(&p, &settings)?;
                    // The adaptive cones report how many cones they used (up to the budget).
                    let sectors_as_asked = match family {
                        Family::Adaptive(budget) => {
                            cert.sectors.iter().all(|&c| (4..=budget).contains(&c))
                        }
                        _ => cert.sectors == vec![family.sectors()],
                    };
                    if cert.levels != vec![family.level()] || !sectors_as_asked {
                        lowered[k] += 1;
                    }
                    if verbose {
                        eprintln!("  {}: cones used {:?}", name(family), cert.sectors);
                    }
                    times[k].push(start.elapsed().as_secs_f64());
                    let upper = trace_upper_bound(&cert.fused.P).min(nm_upper);
                    let bracket = Bracket {
                        lower: cuts.lower_bound,
                        upper,
                        upper_rule: UpperRule::Certified,
                    };
                    gaps[k].push(bracket.gap_relative());
                    if verbose {
                        eprintln!(
                            "  {}: upper {upper:.10} gap {:.1e} status {:?} repair {:.1e}",
                            name(family),
                            bracket.gap_relative(),
                            cert.status,
                            cert.repair
                        );
                    }
                }
            }
            if let (Some(budget), false) = (own_rule, own_gaps.is_empty()) {
                let closed = own_gaps.iter().filter(|&&g| g <= CLOSED_RTOL).count();
                if n == 3 {
                    let runs = own_gaps.iter().copied().zip(cuts_times.iter().copied());
                    all.push(ClassRuns {
                        count,
                        timed_out,
                        runs: runs.collect(),
                    });
                    println!(
                        "| {n} | {class} | {} | {:.1e} | {:.1e} | {closed}/{count} | {:.0} ms | {:.0} ms | end to end; own rule the upper end on {proven_in_loop}; loop restarted from the proof's directions on {restarted}{} |",
                        cuts_row(budget),
                        quantile(&mut own_gaps, 0.5),
                        quantile(&mut own_gaps, 1.0),
                        1e3 * quantile(&mut cuts_times, 0.5),
                        1e3 * quantile(&mut cuts_times, 1.0),
                        limit_note(timed_out),
                    );
                }
                let ran = own_times.len();
                let (median, worst) = if ran > 0 {
                    (
                        format!("{:.0} ms", 1e3 * quantile(&mut own_times, 0.5)),
                        format!("{:.0} ms", 1e3 * quantile(&mut own_times, 1.0)),
                    )
                } else {
                    ("–".into(), "–".into())
                };
                if n == 4 {
                    println!(
                    "| {n} | {class} | level {}, else the cuts' rule (cutting planes to {cuts_tol:.0e}) on ≤ {budget} cones | {:.1e} | {:.1e} | {closed}/{count} | {median} | {worst} | proof run on {ran}; cutting planes {:.0} ms median, {:.0} ms worst; end to end {:.0} ms median, {:.0} ms worst |",
                    CertifySettings::auto_level(n),
                    quantile(&mut own_gaps, 0.5),
                    quantile(&mut own_gaps, 1.0),
                    1e3 * quantile(&mut cuts_times, 0.5),
                    1e3 * quantile(&mut cuts_times, 1.0),
                    1e3 * quantile(&mut total_times, 0.5),
                    1e3 * quantile(&mut total_times, 1.0),
                );
                }
            }
            for (k, &family) in families.iter().enumerate() {
                if gaps[k].is_empty() {
                    continue;
                }
                let closed = gaps[k].iter().filter(|&&g| g <= 1e-6).count();
                let mut notes = Vec::new();
                if failed > 0 {
                    notes.push(format!("{failed} problems redrawn: sdp_cuts failed"));
                }
                if lowered[k] > 0 {
                    notes.push(format!("{} by a lower family (fallback)", lowered[k]));
                }
                println!(
                    "| {n} | {class} | {} | {:.1e} | {:.1e} | {closed}/{count} | {:.0} ms | {:.0} ms | {} |",
                    name(family),
                    quantile(&mut gaps[k], 0.5),
                    quantile(&mut gaps[k], 1.0),
                    1e3 * quantile(&mut times[k], 0.5),
                    1e3 * quantile(&mut times[k], 1.0),
                    notes.join("; "),
                );
            }
        }
        if let (Some(budget), true) = (own_rule, all.len() > 1) {
            let count: usize = all.iter().map(|a| a.count).sum();
            let timed_out: usize = all.iter().map(|a| a.timed_out).sum();
            let runs: Vec<(f64, f64)> = all.iter().flat_map(|a| a.runs.iter().copied()).collect();
            let closed_within = |limit: f64| {
                runs.iter()
                    .filter(|&&(gap, time)| gap <= CLOSED_RTOL && time <= limit)
                    .count()
            };
            // Closed against time: how many closed within each of these many seconds.
            let curve = [0.5, 1.0, 2.0, 5.0, 10.0, 30.0]
                .map(|t| format!("{} within {t} s", closed_within(t)))
                .join(", ");
            let mut times: Vec<f64> = runs.iter().map(|r| r.1).collect();
            println!(
                "| {n} | all {} classes | {} | | | **{}/{count}** | **{:.0} ms** | {:.0} ms | end to end; closed {curve}{} |",
                all.len(),
                cuts_row(budget),
                closed_within(f64::INFINITY),
                1e3 * quantile(&mut times, 0.5),
                1e3 * quantile(&mut times, 1.0),
                limit_note(timed_out),
            );
        }
    }
    Ok(())
}
