#!/usr/bin/env python3
"""Runs the benchmarks and writes docs/benchmarks.md (called by scripts/bench.sh).

Every figure the README and docs quote about speed or bracket closure comes from this report:
each section gives its command, and the header the commit, date and machine of the one run
that produced them all, peers (numpy, scipy, cvxpy) measured in the same run.

Sections (each one command, run in order on an otherwise idle machine):
  rust      criterion benches of benches/fusion.rs (a chosen set, shortened measurement)
  brackets  examples/certify_levels: proven brackets at 2 and 3 states, the default certificate
            and, at 3 states, the cutting planes' own rule proven on cones where it leaves them open
  explorer  the same at 3 states as the explorer's second stage runs sdp_cuts (1e-7, 30 s, stopped at a
            bracket of 1e-6; 128 and 64 cones)
  brackets4 the same at 4 states, 5 problems per class (each takes minutes)
  families  examples/certify_levels: the certificate families on the brackets' problems (2 states:
            levels 1-5, 16/24/32 sectors; 3 states: levels 1-3, 64 cones, adaptive up to 32)
  cuts      examples/cuts_probe: sdp_cuts at 3 to 6 states, its bracket and fresh margins
  study     `nmci track` (release), the paper's 16-agent study, and its headline result
  python    scripts/python.sh bench: nmci from Python against numpy, scipy and cvxpy
  stack     scripts/python.sh bench-stack: k pairs by CI, nmci's stack against numpy, a loop, Stone Soup
  accuracy  scripts/python.sh accuracy: CI, ICI, EI and naive against 50-digit references, beside numpy
  browser   tests/e2e/bench-explore.mjs and bench-study.mjs in headless Chromium

`scripts/bench.sh [SECTION ...]` runs the named sections only and keeps the others' last
results (docs/benchmarks.md holds each section's own run date and commit then).
"""

import datetime
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REPORT = ROOT / "docs" / "benchmarks.md"
STATE = ROOT / "docs" / "benchmarks.json"  # each section's last output, for partial reruns

# The criterion benches reported: (filter regex, what it measures).
RUST_BENCHES = [
    ("^ci/trace/", "CI, exact optimal ω (trace), two random SPD covariances of n states"),
    ("^nmci/112x8$", "nmCI on the study's 112 states in 8 independent blocks"),
    ("^eigen/symmetric/112$", "nalgebra's symmetric eigendecomposition at n = 112 (the floor of a CI)"),
    ("^sdp/paper/", "the sampled SDP on the paper's example, by sample count"),
    ("^fuse/sdp/", "a whole `sdp` request of 1000 samples, proven bracket included"),
    ("^certified/1/paper_one_zero$", "the certified rule, level 1, paper's example with one known zero"),
    ("^certified/2/random3$", "the certified rule, level 2, a random 3-state problem"),
    ("^explore/", "the explorer's analysis of a preset (every rule, bracket, margins), native"),
    ("^stack/", "a stack of 10⁴ pairs of 4-state estimates through `fuse_stack` (nmCI: diagonal pattern); one thread, `/parallel` on rayon's default pool"),
    ("^eigen/symmetric/4x10000$", "10⁴ nalgebra symmetric eigendecompositions of 4 × 4 matrices (the floor of a CI stack)"),
]


def sh(cmd, **kw):
    """Runs `cmd` (a shell string) in the repository, echoing it; returns stdout."""
    print(f"$ {cmd}", file=sys.stderr, flush=True)
    out = subprocess.run(cmd, shell=True, cwd=ROOT, check=True, capture_output=True, text=True, **kw)
    sys.stderr.write(out.stderr[-2000:])
    return out.stdout


def machine():
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        kb = int(re.search(r"MemTotal:\s+(\d+)", Path("/proc/meminfo").read_text()).group(1))
        mem = f", {kb / 2**20:.0f} GiB"
    except (OSError, AttributeError):
        pass
    rustc = subprocess.run(["rustc", "--version"], capture_output=True, text=True).stdout.strip()
    return f"{cpu}, {os.cpu_count()} cores{mem}, {platform.system()} {platform.release()}; {rustc}"


def commit():
    rev = sh("git rev-parse --short HEAD").strip()
    dirty = sh("git status --porcelain --untracked-files=no -- src cli python benches examples scripts tests www Cargo.toml Cargo.lock").strip()
    return rev + (" with uncommitted changes" if dirty else "")


