#!/usr/bin/env bash
# Every test: install what is missing, then native (cargo test), wasm in headless Chromium
# (wasm-pack test), the page end-to-end in headless Chromium, the npm package, and the Python
# package (pytest).
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
scripts/setup.sh test

echo "== layers: the library's dependencies and its modules' imports (scripts/layers.py)"
python3 scripts/layers.py

echo "== native: cargo test (crate, BLAS/LAPACK shims, CLI, doc examples)"
cargo test --workspace --exclude nmci-python --all-features

echo "== dependent: the README's Rust example as a crate outside the workspace (no [patch], no system BLAS/LAPACK)"
scripts/dependent.sh

echo "== wasm: wasm-pack test in headless Chromium"
scripts/wasm.sh test

echo "== page and npm package: build and pack the wasm, drive the explorer in headless Chromium, install the package and run its example"
scripts/wasm.sh pack
node --test tests/e2e/

echo "== python: build the wheel (maturin) into target/py and run pytest"
scripts/python.sh test
