#!/usr/bin/env bash
# Installs what nmci's commands need on a fresh machine of this kind; idempotent and quick
# when everything is present.
#   scripts/setup.sh build   -> wasm32 target, wasm-pack, wasm-bindgen-cli (the version in Cargo.lock)
#   scripts/setup.sh test    -> the above, plus Debian's Chromium + ChromeDriver and the e2e npm packages
set -euo pipefail
cd "$(dirname "$0")/.."
what=${1:-test}
say() { printf '[setup] %s\n' "$*"; }

export PATH="$HOME/.cargo/bin:$PATH"

if ! rustup target list --installed | grep -qx wasm32-unknown-unknown; then
  say "adding the wasm32-unknown-unknown target"
  rustup target add wasm32-unknown-unknown
fi

if ! command -v wasm-pack >/dev/null 2>&1; then
  say "installing wasm-pack"
  cargo install wasm-pack --locked
fi

# wasm-bindgen-cli must match the wasm-bindgen version pinned in Cargo.toml / Cargo.lock.
wb_version=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)
if [ -z "$wb_version" ]; then
  say "cannot find wasm-bindgen in Cargo.lock"
  exit 1
fi
if ! wasm-bindgen --version 2>/dev/null | grep -qw "$wb_version"; then
  say "installing wasm-bindgen-cli $wb_version"
  cargo install wasm-bindgen-cli --version "$wb_version" --locked --force ||
    cargo install wasm-bindgen-cli --version "$wb_version" --force
fi

command -v node >/dev/null 2>&1 || { say "node is required (it ships with this machine kind)"; exit 1; }

if [ "$what" = test ]; then
  if ! command -v chromium >/dev/null 2>&1 || ! command -v chromedriver >/dev/null 2>&1; then
    say "installing Debian's chromium and chromium-driver"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium chromium-driver
  fi
  if [ ! -d tests/e2e/node_modules/playwright-core ] || [ ! -d tests/e2e/node_modules/typescript ]; then
    say "installing the end-to-end tests' npm packages (playwright-core drives /usr/bin/chromium, no browser download; typescript checks the npm package's types)"
    (cd tests/e2e && PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm ci --no-audit --no-fund --loglevel=error)
  fi
fi
say "ready ($what)"