def rust():
    filt = "|".join(f"({f})" for f, _ in RUST_BENCHES)
    cmd = f"cargo bench --bench fusion -- --warm-up-time 1 --measurement-time 4 '{filt}'"
    out = sh(cmd)
    rows = []
    # criterion: "<id>  time:   [low est high]" (the id may be on its own line before).
    pending = None
    for line in out.splitlines():
        m = re.match(r"^(\S.*?)\s+time:\s+\[(.*?)\]", line)
        if m:
            rows.append((m.group(1).strip(), m.group(2)))
            pending = None
            continue
        m = re.match(r"^\s+time:\s+\[(.*?)\]", line)
        if m and pending:
            rows.append((pending, m.group(1)))
            pending = None
            continue
        if line and not line.startswith(" ") and "time:" not in line and not line.startswith(("Benchmarking", "Found", "Warning", "change", "Performance", "No change", "  ")):
            pending = line.strip()
    table = ["| bench | what | time (criterion's estimate, its interval) |", "|---|---|---|"]
    for name, times in rows:
        what = next((w for f, w in RUST_BENCHES if re.search(f, name)), "")
        v = times.split()
        shown = f"**{v[2]} {v[3]}** ({v[0]} {v[1]} – {v[4]} {v[5]})" if len(v) == 6 else times
        table.append(f"| `{name}` | {what} | {shown} |")
    return cmd, "\n".join(table)


def brackets():
    # The defaults: two states, 24 sectors (level 1 beside it); three states, level 2, and
    # what `sdp_cuts` reports: level 2, else its own rule proven on at most 128 cones (the
    # default), with the cutting planes at 1e-10.
    return certify_levels([
        "--dims 2 --count 50 --levels 1 --sectors 24",
        "--dims 3 --count 50 --levels 2 --own-rule 128",
    ])


def explorer():
    # Three states as the explorer's second stage runs `sdp_cuts`: the loop's default tolerance
    # (1e-7), a time limit of 30 s (`PROVE_SECONDS`, www/prove-client.js) and a stop as soon
    # as the bracket is closed to 1e-6 (`explore::prove`), with the default budget of 128 cones
    # and with 64 (closed fraction against the cone budget).
    return certify_levels([
        "--dims 3 --count 50 --levels 2 --own-rule 128 --cuts-tol 1e-7 --time-limit 30 --bracket-rtol 1e-6",
        "--dims 3 --count 50 --levels 2 --own-rule 64 --cuts-tol 1e-7 --time-limit 30 --bracket-rtol 1e-6",
    ])


def certify_levels(runs):
    """`examples/certify_levels` once per argument list: the commands and their tables."""
    parts = []
    cmds = []
    for args in runs:
        cmd = f"cargo run --quiet --release --example certify_levels -- {args}"
        cmds.append(cmd)
        out = sh(cmd)
        parts.append("\n".join(l for l in out.splitlines() if l.startswith("|")))
    return " ; ".join(cmds), "\n\n".join(parts)


def brackets4():
    # Four states: the default certificate (level 1), and the cutting planes' own rule proven
    # by `certify_rule` on at most 64 cones of ℝ⁴ where it leaves the bracket open (what
    # `sdp_cuts` does at three states; at four it stops at the guide).
    cmd = "cargo run --quiet --release --example certify_levels -- --dims 4 --count 5 --levels 1 --own-rule 64"
    out = sh(cmd)
    return cmd, "\n".join(l for l in out.splitlines() if l.startswith("|"))


def families():
    # The certified rule's families on the brackets' problems (docs/methods.md, "How closed the brackets are"):
    # at two states levels 1-5 and 16, 24 (the default) and 32 sectors; at three, level 1,
    # level 2 (the default), level 3, 64 uniform cones and at most 32 adaptive cones.
    return certify_levels([
        "--dims 2 --count 50 --levels 1,2,3,4,5 --sectors 16,24,32",
        "--dims 3 --count 50 --levels 1,2,3 --cones 64 --adaptive 32",
    ])


def cuts():
    # The cutting planes, guided by the certified rule (the default), at 3 to 6 states
    # (docs/methods.md, "Worst-case constraints").
    cmd = "PROBE_GUIDED_ONLY=1 cargo run --quiet --release --example cuts_probe -- 3 4 5 6"
    out = sh(cmd)
    return cmd, "\n".join(l for l in out.splitlines() if l.startswith("|"))


def study():
    sh("cargo build --quiet --release -p nmci-cli")
    with tempfile.TemporaryDirectory() as out:
        cmd = f"target/release/nmci track --out {out}"
        t = time.perf_counter()
        sh(cmd)
        seconds = time.perf_counter() - t
        summary = json.loads(Path(out, "summary.json").read_text())
        same = all(
            Path(out, f.name).read_bytes() == f.read_bytes()
            for f in (ROOT / "docs/figures/track").iterdir()
            if f.is_file() and (Path(out) / f.name).exists()
        )
    ci, nm = summary["ci"], summary["nmci"]
    rmse = 1 - nm["rmse_mean"] / ci["rmse_mean"]
    two = 1 - nm["two_sigma_mean"] / ci["two_sigma_mean"]
    text = (
        f"{summary['runs']} runs × {summary['steps']} steps, five estimators and the exact COIN: "
        f"**{seconds:.1f} s** wall clock on this machine's cores "
        f"({'files byte-identical to' if same else 'files DIFFER from'} `docs/figures/track`).\n\n"
        f"| | CI | nmCI | nmCI against CI |\n|---|---|---|---|\n"
        f"| mean position RMSE | {ci['rmse_mean']:.4g} | {nm['rmse_mean']:.4g} | {-100 * rmse:+.0f} % |\n"
        f"| mean 2σ | {ci['two_sigma_mean']:.4g} | {nm['two_sigma_mean']:.4g} | {-100 * two:+.0f} % |\n"
        f"| largest exact COIN | {ci['coin_max']:.4g} | {nm['coin_max']:.4g} | |"
    )
    return f"time {cmd}", text


