"""Stone Soup's own tests and example, run against nmci's components (issue: "works with
Stone Soup" means Stone Soup's tests pass, not only ours).

The sources are Stone Soup's sdist of the installed version, which ``scripts/python.sh test``
fetches from PyPI into ``target/stonesoup-src`` (``NMCI_STONESOUP_SRC`` points elsewhere).
Their test files run unmodified, in a separate pytest process, with the plugin
``upstream/substitute.py`` putting ``NmciUpdater`` where they import ``ChernoffUpdater`` and
nmci's reducer where they import ``CovarianceIntersection``.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

stonesoup = pytest.importorskip("stonesoup")

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent


def source() -> Path:
    src = Path(os.environ.get("NMCI_STONESOUP_SRC", ROOT / "target" / "stonesoup-src"))
    tree = src / f"stonesoup-{stonesoup.__version__}"
    if not tree.is_dir():
        pytest.skip(f"Stone Soup's sources are not at {tree} (scripts/python.sh test fetches them)")
    return tree


def run_upstream(files, selection=None, tmp_path=None):
    """Stone Soup's test ``files`` (with their conftest), copied as they are, run with the
    substitution plugin; returns (exit code, output)."""
    work = tmp_path / "upstream"
    work.mkdir()
    for f in files:
        (work / f.name).write_bytes(f.read_bytes())
        conftest = f.parent / "conftest.py"
        if conftest.exists():
            (work / "conftest.py").write_bytes(conftest.read_bytes())
    command = [sys.executable, "-m", "pytest", "-q", "-p", "substitute", "--import-mode=importlib",
               "-p", "no:cacheprovider", str(work)]
    if selection:
        command += ["-k", selection]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE / "upstream"), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run(command, capture_output=True, text=True, env=env, cwd=work, timeout=600)
    return done.returncode, done.stdout + done.stderr


def test_stone_soups_test_chernoff_passes_with_nmci_updater(tmp_path):
    tree = source()
    code, out = run_upstream([tree / "stonesoup/updater/tests/test_chernoff.py"], tmp_path=tmp_path)
    assert code == 0 and "1 passed" in out, out


def test_stone_soups_covariance_intersection_tests_pass_with_nmcis_reducer(tmp_path):
    tree = source()
    code, out = run_upstream([tree / "stonesoup/mixturereducer/tests/test_gaussian_mixture_reducer.py"],
                             selection="covariance_intersection", tmp_path=tmp_path)
    assert code == 0 and "17 passed" in out, out


def test_stone_soups_track_fusion_example_and_data_incest_tutorial_run_with_the_readme_switch():
    """Stone Soup's ``Track2Track_Fusion_Example`` (two range-bearing radars: the axes are
    coupled, so the declared blocks are violated and merged) and its data-incest tutorial, each
    ``ChernoffUpdater`` line replaced by the README's three lines, run end to end on shortened
    scenarios (examples/python/stonesoup_upstream_runs.py): every fused track's covariance is
    finite and positive semi-definite, and the metrics are finite beside ChernoffUpdater's."""
    source()
    sys.path.insert(0, str(ROOT / "examples" / "python"))
    try:
        import stonesoup_upstream_runs as runs
    finally:
        sys.path.pop(0)
    rows = runs.main(["--quick"])
    assert len(rows) == 4
    for name, label, r in rows:
        assert r["states"] > 0 and r["improper"] == 0, (name, label, r)
        for key in ("rmse", "nees", "trace"):
            assert r[key] == r[key] and r[key] < float("inf"), (name, label, key, r)
