#!/usr/bin/env bash
# The Python package (python/): a virtual environment in target/py with maturin, numpy and the
# test tools from PyPI (created once, idempotent), the abi3 wheel built by maturin into
# target/wheels and installed there.
#   scripts/python.sh build   -> the wheel, installed into target/py
#   scripts/python.sh test    -> build, then pytest python/tests against the `nmci` CLI
#   scripts/python.sh bench   -> build, then scripts/bench_python.py (installs scipy and cvxpy)
#   scripts/python.sh bench-stack -> build, then scripts/bench_stack.py
#   scripts/python.sh bench-stonesoup -> build, then scripts/bench_stonesoup.py
#   scripts/python.sh accuracy -> build, then scripts/accuracy.py (50-digit references)
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
what=${1:-test}
venv=target/py
py=$venv/bin/python
say() { printf '[python] %s\n' "$*"; }

if [ ! -x "$py" ]; then
  say "creating the virtual environment $venv"
  python3 -m venv "$venv"
fi
# distributed: Dask's local cluster, which examples/python/sharded_study.py runs shards on;
# mpmath: the 50-digit references of the accuracy tests; stonesoup: the plugin nmci.stonesoup
# (its tests, the stack benchmark's ChernoffUpdater peer); graphviz, networkx, pydot,
# ordered_set: what Stone Soup's architecture tutorial imports (python/tests/test_stonesoup_upstream.py).
# ziglang: the linker maturin builds the manylinux2014 (glibc 2.17) wheel with, so it installs
# on RHEL/Rocky 8 and 9 clusters, not only on this machine's glibc.
need=(maturin numpy pytest scipy distributed mpmath stonesoup graphviz networkx pydot ordered_set ziglang)
[ "$what" = bench ] && need+=(cvxpy clarabel)
missing=()
for p in "${need[@]}"; do
  "$py" -c "import $p" 2>/dev/null || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  say "installing ${missing[*]} from PyPI"
  "$py" -m pip install -q --disable-pip-version-check "${missing[@]}"
fi

say "building the wheel (maturin, release)"
rm -rf target/wheels
(cd python && PATH="$PWD/../$venv/bin:$PATH" VIRTUAL_ENV="$PWD/../$venv" "../$venv/bin/maturin" build --release --quiet \
  -i "../$py" --zig --compatibility manylinux2014 -o ../target/wheels)
"$py" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps target/wheels/nmci-*.whl

case "$what" in
  build) ;;
  test)
    # Stone Soup's own tests and examples (not in its wheel): its sdist of the installed
    # version, from PyPI, once (python/tests/test_stonesoup_upstream.py runs them).
    ss_version=$("$py" -c 'import stonesoup; print(stonesoup.__version__)')
    ss_src=target/stonesoup-src
    if [ ! -f "$ss_src/stonesoup-$ss_version/docs/tutorials/architecture/03_Avoiding_Data_Incest.py" ]; then
      say "fetching Stone Soup $ss_version's sources (its tests and examples) from PyPI"
      rm -rf "$ss_src" && mkdir -p "$ss_src"
      "$py" -m pip download -q --disable-pip-version-check --no-deps --no-binary :all: \
        "stonesoup==$ss_version" -d "$ss_src"
      tar -xzf "$ss_src/stonesoup-$ss_version.tar.gz" -C "$ss_src" \
        "stonesoup-$ss_version/stonesoup" "stonesoup-$ss_version/docs/examples" \
        "stonesoup-$ss_version/docs/tutorials/architecture"
    fi
    # The CLI to compare with: the dev build (`cargo test` has built its dependencies); the
    # contract tests compare its output with the release wheel's to the bit.
    cargo build --quiet -p nmci-cli
    NMCI_CLI="$PWD/target/debug/nmci" "$py" -m pytest -q --durations=10 python/tests
    ;;
  bench)
    "$py" scripts/bench_python.py
    ;;
  bench-stonesoup)
    "$py" scripts/bench_stonesoup.py
    ;;
  bench-stack)
    "$py" scripts/bench_stack.py
    ;;
  accuracy)
    "$py" scripts/accuracy.py
    ;;
  *) echo "usage: scripts/python.sh build|test|bench|bench-stack|bench-stonesoup|accuracy" >&2; exit 2 ;;
esac