def python():
    cmd = "scripts/python.sh bench"
    out = sh(f"bash {cmd}")
    # The script's own progress lines (`[python] …`) are not results.
    lines = [l for l in out.strip().splitlines() if not l.startswith(("[python] ", "🛠"))]
    # A blank line between the versions and the table (a table does not interrupt a paragraph).
    return cmd, "\n".join(l + ("\n" if l.startswith("numpy ") else "") for l in lines)


def stack():
    cmd = "scripts/python.sh bench-stack"
    out = sh(f"bash {cmd}")
    return cmd, "\n".join(l for l in out.strip().splitlines() if not l.startswith(("[python] ", "🛠")))


def stonesoup():
    cmd = "scripts/python.sh bench-stonesoup"
    out = sh(f"bash {cmd}")
    # The table only (maturin's and the script's progress lines are not results).
    return cmd, "\n".join(l for l in out.strip().splitlines() if l.startswith("|"))


def accuracy():
    # CI, ICI, EI and naive against 50-digit references (docs/methods.md, "CI's accuracy").
    cmd = "scripts/python.sh accuracy"
    out = sh(f"bash {cmd}")
    return cmd, "\n".join(l for l in out.strip().splitlines() if not l.startswith(("[python] ", "🛠")))


def browser():
    sh("bash scripts/wasm.sh build")
    cmds, lines = [], []
    for cmd in ["node tests/e2e/bench-explore.mjs 30", "node tests/e2e/bench-study.mjs 3"]:
        cmds.append(cmd)
        out = sh(cmd)
        lines += [f"- {l}" for l in out.splitlines() if "min " in l or "median" in l]
    return " ; ".join(cmds), "\n".join(lines)


SECTIONS = {
    "rust": ("Rust (criterion)", rust),
    "brackets": ("Proven brackets (the certified rule, and the cutting planes' own rule proven, against the cutting planes' lower end)", brackets),
    "explorer": ("Proven brackets as the explorer's second stage runs them (cutting planes to 1e-7, 30 s)", explorer),
    "brackets4": ("Proven brackets at four states (the cutting planes' own rule proven on cones of ℝ⁴)", brackets4),
    "families": ("Certificate families at two and three states (levels, sectors, uniform and adaptive cones)", families),
    "cuts": ("The cutting planes (`sdp_cuts`) at 3 to 6 states", cuts),
    "study": ("The 16-agent tracking study", study),
    "python": ("From Python, beside numpy, scipy and cvxpy", python),
    "stack": ("Stacks: k pairs by CI in one call, one thread", stack),
    "stonesoup": ("Stone Soup: one update per rule, a 4-state track pair", stonesoup),
    "accuracy": ("Accuracy of the closed-form rules against 50-digit references", accuracy),
    "browser": ("In the browser (wasm, headless Chromium)", browser),
}


def write_report(state):
    lines = [
        "# Benchmarks",
        "",
        "Generated by `scripts/bench.sh` (do not edit: rerun it). Each section gives the command",
        "that produced it and the commit, date and machine of that run; peers in a section were",
        "measured in the same run. Times are wall clock on the machine named.",
        "",
    ]
    for key, (title, _) in SECTIONS.items():
        if key not in state:
            continue
        s = state[key]
        lines += [
            f"## {title}",
            "",
            f"`{s['command']}` — commit {s['commit']}, {s['date']}, {s['machine']}.",
            "",
            s["body"],
            "",
        ]
    missing = [key for key in SECTIONS if key not in state]
    if missing:
        lines += [
            f"Not in this report yet: {', '.join(missing)} (`scripts/bench.sh {' '.join(missing)}`).",
            "",
        ]
    REPORT.write_text("\n".join(lines))
    print(f"wrote {REPORT.relative_to(ROOT)}", file=sys.stderr)


def main():
    wanted = sys.argv[1:] or list(SECTIONS)
    unknown = [w for w in wanted if w not in SECTIONS]
    if unknown:
        sys.exit(f"unknown section(s) {unknown}; sections: {', '.join(SECTIONS)}")
    state = json.loads(STATE.read_text()) if STATE.exists() else {}
    rev, when, where = commit(), datetime.date.today().isoformat(), machine()
    for key in wanted:
        title, run = SECTIONS[key]
        cmd, body = run()
        state[key] = {"command": cmd, "body": body, "commit": rev, "date": when, "machine": where}
        STATE.write_text(json.dumps(state, indent=1, ensure_ascii=False) + "\n")
        write_report(state)  # after each section: a stopped run leaves the sections it finished


if __name__ == "__main__":
    main()
