#!/usr/bin/env bash
# Every test: install what is missing, then formatting and lints, native (cargo test), a crate
# depending on nmci from outside the workspace, wasm in headless Chromium (wasm-pack test), the
# page end-to-end in headless Chromium, the npm package, and the Python package (pytest).
#   scripts/test.sh         -> all of it (the README's test command; CI runs it)
#   scripts/test.sh quick   -> the contributor's tier: formatting, lints, the library's unit
#                              tests, the shims' and the CLI's tests (minutes, no browser)
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
what=${1:-all}

# Each stage's heading, with the minutes and seconds the command has run so far.
stage() { printf '== [%d:%02d] %s\n' $((SECONDS / 60)) $((SECONDS % 60)) "$*"; }
trap 'stage "end, exit status $?"' EXIT

lint() {
  stage "format and lints: cargo fmt --check, cargo clippy -D warnings (native, and the library for wasm32)"
  cargo fmt --all --check
  cargo clippy --workspace --all-targets --all-features --quiet -- -D warnings
  cargo clippy -p nmci --target wasm32-unknown-unknown --lib --features charts --quiet -- -D warnings
  python3 scripts/layers.py
}

case "$what" in
  quick)
    scripts/setup.sh build
    lint
    stage "quick: the library's unit tests, the shims, the CLI"
    cargo test --quiet -p nmci --lib --all-features
    cargo test --quiet -p blas -p lapack -p nmci-cli
    exit 0
    ;;
  all) ;;
  *) echo "usage: scripts/test.sh [quick]" >&2; exit 2 ;;
esac

scripts/setup.sh test
lint

stage "native: cargo test (crate, BLAS/LAPACK shims, CLI, doc examples)"
cargo test --workspace --exclude nmci-python --all-features

stage "dependent: the README's Rust example as a crate outside the workspace (no [patch], no system BLAS/LAPACK)"
scripts/dependent.sh

stage "wasm: wasm-pack test in headless Chromium"
scripts/wasm.sh test

stage "page and npm package: build and pack the wasm, drive the explorer in headless Chromium, install the package and run its example"
scripts/wasm.sh pack
node --test tests/e2e/

stage "python: build the wheel (maturin) into target/py and run pytest"
scripts/python.sh test
