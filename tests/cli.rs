//! The `nmci` binary: JSON in, JSON out; bad input exits non-zero with one line on stderr.
#![cfg(not(target_arch = "wasm32"))] // native tests; tests/web.rs runs in the browser

use std::io::Write;
use std::process::{Command, Stdio};

fn nmci(args: &[&str], stdin: &str) -> (i32, String, String) {
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
