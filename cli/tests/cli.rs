//! The `nmci` binary: JSON in, JSON out; bad input exits non-zero with one line on stderr.
#![allow(non_snake_case)] // textbook symbols: P_a, K_b, …

use std::io::Write;
use std::process::{Command, Stdio};

pub(crate) fn nmci(args: &[&str], stdin: &str) -> (i32, String, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_nmci"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(stdin.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

const PAPER: &str = r#"{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]], "pab_unknown": [[true, false], [false, true]], "method": "nmci"}"#;

/// `nmci fuse --help` lists every method of the registry, the request's fields and an example
/// that runs.
#[test]
fn fuse_help_lists_the_methods_the_fields_and_an_example() {
    let (code, out, err) = nmci(&["fuse", "--help"], "");
    assert_eq!(code, 0, "{err}");
    for rule in nmci::rules::rules() {
        assert!(
            out.contains(&format!("  {:<10} {}", rule.name, rule.label)),
            "{out}"
        );
    }
    for field in nmci::contract::request_fields() {
        assert!(out.contains(&field), "{field}: {out}");
    }
    let example = out.lines().find(|l| l.contains("| nmci fuse")).unwrap();
    let request = example.split('\'').nth(1).unwrap();
    let (code, answer, err) = nmci(&["fuse"], request);
    assert_eq!(code, 0, "{err}");
    assert!(answer.contains("\"trace\": 2.0"), "{answer}");
}

/// Errors name the field, not a position in the JSON, for data; a text that is not JSON keeps
/// its line and column (it is the user's).
#[test]
fn errors_name_the_field() {
    let (code, _, err) = nmci(&["fuse"], r#"{"pa": [[1]], "pb": [[1]], "method": "CI"}"#);
    assert_eq!(code, 1);
    assert!(
        err.contains("`method`: unknown method `CI` (names are lower case: `ci`)"),
        "{err}"
    );
    let (_, _, err) = nmci(&["fuse"], "[1]");
    assert_eq!(
        err.trim(),
        "nmci: request 0: invalid request: a request is a JSON object (got a number)"
    );
    let (_, _, err) = nmci(&["fuse"], r#"{"pa": [[1]], "pb": [[1]], "xa": [1, 2, 3 "#);
    assert!(err.contains("line 1 column"), "{err}");
}

#[test]
fn fuse_from_stdin_and_file() {
    let (code, out, err) = nmci(&["fuse"], PAPER);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["trace"], 2.0);
    assert_eq!(v["omega"], serde_json::json!([0.0, 1.0]));

    let dir = std::env::temp_dir().join(format!("nmci-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("req.json");
    std::fs::write(&file, PAPER.replace("nmci", "sdp")).unwrap();
    let (code, out, err) = nmci(&["fuse", file.to_str().unwrap()], "");
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!((v["trace"].as_f64().unwrap() - 2.0).abs() < 1e-6);
    assert_eq!(v["samples"], 200);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_input_exits_nonzero_with_one_line() {
    for (input, needle) in [
        (
            r#"{"pa": [[1, 2], [2, 1]], "pb": [[1, 0], [0, 1]], "method": "ci"}"#,
            "P_a is not positive definite",
        ),
        (
            r#"{"pa": [[1]], "pb": [[1]], "method": "ci", "oops": true}"#,
            "unknown field `oops`",
        ),
        ("{", "invalid request"),
    ] {
        let (code, out, err) = nmci(&["fuse"], input);
        assert_ne!(code, 0);
        assert!(out.is_empty());
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(needle), "{err}");
    }
    let (code, _, err) = nmci(&["fuse", "/nonexistent/request.json"], "");
    assert_ne!(code, 0);
    assert!(
        err.contains("cannot read /nonexistent/request.json"),
        "{err}"
    );
}

#[test]
fn track_writes_the_summary_and_csvs() {
    let dir = std::env::temp_dir().join(format!("nmci-track-{}", std::process::id()));
    let (code, out, err) = nmci(
        &[
            "track",
            "--runs",
            "2",
            "--steps",
            "6",
            "--seed",
            "3",
            "--out",
            dir.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("2 runs × 6 steps"));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    for method in ["central", "ci", "nmci", "naive", "ici"] {
        for key in [
            "rmse_mean",
            "two_sigma_mean",
            "nees_mean",
            "nees_frac_above_upper",
            "coin_mean",
            "coin_max",
        ] {
            assert!(summary[method][key].is_number(), "{method}.{key}");
        }
    }
    assert_eq!(summary["nees_bounds"].as_array().unwrap().len(), 2);
    assert!(summary["omega_7_11"]["ci"].is_number());
    assert_eq!(summary["omega_7_11"]["nmci"].as_array().unwrap().len(), 8);
    assert_eq!(
        (
            summary["steps"].as_u64(),
            summary["runs"].as_u64(),
            summary["seed"].as_u64(),
            summary["agent"].as_u64()
        ),
        (Some(6), Some(2), Some(3), Some(7))
    );
    let nees = std::fs::read_to_string(dir.join("nees.csv")).unwrap();
    assert_eq!(nees.lines().count(), 7);
    assert!(nees.starts_with("step,time,central,ci,nmci,naive,ici\n"));
    let coin = std::fs::read_to_string(dir.join("coin.csv")).unwrap();
    assert!(coin.starts_with("step,time,central,ci,nmci,naive,ici\n"));
    assert_eq!(coin.lines().count(), 7);
    assert!(dir.join("coin.svg").exists());
    assert!(std::fs::read_to_string(dir.join("network.svg"))
        .unwrap()
        .starts_with("<svg"));
    assert!(summary["omega_7_11"]["ici"].is_number());
    // --no-coin: the same study without the exact COIN.
    let (code, _, err) = nmci(
        &[
            "track",
            "--runs",
            "1",
            "--steps",
            "4",
            "--no-coin",
            "--out",
            dir.join("no-coin").to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("no-coin/summary.json")).unwrap())
            .unwrap();
    assert!(summary["ci"]["coin_mean"].is_null() && summary["ci"]["nees_mean"].is_number());
    assert!(!dir.join("no-coin/coin.csv").exists());
    assert_eq!(
        std::fs::read_to_string(dir.join("omega.csv"))
            .unwrap()
            .lines()
            .count(),
        1 + 2 * 6
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn track_rejects_bad_configurations() {
    let dir = std::env::temp_dir().join(format!("nmci-track-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("bad.toml");
    std::fs::write(&cfg, "steps = 10\nspeed = 3\n").unwrap();
    let (code, _, err) = nmci(
        &[
            "track",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ],
        "",
    );
    assert_ne!(code, 0);
    assert!(err.contains("unknown field `speed`"), "{err}");
    let (code, _, err) = nmci(
        &["track", "--runs", "0", "--out", dir.to_str().unwrap()],
        "",
    );
    assert_ne!(code, 0);
    assert!(err.contains("runs at least 1"), "{err}");
    std::fs::write(&cfg, "agent = 1\nwatched = 11\n").unwrap();
    let (code, _, err) = nmci(
        &[
            "track",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ],
        "",
    );
    assert_ne!(code, 0);
    assert!(err.contains("agent 1 has no link to agent 11"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn fig2_writes_the_csv_and_the_figure_and_rejects_bad_sizes() {
    let out = std::env::temp_dir().join(format!("nmci-fig2-{}", std::process::id()));
    let dir = out.to_str().unwrap();
    let (code, stdout, stderr) = nmci(
        &["fig2", "--runs", "4", "--sizes", "1,10", "--out", dir],
        "",
    );
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("4 runs × 2 sizes"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("fig2.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3);
    assert!(csv.lines().nth(1).unwrap().starts_with("1,"));
    let svg = std::fs::read_to_string(out.join("fig2.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("samples N"));
    std::fs::remove_dir_all(&out).ok();
    let (code, _, stderr) = nmci(&["fig2", "--runs", "2", "--sizes", "0", "--out", dir], "");
    assert_eq!(code, 1);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("nmci: invalid request: fig2 needs"),
        "{stderr}"
    );
}

#[test]
fn ici_ei_and_naive_through_the_cli_with_their_guarantees_stated() {
    let req = |method: &str| PAPER.replace("\"nmci\"", &format!("\"{method}\""));
    let (code, out, err) = nmci(&["fuse"], &req("ici"));
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["guarantee"], "common_information");
    let omega = v["omega"][0].as_f64().unwrap();
    assert!(omega > 0.0 && omega < 1.0, "{omega}");
    for method in ["ei", "naive"] {
        let (code, out, err) = nmci(&["fuse"], &req(method));
        assert_eq!(code, 0, "{err}");
        let v: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_eq!(v["guarantee"], "none");
        assert!(v.get("omega").is_none());
    }
    // EI keeps the smaller variance per axis: diag(1, 1) here.
    let (_, out, _) = nmci(&["fuse"], &req("ei"));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["trace"], 2.0);
    let bad = req("ei").replace("}", ", \"criterion\": \"logdet\"}");
    let (code, out, err) = nmci(&["fuse"], &bad);
    assert_ne!(code, 0);
    assert!(out.is_empty());
    assert!(err.contains("`criterion` does not apply"), "{err}");
}

#[test]
fn fuse_takes_n_estimates() {
    let (code, out, err) = nmci(
        &["fuse"],
        r#"{"estimates": [{"x": [1,0], "p": [[1,0],[0,9]]}, {"x": [0,1], "p": [[9,0],[0,1]]},
                          {"p": [[4,0],[0,4]]}], "method": "ci"}"#,
    );
    assert_eq!(code, 0, "{err}");
    let r: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(r["gains"].as_array().unwrap().len(), 3);
    let w: Vec<f64> = r["weights"][0]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(w.len(), 3);
    assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    let (code, out, err) = nmci(
        &["fuse"],
        r#"{"estimates": [{"p": [[1]]}, {"p": [[1]]}], "method": "ei"}"#,
    );
    assert_ne!(code, 0);
    assert!(out.is_empty());
    assert!(
        err.contains("supports methods \"ci\" and \"nmci\""),
        "{err}"
    );
}

#[test]
fn sweep_writes_the_ranking_the_best_configuration_and_its_drawing() {
    let dir = std::env::temp_dir().join(format!("nmci-sweep-{}", std::process::id()));
    let out = dir.to_str().unwrap();
    let (code, stdout, err) = nmci(
        &[
            "sweep",
            "--extra",
            "1",
            "--steps",
            "4",
            "--runs",
            "1",
            "--short-list",
            "2",
            "--out",
            out,
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        stdout.starts_with("7 networks fit the text; 2 with Monte Carlo RMSE (1 runs × 4 steps)"),
        "{stdout}"
    );
    assert!(stdout.contains("reference"), "{stdout}");
    let csv = std::fs::read_to_string(dir.join("sweep.csv")).unwrap();
    // Header, 7 fitting networks, the figure's reading as a reference.
    assert_eq!(csv.lines().count(), 1 + 7 + 1);
    assert!(csv
        .lines()
        .last()
        .unwrap()
        .starts_with("reference,4-7 7-11 12-13,false,"));
    // The best network as a configuration `nmci track` runs.
    let best: nmci::study::StudyConfig =
        toml::from_str(&std::fs::read_to_string(dir.join("best.toml")).unwrap()).unwrap();
    let report: nmci::study::SweepReport =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sweep.json")).unwrap()).unwrap();
    assert_eq!(best.scenario.bridges, report.ranked[0].links);
    assert_eq!(nmci::study::check_text(&best.scenario), Ok(()));
    let svg = std::fs::read_to_string(dir.join("network.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.matches("<circle").count() == 16);
    // Bad input: non-zero exit, the reason on stderr.
    let (code, _, err) = nmci(&["sweep", "--extra", "5", "--out", out], "");
    assert_ne!(code, 0);
    assert_eq!(
        err.trim(),
        "nmci: invalid scenario: extra links: at most 3 (got 5; the count grows as 93^extra)"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The `nmci fuse` examples of the README and docs/contract.md, run as written: every
/// `"key": value` they show (values elided as `…` or `[...]` are skipped) equals the
/// response's to 1e-12 relative, and the error example prints its line and exits 1.
#[test]
fn the_readme_cli_examples_print_what_the_readme_shows() {
    for (file, examples) in [("README.md", 1), ("docs/contract.md", 3)] {
        let text =
            std::fs::read_to_string(format!("{}/../{file}", env!("CARGO_MANIFEST_DIR"))).unwrap();
        assert_eq!(
            cli_examples_checked(file, &text),
            examples,
            "{file}'s nmci fuse examples"
        );
    }
}

/// Runs the `$ echo '…' | nmci fuse` examples of `text` and checks what they show; returns
/// how many it checked.
fn cli_examples_checked(file: &str, text: &str) -> usize {
    let lines: Vec<&str> = text.lines().collect();
    let mut checked = 0;
    for (k, line) in lines.iter().enumerate() {
        let Some(rest) = line.strip_prefix("$ echo '") else {
            continue;
        };
        let request = &rest[..rest.find("' | nmci fuse").expect("an nmci fuse example")];
        let (code, out, err) = nmci(&["fuse"], request);
        let shown = lines[k + 1];
        if let Some(message) = shown.strip_prefix("nmci: ") {
            assert_eq!(code, 1);
            assert_eq!(lines[k + 2], "1");
            assert_eq!(err.trim(), format!("nmci: {message}"));
            checked += 1;
            continue;
        }
        assert_eq!(code, 0, "{err}");
        let response: serde_json::Value = serde_json::from_str(&out).unwrap();
        let mut pairs = 0;
        for (start, _) in shown.match_indices("\"") {
            // A key is a quoted word followed by `": `.
            let after = &shown[start + 1..];
            let Some(end) = after.find('"') else { continue };
            let (key, tail) = (&after[..end], &after[end + 1..]);
            let Some(value) = tail.strip_prefix(": ") else {
                continue;
            };
            if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                continue;
            }
            let mut stream =
                serde_json::Deserializer::from_str(value).into_iter::<serde_json::Value>();
            let Some(Ok(expected)) = stream.next() else {
                continue; // `[...]` or `…`
            };
            assert!(
                same(&expected, &response[key]),
                "{file} line {}: {key} = {expected}, the CLI gives {}",
                k + 2,
                response[key]
            );
            pairs += 1;
        }
        assert!(
            pairs >= 5,
            "{file} line {}: only {pairs} values read",
            k + 2
        );
        checked += 1;
    }
    checked
}

/// The prose figures of the paper's example (the README's and docs/contract.md's).
#[test]
fn the_paper_example_prose_figures_hold() {
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md")).unwrap();
    let (code, out, _) = nmci(
        &["fuse"],
        r#"{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]], "pab_unknown": [[true, false], [false, true]], "method": "ci"}"#,
    );
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(readme.contains("`tr P = 3.088` (`ω = 0.556`)"));
    assert_eq!(format!("{:.3}", v["trace"].as_f64().unwrap()), "3.088");
    assert_eq!(format!("{:.3}", v["omega"][0].as_f64().unwrap()), "0.556");
    // The README's CLI example in prose: one known zero, the certified trace against CI's.
    let (code, out, _) = nmci(
        &["fuse"],
        r#"{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]], "pab_unknown": [[true, true], [false, true]], "method": "certified"}"#,
    );
    assert_eq!(code, 0);
    let cert: serde_json::Value = serde_json::from_str(&out).unwrap();
    let shown = format!(
        "certified rule's bound has\ntrace {:.8}, proven for every admissible `P_ab` (CI's is {:.3})",
        cert["trace"].as_f64().unwrap(),
        v["trace"].as_f64().unwrap()
    );
    assert!(readme.contains(&shown), "the README should say: {shown}");
}

/// Equal JSON values, numbers to 1e-12 relative.
fn same(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            (x - y).abs() <= 1e-12 * x.abs().max(1.0)
        }
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same(x, y))
        }
        _ => a == b,
    }
}

/// `nmci track` (parallel) writes exactly the sequential study's report; a configuration file
/// is applied and the flags override it; a missing file, a TOML syntax error and an unknown
/// key are refused with the reason.
#[test]
fn track_equals_the_sequential_study_and_applies_its_configuration() {
    use nmci::study::{run_study, StudyConfig, StudyReport};
    let dir = std::env::temp_dir().join(format!("nmci-track-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("study.toml");
    // The figure's network, 7 steps and seed 5 from the file; runs from the file, then
    // overridden by the flag.
    std::fs::write(
        &cfg,
        "steps = 7\nruns = 4\nseed = 5\ncoin = false\n[scenario]\nbridges = [[4, 7], [7, 11], [12, 13]]\n",
    )
    .unwrap();
    let out = dir.join("out");
    let (code, stdout, err) = nmci(
        &[
            "track",
            "--config",
            cfg.to_str().unwrap(),
            "--runs",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("2 runs × 7 steps"), "{stdout}");
    // Quiet: one line on stdout; the summary only with --json.
    assert_eq!(stdout.trim_end().lines().count(), 1, "{stdout}");
    let written: StudyReport =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let config = StudyConfig {
        steps: 7,
        runs: 2,
        seed: 5,
        coin: false,
        scenario: nmci::study::Scenario {
            bridges: nmci::study::FIGURE_BRIDGES.to_vec(),
            ..Default::default()
        },
        ..StudyConfig::default()
    };
    let (_, sequential) = run_study(&config).unwrap();
    assert_eq!(written, sequential);
    // --steps and --seed override the file too.
    let (code, stdout, err) = nmci(
        &[
            "track",
            "--config",
            cfg.to_str().unwrap(),
            "--runs",
            "1",
            "--steps",
            "3",
            "--seed",
            "9",
            "--out",
            out.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("1 runs × 3 steps"), "{stdout}");
    let written: StudyReport =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!((written.steps, written.runs, written.seed), (3, 1, 9));
    // Bad configurations.
    let missing = dir.join("missing.toml");
    std::fs::write(dir.join("syntax.toml"), "steps = = 3\n").unwrap();
    std::fs::write(dir.join("unknown.toml"), "[scenario]\nbridge = [[1, 2]]\n").unwrap();
    for (file, expected) in [
        (
            missing.clone(),
            format!("nmci: cannot read {}", missing.display()),
        ),
        (
            dir.join("syntax.toml"),
            "nmci: invalid configuration".to_string(),
        ),
        (
            dir.join("unknown.toml"),
            "nmci: invalid configuration".to_string(),
        ),
    ] {
        let (code, _, err) = nmci(
            &[
                "track",
                "--config",
                file.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            "",
        );
        assert_eq!(code, 1, "{err}");
        assert!(err.starts_with(&expected), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
    let (_, _, err) = nmci(
        &[
            "track",
            "--config",
            dir.join("unknown.toml").to_str().unwrap(),
        ],
        "",
    );
    assert!(err.contains("unknown field `bridge`"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `nmci track --first-run` shards merged by `nmci merge` write byte for byte the files of one
/// `nmci track` of all the runs; shards that do not make one study exit non-zero with the
/// reason.
#[test]
fn track_shards_merged_write_the_files_of_one_track() {
    let dir = std::env::temp_dir().join(format!("nmci-shards-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let path = |p: &str| dir.join(p).to_str().unwrap().to_string();
    let run = |args: &[&str]| {
        let (code, out, err) = nmci(args, "");
        assert_eq!(code, 0, "{args:?}: {err}");
        out
    };
    let common = ["--steps", "9", "--seed", "6"];
    let one = path("one");
    run(&[&["track", "--runs", "3", "--out", &one][..], &common].concat());
    let shards = path("shards");
    for (first, runs) in [("2", "1"), ("0", "2")] {
        let out = run(&[
            &[
                "track",
                "--first-run",
                first,
                "--runs",
                runs,
                "--out",
                &shards,
            ][..],
            &common,
        ]
        .concat());
        assert!(out.contains("wrote the shard"), "{out}");
    }
    let merged = path("merged");
    let out = run(&["merge", &shards, "--out", &merged]);
    assert!(out.contains("merged 2 shards: 3 runs × 9 steps"), "{out}");
    let mut names: Vec<_> = std::fs::read_dir(&one)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert_eq!(names.len(), 11, "{names:?}");
    for name in &names {
        let a = std::fs::read(dir.join("one").join(name)).unwrap();
        let b = std::fs::read(dir.join("merged").join(name)).unwrap();
        assert!(a == b, "{name:?} differs");
    }
    // Refused: a gap, a shard of another study, a file that is not a shard, no shards.
    let lone = path("shards/shard-000002-000003.json");
    let (code, _, err) = nmci(&["merge", &lone, "--out", &merged], "");
    assert_ne!(code, 0);
    assert!(err.contains("runs 0..2 are in no shard"), "{err}");
    let other = path("other");
    run(&[
        "track",
        "--first-run",
        "2",
        "--runs",
        "1",
        "--steps",
        "9",
        "--seed",
        "7",
        "--out",
        &other,
    ]);
    let first = path("shards/shard-000000-000002.json");
    let (code, _, err) = nmci(&["merge", &first, &other, "--out", &merged], "");
    assert_ne!(code, 0);
    assert!(err.contains("its `seed` differs"), "{err}");
    let (code, _, err) = nmci(&["merge", &path("one/summary.json"), "--out", &merged], "");
    assert_ne!(code, 0);
    assert!(err.contains("is not a study shard"), "{err}");
    let (code, _, err) = nmci(&["merge", &one, "--out", &merged], "");
    assert_ne!(code, 0);
    assert!(err.contains("holds no shard-*.json file"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Near-zero couplings absorbed: the response on stdout, the note on stderr; a declared
/// partition that contradicts the covariances exits non-zero naming the entry.
#[test]
fn the_structure_note_goes_to_stderr_and_refusals_exit_nonzero() {
    let coupled = r#"{"pa": [[3, 1e-13], [1e-13, 1]], "pb": [[1, 0], [0, 4]], "pab_unknown": [[true, false], [false, true]], "method": "nmci"}"#;
    let (code, out, err) = nmci(&["fuse"], coupled);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!((v["trace"].as_f64().unwrap() - 2.0).abs() < 1e-9, "{out}");
    assert_eq!(v["structure"]["blocks"], serde_json::json!([[0], [1]]));
    assert!(
        err.starts_with("nmci: structure: 1 near-zero coupling") && err.contains("absorbed"),
        "{err}"
    );
    // Exact zeros: nothing on stderr.
    let (code, _, err) = nmci(&["fuse"], PAPER);
    assert_eq!((code, err.as_str()), (0, ""));
    // A list: the array of responses on stdout, each note naming its request.
    let (code, out, err) = nmci(&["fuse"], &format!("[{PAPER}, {coupled}]"));
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v.as_array().map(Vec::len), Some(2), "{out}");
    assert!(
        v[0].get("structure").is_none() && v[1]["structure"]["blocks"].is_array(),
        "{out}"
    );
    assert!(
        err.starts_with("nmci: structure: request 1: 1 near-zero coupling"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    // A failing request of a list exits non-zero, naming it.
    let (code, _, err) = nmci(
        &["fuse"],
        &format!(r#"[{PAPER}, {{"pa": [[-1]], "pb": [[1]], "method": "ci"}}]"#),
    );
    assert_ne!(code, 0);
    assert!(err.contains("request 1: P_a"), "{err}");
    for (extra, needle) in [
        (
            r#""blocks": [[0], [1]], "pa": [[3, 0.5], [0.5, 1]]"#,
            "pa[0][1] = 0.5 couples blocks 0 and 1",
        ),
        (
            r#""blocks": [[0]], "pa": [[3, 0], [0, 1]]"#,
            "state 1 is in no block",
        ),
        (
            r#""coupling_tol": 2, "pa": [[3, 0], [0, 1]]"#,
            "coupling_tol must be in [0, 1]",
        ),
    ] {
        let req = format!(r#"{{{extra}, "pb": [[1, 0], [0, 4]], "method": "nmci"}}"#);
        let (code, out, err) = nmci(&["fuse"], &req);
        assert_ne!(code, 0, "{out}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(needle), "{err}");
    }
}

/// The SVG files are the library's drawings of the study's and fig. 2's charts.
#[test]
fn the_clis_figures_are_this_codes_drawings() {
    use nmci::study::{run_study, StudyConfig};
    use nmci::{
        chart::charts_svg,
        fig2::{fig2_charts, fig2_run, fig2_summary, Fig2Config},
        study::study_charts,
    };
    let config = StudyConfig {
        runs: 2,
        steps: 12,
        seed: 5,
        coin: true,
        ..StudyConfig::default()
    };
    let dir = std::env::temp_dir().join(format!("nmci-charts-{}", std::process::id()));
    let (code, _, err) = nmci(
        &[
            "track",
            "--runs",
            "2",
            "--steps",
            "12",
            "--seed",
            "5",
            "--out",
            dir.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    let (summary, _) = run_study(&config).unwrap();
    for (name, chart) in study_charts(&config, &summary, config.runs) {
        let file = std::fs::read_to_string(dir.join(format!("{name}.svg"))).unwrap();
        assert_eq!(
            file,
            charts_svg(&[&chart], (900, 480)).unwrap(),
            "{name}.svg"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
    let out = std::env::temp_dir().join(format!("nmci-charts-fig2-{}", std::process::id()));
    let (code, _, err) = nmci(
        &[
            "fig2",
            "--runs",
            "3",
            "--sizes",
            "1,10,50",
            "--seed",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    let fig2 = Fig2Config {
        runs: 3,
        sizes: vec![1, 10, 50],
        seed: 2,
    };
    let runs: Vec<_> = (0..3).map(|r| fig2_run(&fig2, r).unwrap()).collect();
    let [dev, eig] = fig2_charts(&fig2_summary(&fig2, &runs), 3);
    let file = std::fs::read_to_string(out.join("fig2.svg")).unwrap();
    assert_eq!(file, charts_svg(&[&dev, &eig], (900, 400)).unwrap());
    // One document holding both charts (each drawn once, closed once).
    assert_eq!(
        (file.matches("<svg").count(), file.matches("</svg>").count()),
        (1, 1)
    );
    assert!(file.trim_end().ends_with("</svg>"));
    assert!(file.contains("samples N") && file.contains("λ_min") && file.contains("deviation"));
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn a_request_past_the_byte_limit_is_not_read_whole() {
    use nmci::contract::MAX_REQUEST_BYTES;
    let text = " ".repeat(MAX_REQUEST_BYTES + 1);
    // The CLI stops reading one byte past it, exits non-zero and says why.
    let path = std::env::temp_dir().join(format!("nmci-too-large-{}.json", std::process::id()));
    std::fs::write(&path, text.as_bytes()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_nmci"))
        .args(["fuse", path.to_str().unwrap()])
        .output()
        .unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains(&format!(
            "longer than the limit of {MAX_REQUEST_BYTES} bytes"
        )),
        "{stderr}"
    );
}
