#!/usr/bin/env bash
# Test strength of the core (issue 18): cargo-mutants on each file below with the tests that
# cover it (a selection that runs in seconds per mutant), one report per file in
# target/mutants/<file>/ (mutants.out/caught.txt, missed.txt, unviable.txt, timeout.txt).
# Not part of the test command: several hours on two cores for all files.
#   scripts/mutants.sh                  -> every file of the table
#   scripts/mutants.sh ci coin          -> the named rows only
# Needs `cargo install cargo-mutants --locked` (crates.io). Mutants are built in cargo-mutants'
# scratch copies of the tree, all sharing one target directory (target/mutants/build), so the
# dependencies are compiled once; .cargo/mutants.toml lists what is skipped and why.
# Never run two of these at once on one target directory: the crate's test binary has the
# same file name in every scratch copy, so each run would test the other's build.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
command -v cargo-mutants >/dev/null || { echo "cargo-mutants is missing: cargo install cargo-mutants --locked" >&2; exit 1; }

# row name | file | test filters (native test binary and the crate's unit tests)
table=(
  "structure|src/structure.rs|nmci_rule:: ci:: properties:: validation::"
  "ci|src/fusion/ci/*.rs|ci:: nmci_rule::"
  "nmci|src/fusion/nmci.rs|nmci_rule:: ci::"
  "known|src/fusion/known.rs|known rules:: fig2:: explore::known_correlation"
  "check|src/fusion/check.rs|check rules:: sample:: nmci_rule:: ci::"
  "sample|src/fusion/sample.rs|sample::"
  "coin|src/sim/coin.rs|study_coin:: coin::tests::"
  "scale|src/fusion/scale.rs|scale::tests validation::"
)

export CARGO_TARGET_DIR=$PWD/target/mutants/build
for row in "${table[@]}"; do
  IFS='|' read -r name file filters <<<"$row"
  if [ $# -gt 0 ] && [[ " $* " != *" $name "* ]]; then continue; fi
  echo "[mutants] $file (tests: $filters)"
  mkdir -p "target/mutants/$name"
  # Exit status 2: some mutants missed, 3: some timed out (reported below); others are errors.
  status=0
  # shellcheck disable=SC2086
  cargo mutants -f "$file" -o "target/mutants/$name" -- --lib --test native -- $filters || status=$?
  [ "$status" = 0 ] || [ "$status" = 2 ] || [ "$status" = 3 ] || { echo "[mutants] cargo mutants failed ($status)" >&2; exit "$status"; }
  out=target/mutants/$name/mutants.out
  printf '[mutants] %s: caught %s, missed %s, unviable %s, timeout %s\n' "$file" \
    "$(wc -l <"$out/caught.txt")" "$(wc -l <"$out/missed.txt")" "$(wc -l <"$out/unviable.txt")" "$(wc -l <"$out/timeout.txt")"
done
