#!/usr/bin/env bash
# Fuzzing the JSON contract (issue 17): the structure-aware generator of tests/common/fuzz.rs
# through `fuse_json`, NMCI_FUZZ_CASES cases (default 100 000) split over one process per core
# (NMCI_FUZZ_JOBS, default nproc). Every case must end in a response or a typed error, never
# a panic. Not part of the test command, which runs the first 1000 cases of the same stream
# (and 150 of them through the wasm `fuse` in headless Chromium).
#   scripts/fuzz.sh                          -> cases 0..100000
#   NMCI_FUZZ_CASES=2000000 scripts/fuzz.sh  -> more
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
cases=${NMCI_FUZZ_CASES:-100000}
jobs=${NMCI_FUZZ_JOBS:-$(nproc)}
cargo test --test native --no-run
per=$(( (cases + jobs - 1) / jobs ))
mkdir -p target/fuzz
pids=()
for ((j = 0; j < jobs; j++)); do
  first=$(( j * per ))
  count=$(( cases - first < per ? cases - first : per ))
  [ "$count" -gt 0 ] || break
  NMCI_FUZZ_FIRST=$first NMCI_FUZZ_CASES=$count \
    cargo test -q --test native fuzz:: -- --nocapture >"target/fuzz/job-$j.log" 2>&1 &
  pids+=($!)
done
status=0
for pid in "${pids[@]}"; do wait "$pid" || status=1; done
grep -h "fuzz cases\|panicked\|case [0-9]*:" target/fuzz/job-*.log || true
if [ "$status" = 0 ]; then
  echo "[fuzz] $cases cases: no panic, every error typed (logs: target/fuzz/)"
else
  echo "[fuzz] FAILED (logs: target/fuzz/)" >&2
fi
exit "$status"
