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


def readme_switch() -> str:
    text = (ROOT / "README.md").read_text()
    start = text.index("```python\nfrom nmci.stonesoup") + len("```python\n")
    return text[start: text.index("```", start)]


def test_stone_soups_radar_track_fusion_example_runs_with_the_readme_switch(tmp_path):
    """Stone Soup's ``Track2Track_Fusion_Example`` (two radars, range-bearing: the axes are
    coupled, so the declared blocks are violated and merged), its ``ChernoffUpdater`` line
    replaced by the README's three lines, run end to end on a shortened scenario."""
    tree = source()
    example = (tree / "docs/examples/trackfusion/Track2Track_Fusion_Example.py").read_text()
    line = "ch_updater = ChernoffUpdater(measurement_model=None)"
    assert line in example and "num_steps = 50" in example
    switched = example.replace(line, "transition_model = truth_transition_model\n" + readme_switch()
                               + "ch_updater = track_updater\n")
    switched = switched.replace("num_steps = 50", "num_steps = 12")
    script = tmp_path / "example.py"
    script.write_text(
        "import matplotlib\nmatplotlib.use('Agg')\nimport warnings\n"
        "import numpy as np\nnp.random.seed(1990)\n"
        + switched
        + "\nstates = [s for t in track_fusion_tracks for s in t]\n"
        "assert all(np.all(np.isfinite(s.covar)) and np.linalg.eigvalsh((s.covar + s.covar.T) / 2).min()"
        " >= -1e-9 * np.abs(s.covar).max() for s in states)\n"
        "print('NMCI-EXAMPLE-DONE', len(track_fusion_tracks), len(states))\n")
    env = dict(os.environ, MPLBACKEND="Agg")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env,
                          cwd=tmp_path, timeout=900)
    assert done.returncode == 0 and "NMCI-EXAMPLE-DONE" in done.stdout, done.stdout[-3000:] + done.stderr[-3000:]
