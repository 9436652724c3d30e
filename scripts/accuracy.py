"""Accuracy of the closed-form rules against 50-digit references (scripts/python.sh accuracy).

For each condition number κ, pairs P_a, P_b of that condition number (random rotations of
diag(geomspace(1, κ, n)), n = 2, 3, 5, five pairs each, P_b scaled by a random factor in
10^±3) are fused by nmci's CI, ICI, EI and naive rule. Each P is compared with the same rule
evaluated by mpmath at 50 digits on the same float inputs (at nmci's own ω). The table gives
the largest relative error ‖P − P_ref‖_F / ‖P_ref‖_F in units of ε κ (ε = 2⁻⁵²), beside two
ways a numpy user would compute CI's P at the same ω: the textbook pencil (P_a = L Lᵀ, numpy's
eigh of L⁻¹ P_b L⁻ᵀ, as in scripts/bench_python.py) and plain inverses. A relative change of ε in the
inputs moves P by up to about ε κ, so a value of order 1 is as accurate as the inputs allow.
"""

import numpy as np
import mpmath as mp

import nmci

mp.mp.dps = 50
EPS = np.finfo(float).eps


def rotated(rng, n, cond, scale=1.0):
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    ev = np.geomspace(1.0, cond, n)
    rng.shuffle(ev)
    p = scale * (q * ev) @ q.T
    return (p + p.T) / 2


def mat(m):
    return mp.matrix(np.asarray(m).tolist())


def rel(x, e):
    return float(mp.mnorm(mat(x) - e, "f") / mp.mnorm(e, "f"))


def ci_ref(A, B, w):
    return (w * A**-1 + (1 - w) * B**-1) ** -1


def ici_ref(A, B, w):
    return (A**-1 + B**-1 - (w * A + (1 - w) * B) ** -1) ** -1


def ei_ref(A, B):
    da, sa = mp.eigsy(A)
    T = mp.diag([1 / mp.sqrt(d) for d in da]) * sa.T
    db, sb = mp.eigsy(T * B * T.T)
    G = T**-1 * sb * mp.diag([max(d, 1) for d in db]) * sb.T * (T**-1).T
    return (A**-1 + B**-1 - G**-1) ** -1


def textbook_ci(a, b, w):
    L = np.linalg.cholesky(a)
    Li = np.linalg.inv(L)
    lam, V = np.linalg.eigh(Li @ b @ Li.T)
    T = L @ V
    return (T / (w + (1 - w) / lam)) @ T.T


def inverse_ci(a, b, w):
    return np.linalg.inv(w * np.linalg.inv(a) + (1 - w) * np.linalg.inv(b))


def main():
    rng = np.random.default_rng(2026)
    cols = ["nmci.ci", "nmci.ici", "nmci.ei", "nmci.naive", "numpy textbook CI", "numpy inverses CI"]
    print("| κ | " + " | ".join(cols) + " |")
    print("|---|" + "---|" * len(cols))
    for cond in [1e2, 1e4, 1e6, 1e8, 1e10, 1e12, 1e14]:
        worst = {c: 0.0 for c in cols}
        refused = {c: 0 for c in cols}
        for n in (2, 3, 5):
            for _ in range(5):
                a, b = rotated(rng, n, cond), rotated(rng, n, cond, 10 ** rng.uniform(-3, 3))
                A, B = mat(a), mat(b)
                unit = EPS * cond
                errs = {}
                try:
                    r = nmci.ci(a, b)
                    w = r.omega[0]
                    ref = ci_ref(A, B, mp.mpf(w))
                    errs["nmci.ci"] = rel(r.P, ref)
                except nmci.InputError:  # a refusal of positive definite inputs is counted
                    errs["nmci.ci"] = None
                    w = 0.5
                    ref = ci_ref(A, B, mp.mpf(w))
                for c, call in (
                    ("nmci.ici", lambda: (lambda r: rel(r.P, ici_ref(A, B, mp.mpf(r.omega[0]))))(nmci.ici(a, b))),
                    ("nmci.ei", lambda: rel(nmci.ei(a, b).P, ei_ref(A, B))),
                    ("nmci.naive", lambda: rel(nmci.naive(a, b).P, (A**-1 + B**-1) ** -1)),
                ):
                    try:
                        errs[c] = call()
                    except nmci.InputError:
                        errs[c] = None
                for c, f in (("numpy textbook CI", textbook_ci), ("numpy inverses CI", inverse_ci)):
                    with np.errstate(all="ignore"):
                        p = f(a, b, w)
                    errs[c] = rel(p, ref) if np.all(np.isfinite(p)) else float("inf")
                for c, e in errs.items():
                    if e is None:
                        refused[c] += 1
                    else:
                        worst[c] = max(worst[c], e / unit)

        def cell(c):
            return f"{worst[c]:.2g}" + (f" ({refused[c]} refused)" if refused[c] else "")

        print(f"| 10^{int(round(np.log10(cond)))} | " + " | ".join(cell(c) for c in cols) + " |")
    print(f"\nLargest relative error of P over 15 pairs per row, in units of ε κ (pairs a rule refused as not positive definite in brackets); nmci {nmci.__version__}, numpy {np.__version__}.")


if __name__ == "__main__":
    main()
