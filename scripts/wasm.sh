#!/usr/bin/env bash
# Build or test the wasm package with the settings in wasm-pack.toml.
#   scripts/wasm.sh build   -> wasm-pack build into [build].out_dir, then the "env" import guard
#   scripts/wasm.sh test    -> wasm-pack test in the headless browser of [test]
#   scripts/wasm.sh pack    -> the npm package: the build's files and npm/ in target/npm/nmci,
#                              packed by `npm pack` into target/npm/nmci-VERSION.tgz
set -euo pipefail
cd "$(dirname "$0")/.."

setting() { # section key
  python3 - "$1" "$2" <<'PY'
import sys, tomllib
with open("wasm-pack.toml", "rb") as f:
    value = tomllib.load(f)[sys.argv[1]][sys.argv[2]]
if isinstance(value, bool):
    print("true" if value else "false")
elif isinstance(value, list):
    print(" ".join(str(v) for v in value))
else:
    print(value)
PY
}

profile_flag() {
  case "$1" in
    release) echo --release ;;
    dev) echo --dev ;;
    *) echo "wasm-pack.toml: unknown profile '$1' (release | dev)" >&2; exit 2 ;;
  esac
}

case "${1:-}" in
  build)
    target=$(setting build target)
    out_dir=$(setting build out_dir)
    opt=()
    [ "$(setting build wasm_opt)" = "true" ] || opt=(--no-opt)
    wasm-pack build --mode no-install --target "$target" --out-dir "$out_dir" \
      "$(profile_flag "$(setting build profile)")" "${opt[@]}" --no-pack \
      -- --features "$(setting build features | tr ' ' ,)"
    # Guard: a symbol missing on wasm32 (e.g. an unpatched BLAS routine) becomes an import
    # from "env" instead of a link error. The package must import nothing from "env".
    node scripts/check-env-imports.mjs "$out_dir"
    # The docs the page's "What am I looking at?" panels link to, beside it (www/docs/, not
    # committed: docs/ is the one copy).
    mkdir -p www/docs
    cp docs/explorer.md docs/methods.md www/docs/
    ;;
  test)
    browser=$(setting test browser)
    headless=()
    [ "$(setting test headless)" = "true" ] && headless=(--headless)
    tests=()
    for t in $(setting test test_files); do tests+=(--test "$t"); done
    WASM_BINDGEN_TEST_TIMEOUT=$(setting test timeout_seconds) \
      wasm-pack test --mode no-install "${headless[@]}" "--$browser" \
      "$(profile_flag "$(setting test profile)")" -- -p nmci "${tests[@]}" \
      --features "$(setting test features | tr ' ' ,)"
    ;;
  pack)
    out_dir=$(setting build out_dir)
    "$0" build
    version=$(cargo metadata --no-deps --format-version 1 |
      python3 -c 'import json, sys; print(next(p["version"] for p in json.load(sys.stdin)["packages"] if p["name"] == "nmci"))')
    pkg=target/npm/nmci
    rm -rf target/npm && mkdir -p "$pkg"
    cp "$out_dir"/nmci.js "$out_dir"/nmci.d.ts "$out_dir"/nmci_bg.wasm "$out_dir"/nmci_bg.wasm.d.ts "$pkg"/
    cp npm/node.js npm/index.d.ts npm/contract.d.ts npm/README.md LICENSE-MIT LICENSE-APACHE "$pkg"/
    sed "s/@VERSION@/$version/" npm/package.json > "$pkg/package.json"
    (cd target/npm && npm pack --silent ./nmci >/dev/null)
    echo "target/npm/nmci-$version.tgz"
    ;;
  *)
    echo "usage: scripts/wasm.sh build|test|pack" >&2
    exit 2
    ;;
esac
