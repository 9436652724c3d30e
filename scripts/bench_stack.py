"""Stack benchmark (scripts/python.sh bench-stack): CI on ``k`` pairs of ``n``-state estimates, one
thread, side by side in one run. Prints a Markdown table (median of repeated runs, this machine).

- ``nmci.ci(Pa, Pb)`` on ``(k, n, n)`` stacks (one call; ``nmci::contract::fuse_stack``);
- a careful numpy batched CI: ``np.linalg.cholesky`` and ``eigh`` on the stacks (simultaneous
  diagonalisation, as in scripts/bench_python.py), then a vectorised bisection on the sign of
  the closed-form derivative of ``tr P(ω)`` (60 halvings: ω to 1e-18), then ``P(ω)``;
- ``np.linalg.eigh`` alone on a ``(k, n, n)`` stack: one symmetric eigendecomposition per pair,
  the floor of every exact CI (each needs the eigenvalues of one pencil per pair), done by LAPACK;
- a Python loop over ``nmci.ci`` (one call per pair: what a tracker without stacks does);
- Stone Soup's ``ChernoffUpdater`` (fixed ω = 0.5, no ω search) in a loop, when ``stonesoup`` is
  installed.

Every method's traces are compared with nmci's (the largest relative difference is printed), and
the numpy CI must never be below nmci's optimum beyond 1e-12 relative: equal accuracy, or the
table says otherwise. Threads: ``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS`` and
``RAYON_NUM_THREADS`` (nmci's pool for stacks of 64 pairs or more) are set to 1 before numpy and
nmci are imported.

The single call: "one ``nmci.ci`` call" is ``nmci.ci(A, B)`` on one pair's 2-D arrays, called
again and again (100 calls a run), next to numpy's ``np.linalg.eigh(A)`` timed the same way (a
single eigendecomposition, the least a CI needs, through numpy's Python interface); "per call
(loop)" is the loop's time per pair over the whole stack, which also makes a view of each pair
and keeps every result.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import nmci  # noqa: E402
from bench_python import median_time  # noqa: E402 (the same timing as the Python section)


def stacks(rng, n, k):
    a = rng.standard_normal((2, k, n, n))
    s = a @ a.transpose(0, 1, 3, 2) / n + 0.3 * np.eye(n)
    return s[0], s[1]


def ci_numpy_batched(Pa, Pb):
    """P_a = T Tᵀ, P_b = T Λ Tᵀ per pair; tr P(ω) = Σ cᵢ λᵢ / (1 + ω(λᵢ − 1)), convex in ω; its
    derivative's sign bisected for every pair at once."""
    L = np.linalg.cholesky(Pa)
    Li = np.linalg.inv(L)
    lam, V = np.linalg.eigh(Li @ Pb @ Li.transpose(0, 2, 1))
    T = L @ V
    c = np.einsum("kij,kij->kj", T, T)
    m = lam - 1.0

    def slope(w):
        return -np.sum(c * lam * m / (1.0 + w[:, None] * m) ** 2, axis=1)

    lo, hi = np.zeros(len(Pa)), np.ones(len(Pa))
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        up = slope(mid) > 0
        hi = np.where(up, mid, hi)
        lo = np.where(up, lo, mid)
    w = 0.5 * (lo + hi)
    w = np.where(slope(np.zeros(len(Pa))) >= 0, 0.0, np.where(slope(np.ones(len(Pa))) <= 0, 1.0, w))
    d = lam / (1.0 + w[:, None] * m)
    P = (T * d[:, None, :]) @ T.transpose(0, 2, 1)
    return w, P


def chernoff_loop(Pa, Pb):
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.types.detection import GaussianDetection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.prediction import GaussianStatePrediction
    from stonesoup.updater.chernoff import ChernoffUpdater

    n = Pa.shape[1]
    updater = ChernoffUpdater(measurement_model=None, omega=0.5)
    out = []
    for a, b in zip(Pa, Pb):
        model = LinearGaussian(ndim_state=n, mapping=tuple(range(n)), noise_covar=b)
        detection = GaussianDetection(np.zeros((n, 1)), b, measurement_model=model)
        prediction = GaussianStatePrediction(np.zeros((n, 1)), a)
        out.append(updater.update(SingleHypothesis(prediction, detection)).covar)
    return out


def main():
    try:
        import stonesoup

        soup = stonesoup.__version__
    except ImportError:
        soup = None
    rng = np.random.default_rng(4)
    print(f"numpy {np.__version__}, nmci {nmci.__version__}, stonesoup {soup or 'not installed'}; one thread")
    print()
    print("| n | k | nmci stack | numpy batched CI | `eigh` alone (floor) | loop over `nmci.ci` | `ChernoffUpdater` loop (ω = 0.5) | stack vs numpy | per pair (stack) | per call (loop) | one `nmci.ci` call | one `eigh` call | traces |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for n in (2, 4, 6, 14):
        for k in (1, 100, 10_000):
            Pa, Pb = stacks(rng, n, k)
            repeat = 21 if k < 10_000 else 5
            t_stack = median_time(lambda: nmci.ci(Pa, Pb), repeat)
            t_numpy = median_time(lambda: ci_numpy_batched(Pa, Pb), repeat)
            t_eigh = median_time(lambda: np.linalg.eigh(Pa), repeat)
            t_loop = median_time(lambda: [nmci.ci(a, b) for a, b in zip(Pa, Pb)], repeat if k < 10_000 else 3)
            one, other = Pa[0].copy(), Pb[0].copy()
            t_one_ci = median_time(lambda: [nmci.ci(one, other) for _ in range(100)], repeat) / 100
            t_one_eigh = median_time(lambda: [np.linalg.eigh(one) for _ in range(100)], repeat) / 100
            stack = nmci.ci(Pa, Pb)
            _, P_np = ci_numpy_batched(Pa, Pb)
            tr_np = np.trace(P_np, axis1=1, axis2=2)
            rel = np.max(np.abs(tr_np - stack.trace) / stack.trace)
            below = np.min((tr_np - stack.trace) / stack.trace)
            assert below > -1e-12, f"numpy's CI below nmci's optimum at n = {n}, k = {k}: {below}"
            if soup:
                t_soup = median_time(lambda: chernoff_loop(Pa, Pb), 3 if k == 10_000 else 7)
                tr_soup = np.array([np.trace(P) for P in chernoff_loop(Pa, Pb)])
                soup_cell = f"{t_soup * 1e3:.3g} ms (tr {np.median(tr_soup / stack.trace):.3f}× CI's)"
            else:
                soup_cell = "—"
            print(
                f"| {n} | {k} | {t_stack * 1e3:.3g} ms | {t_numpy * 1e3:.3g} ms | {t_eigh * 1e3:.3g} ms | {t_loop * 1e3:.3g} ms | {soup_cell} "
                f"| {t_numpy / t_stack:.2f}× | {t_stack / k * 1e6:.3g} µs | {t_loop / k * 1e6:.3g} µs | {t_one_ci * 1e6:.3g} µs | {t_one_eigh * 1e6:.3g} µs "
                f"| numpy within {rel:.1e} |"
            )


if __name__ == "__main__":
    main()
