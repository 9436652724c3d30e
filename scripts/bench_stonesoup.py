"""Stone Soup benchmark (scripts/python.sh bench-stonesoup): one ``NmciUpdater.update`` per
rule on a track-to-track pair of a constant-velocity target in the plane (4 states, the two
axes declared as blocks), beside Stone Soup's ``ChernoffUpdater(None)`` in the same run. What a
tracker's per-update budget buys. Prints a Markdown table (median of repeated updates, this
machine; one thread).

The pair: the two nodes' covariances of a constant-velocity track (per axis
``[[4, 1], [1, 1]]`` scaled by a random factor per node and axis), the cross-covariance unknown
within each axis and zero between the axes (``blocks``).
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("RAYON_NUM_THREADS", "1")

import warnings  # noqa: E402

import numpy as np  # noqa: E402
from stonesoup.models.measurement.linear import LinearGaussian  # noqa: E402
from stonesoup.types.detection import GaussianDetection  # noqa: E402
from stonesoup.types.hypothesis import SingleHypothesis  # noqa: E402
from stonesoup.types.prediction import GaussianStatePrediction  # noqa: E402
from stonesoup.updater.chernoff import ChernoffUpdater  # noqa: E402

from bench_python import median_time  # noqa: E402
from nmci.stonesoup import NmciUpdater  # noqa: E402


def pair(rng):
    axis = np.array([[4.0, 1.0], [1.0, 1.0]])
    cov = lambda s: np.block([[s[0] * axis, np.zeros((2, 2))], [np.zeros((2, 2)), s[1] * axis]])  # noqa: E731
    A, B = cov(rng.uniform(0.5, 2.0, 2)), cov(rng.uniform(0.5, 2.0, 2))
    a, b = rng.standard_normal((4, 1)), rng.standard_normal((4, 1))
    model = LinearGaussian(ndim_state=4, mapping=(0, 1, 2, 3), noise_covar=A)
    return SingleHypothesis(GaussianStatePrediction(b, B), GaussianDetection(a, A, measurement_model=model))


def main():
    rng = np.random.default_rng(7)
    h = pair(rng)
    blocks = [[0, 1], [2, 3]]
    updaters = [
        ("`ChernoffUpdater(None)` (ω = 0.5)", ChernoffUpdater(None), 200),
        ("`NmciUpdater(None, 0.5)` (fixed ω)", NmciUpdater(None, 0.5), 200),
        ("`rule=\"ci\"`", NmciUpdater(None, rule="ci"), 200),
        ("`rule=\"nmci\"`, blocks", NmciUpdater(None, rule="nmci", blocks=blocks), 200),
        ("`rule=\"certified\"`, blocks", NmciUpdater(None, rule="certified", blocks=blocks), 20),
        ("`rule=\"sdp\"`, blocks, 100 samples", NmciUpdater(None, rule="sdp", blocks=blocks, options={"samples": 100}), 5),
        ("`rule=\"sdp_cuts\"`, blocks", NmciUpdater(None, rule="sdp_cuts", blocks=blocks), 3),
    ]
    print("| updater | median per update | tr P | guarantee |")
    print("|---|---|---|---|")
    for label, updater, repeat in updaters:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t = median_time(lambda: updater.update(h), repeat)
            u = updater.update(h)
        guarantee = getattr(u, "fusion", None)
        guarantee = guarantee.guarantee.split(":")[0] if guarantee is not None else "conservative (CI at ω = 0.5)"
        unit = (t * 1e6, "µs") if t < 1e-3 else ((t * 1e3, "ms") if t < 1 else (t, "s"))
        print(f"| {label} | {unit[0]:.3g} {unit[1]} | {np.trace(u.covar):.6g} | {guarantee} |")


if __name__ == "__main__":
    main()
