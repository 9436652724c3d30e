#!/usr/bin/env bash
# The README's Rust example as a user's crate builds and runs it: a crate outside nmci's
# workspace (a temporary directory; none of the workspace's [patch] entries apply) depending on
# nmci by path, built from its own lock (tests/dependent/Cargo.lock, --locked), with no system
# BLAS or LAPACK. Its build directory is target/dependent, kept between runs.
#   scripts/dependent.sh          -> build and run it, --locked
#   scripts/dependent.sh update   -> after nmci's dependencies changed: its lock refreshed from
#                                    the workspace's Cargo.lock (same versions where shared)
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
root=$PWD
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
mkdir -p "$dir/src"
sed "s|NMCI_PATH|$root|" tests/dependent/Cargo.toml > "$dir/Cargo.toml"
if [ "${1:-}" = update ]; then
  cp Cargo.lock "$dir/Cargo.lock"
  echo 'fn main() {}' > "$dir/src/main.rs"
  (cd "$dir" && cargo metadata --format-version 1 > /dev/null)
  cp "$dir/Cargo.lock" tests/dependent/Cargo.lock
  echo "[dependent] tests/dependent/Cargo.lock refreshed"
  exit 0
fi
cp tests/dependent/Cargo.lock "$dir/Cargo.lock"
# The README's one ```rust block, as copied by a reader.
awk '/^```rust$/ { inside = 1; next } /^```$/ && inside { exit } inside { print }' README.md > "$dir/src/main.rs"
[ -s "$dir/src/main.rs" ] || { echo "no \`\`\`rust block in README.md" >&2; exit 1; }
echo "[dependent] cargo run --locked in $dir (nmci by path, no [patch])"
(cd "$dir" && CARGO_TARGET_DIR="$root/target/dependent" cargo run --locked --quiet)
echo "[dependent] the README's Rust example ran"
