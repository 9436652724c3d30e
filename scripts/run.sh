#!/usr/bin/env bash
# The main job: install what is missing, build the wasm package, serve the explorer.
#   PORT=8081 scripts/run.sh   -> serve on another port (default 8080)
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
port=${PORT:-8080}
# A port that is taken is said before the build, in one line (tests/e2e/run-script.test.mjs).
if ! python3 -c 'import socket, sys; s = socket.socket(); s.bind(("127.0.0.1", int(sys.argv[1])))' "$port" 2>/dev/null; then
  echo "scripts/run.sh: port $port on 127.0.0.1 is taken (another server?); choose another: PORT=$((port + 1)) scripts/run.sh" >&2
  exit 1
fi
scripts/setup.sh build
scripts/wasm.sh build
echo
echo "nmci explorer: http://127.0.0.1:$port/"
echo "(Ctrl-C stops the server)"
# Python's file server, with the docs the page links to served as UTF-8 text.
exec python3 - "$port" <<'PY'
import functools, http.server, sys

class Handler(http.server.SimpleHTTPRequestHandler):
    extensions_map = {**http.server.SimpleHTTPRequestHandler.extensions_map,
                      ".md": "text/markdown; charset=utf-8", ".wasm": "application/wasm", ".js": "text/javascript"}

server = http.server.ThreadingHTTPServer(("127.0.0.1", int(sys.argv[1])), functools.partial(Handler, directory="www"))
try:
    server.serve_forever()
except KeyboardInterrupt:
    pass
PY
