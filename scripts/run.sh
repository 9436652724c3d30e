#!/usr/bin/env bash
# The main job: install what is missing, build the wasm package, serve the explorer.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
scripts/setup.sh build
scripts/wasm.sh build
port=${PORT:-8080}
echo
echo "nmci explorer: http://127.0.0.1:$port/"
echo "(Ctrl-C stops the server)"
exec python3 -m http.server "$port" --bind 127.0.0.1 --directory www
