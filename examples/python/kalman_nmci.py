"""Two trackers, one target: fusing the other tracker's estimate with nmCI inside a
constant-velocity Kalman loop.

Each tracker runs its own Kalman filter on the same target (state x, ẋ, y, ẏ) with its own
position sensor. Both predict with the same model, so after a few fusions their errors are
correlated by an unknown amount — but the x and y axes never mix (the model, the sensors and
the fusions are per axis), so the cross-covariance between the two estimates is known to be
zero between x-states and y-states. nmCI uses exactly that: one ω per axis, where CI has one
for all. Each tracker fuses the other's estimate every step; we compare the bound each rule
reports (mean trace of P) with the actual error (RMSE over Monte Carlo runs) and check
consistency with the NEES (≤ 4 on average = conservative for the 4-state estimate).

    python examples/python/kalman_nmci.py [--quick]
"""

import sys

import numpy as np

import nmci

quick = "--quick" in sys.argv
runs, steps = (5, 40) if quick else (50, 200)
dt = 1.0
F1 = np.array([[1.0, dt], [0.0, 1.0]])
Q1 = 0.05 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
# State (x, ẋ, y, ẏ): the two axes are independent copies.
F = np.kron(np.eye(2), F1)
Q = np.kron(np.eye(2), Q1)
H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
# Tracker A sees x well and y badly, tracker B the other way round.
R = [np.diag([0.5, 8.0]), np.diag([8.0, 0.5])]
# Known zeros of P_ab: an x-state and a y-state are never correlated across the trackers.
axis = np.array([0, 0, 1, 1])
pab_unknown = axis[:, None] == axis[None, :]


def update(x, P, z, R_):
    """Kalman measurement update, Joseph form."""
    S = H @ P @ H.T + R_
    K = np.linalg.solve(S, H @ P).T
    I_KH = np.eye(4) - K @ H
    return x + K @ (z - H @ x), I_KH @ P @ I_KH.T + K @ R_ @ K.T


def run(rule, seed):
    rng = np.random.default_rng(seed)
    truth = np.array([0.0, 1.0, 0.0, 0.5])
    est = [(truth + rng.standard_normal(4), 4.0 * np.eye(4)) for _ in range(2)]
    sq_err, trace, nees = [], [], []
    L = np.linalg.cholesky(Q + 1e-12 * np.eye(4))
    for _ in range(steps):
        truth = F @ truth + L @ rng.standard_normal(4)
        est = [(F @ x, F @ P @ F.T + Q) for x, P in est]
        est = [update(x, P, H @ truth + np.sqrt(np.diag(R[i])) * rng.standard_normal(2), R[i])
               for i, (x, P) in enumerate(est)]
        (xa, Pa), (xb, Pb) = est
        fused = [rule(Pa, Pb, xa, xb), rule(Pb, Pa, xb, xa)]
        est = [(f.x, f.P) for f in fused]
        e = est[0][0] - truth
        sq_err.append(e[[0, 2]] @ e[[0, 2]])
        trace.append(np.trace(est[0][1]))
        nees.append(e @ np.linalg.solve(est[0][1], e))
    return np.array(sq_err), np.array(trace), np.array(nees)


rules = {
    "CI": lambda Pa, Pb, xa, xb: nmci.ci(Pa, Pb, xa, xb),
    "nmCI": lambda Pa, Pb, xa, xb: nmci.nmci(Pa, Pb, xa, xb, pab_unknown=pab_unknown),
}
print(f"{runs} runs × {steps} steps; tracker A's estimate after fusing B's")
print(f"{'rule':<6}{'position RMSE':>15}{'mean tr P':>12}{'mean NEES':>11}  (4 states: a conservative bound gives ≤ 4, up to Monte Carlo noise)")
for name, rule in rules.items():
    results = [run(rule, seed) for seed in range(runs)]
    sq = np.mean([r[0] for r in results], axis=0)
    print(f"{name:<6}{np.sqrt(sq.mean()):>15.3f}{np.mean([r[1] for r in results]):>12.3f}"
          f"{np.mean([r[2] for r in results]):>11.2f}")
