#!/usr/bin/env bash
# Runs the benchmarks and writes docs/benchmarks.md: `scripts/bench.sh [rust|brackets|study|python|browser ...]`
# (all sections by default; scripts/bench.py says what each runs). Run it on an idle machine.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
scripts/setup.sh test
exec python3 scripts/bench.py "$@"
