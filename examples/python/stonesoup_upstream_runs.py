"""Stone Soup's own track-fusion example and data-incest tutorial, run as Stone Soup ships them
and with the README's three-line switch to nmci, side by side.

The sources are Stone Soup's sdist of the installed version (``scripts/python.sh test`` fetches
it into ``target/stonesoup-src``; ``NMCI_STONESOUP_SRC`` points elsewhere). Each script's
``ChernoffUpdater`` line is replaced by the README's block (``transition_model`` bound to the
script's own model), nothing else; the scenario length can be shortened. For the fused tracks
it reports the position RMSE against the nearest truth at each time, the mean NEES (full state,
against that truth's state) and the mean covariance trace.

    target/py/bin/python examples/python/stonesoup_upstream_runs.py [--quick]

``python/tests/test_stonesoup_upstream.py`` runs it with ``--quick`` (the short scenarios);
docs/python.md quotes a full run.
"""

import argparse
import contextlib
import io
import os
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def source_tree() -> Path:
    import stonesoup

    src = Path(os.environ.get("NMCI_STONESOUP_SRC", ROOT / "target" / "stonesoup-src"))
    tree = src / f"stonesoup-{stonesoup.__version__}"
    if not tree.is_dir():
        raise SystemExit(f"Stone Soup's sources are not at {tree} (scripts/python.sh test fetches them)")
    return tree


def readme_switch() -> str:
    text = (ROOT / "README.md").read_text()
    start = text.index("```python\nfrom nmci.stonesoup") + len("```python\n")
    return text[start: text.index("```", start)]


#: (name, script, the ChernoffUpdater line, the name the updater takes, the transition model's
#: name, the scenario-length setting and its short value, the positions' state indices,
#: how to read (tracks, truths) from the script's namespace).
SCRIPTS = [
    ("Track2Track_Fusion_Example (two radars, GM-PHD)",
     "docs/examples/trackfusion/Track2Track_Fusion_Example.py",
     "ch_updater = ChernoffUpdater(measurement_model=None)", "ch_updater", "truth_transition_model",
     ("num_steps = 50", "num_steps = 12"), [0, 2, 4],
     lambda ns: (ns["track_fusion_tracks"], ns["truths"])),
    ("03_Avoiding_Data_Incest (hierarchical, Fusion Node 1)",
     "docs/tutorials/architecture/03_Avoiding_Data_Incest.py",
     "track_updater = ChernoffUpdater(None)", "track_updater", "transition_model",
     ("time_max = 60", "time_max = 20"), [0, 2],
     lambda ns: ([n.tracks for n in ns["H_architecture"].fusion_nodes if n.label == "Fusion Node 1"][0],
                 ns["truths"])),
]


def metrics(tracks, truths, positions):
    """Position RMSE against the nearest truth at each time, mean NEES, mean trace, and how many
    covariances are not finite and positive semi-definite (to rounding)."""
    by_time = {}
    for truth in truths:
        for state in truth:
            by_time.setdefault(state.timestamp, []).append(np.ravel(state.state_vector).astype(float))
    squared, nees, traces, improper = [], [], [], 0
    for track in tracks:
        for state in track:
            candidates = by_time.get(state.timestamp)
            if not candidates:
                continue
            x = np.ravel(state.state_vector).astype(float)
            truth = min(candidates, key=lambda t: np.linalg.norm(t[positions] - x[positions]))
            e = x - truth
            P = np.asarray(state.covar, dtype=float)
            if not np.all(np.isfinite(P)) or np.linalg.eigvalsh((P + P.T) / 2).min() < -1e-9 * np.abs(P).max():
                improper += 1
            squared.append(float(e[positions] @ e[positions]))
            nees.append(float(e @ np.linalg.pinv(P) @ e))
            traces.append(float(np.trace(P)))
    if not squared:
        return {"states": 0, "rmse": float("nan"), "nees": float("nan"), "trace": float("nan"), "improper": 0}
    return {"states": len(squared), "rmse": float(np.sqrt(np.mean(squared))),
            "nees": float(np.mean(nees)), "trace": float(np.mean(traces)), "improper": improper}


def run(script, switched: bool, short: bool):
    """One script, as shipped or switched: its metrics."""
    import matplotlib

    matplotlib.use("Agg")
    name, path, line, updater, model, (length, short_length), positions, read = script
    text = (source_tree() / path).read_text()
    if line not in text or length not in text:
        raise SystemExit(f"{path}: the lines this run replaces are not there ({line!r}, {length!r})")
    if switched:
        text = text.replace(line, f"transition_model = {model}\n{readme_switch()}{updater} = track_updater\n")
    if short:
        text = text.replace(length, short_length)
    np.random.seed(1990)
    namespace = {"__name__": "__stonesoup_script__"}
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        exec(compile(text, path, "exec"), namespace)
    tracks, truths = read(namespace)
    return metrics(tracks, truths, positions)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the short scenarios (the tests')")
    args = parser.parse_args(argv)
    rows = []
    for script in SCRIPTS:
        for label, switched in (("ChernoffUpdater(None) (as shipped)", False), ("README switch (nmci)", True)):
            r = run(script, switched, args.quick)
            rows.append((script[0], label, r))
    print("| script | updater | fused states | position RMSE | mean NEES | mean trace |")
    print("|---|---|---|---|---|---|")
    for name, label, r in rows:
        print(f"| {name} | {label} | {r['states']} | {r['rmse']:.3g} | {r['nees']:.3g} | {r['trace']:.4g} |")
    return rows


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
