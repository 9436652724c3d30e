"""nmci for Python: the contract equals the CLI's to the bit, the rules match independent
numpy/scipy references and hold on sampled cross-covariances, bad input raises the right
exception with the CLI's message, shards merged equal one run (also from a process pool), the
GIL is released, a panic becomes an exception, and the examples run.

Run by scripts/test.sh (scripts/python.sh test) against the wheel it builds; NMCI_CLI names the
`nmci` binary to compare with."""

import ast
import concurrent.futures
import doctest
import json
import re
import os
import pickle
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
import scipy.optimize

import nmci

ROOT = Path(__file__).resolve().parents[2]


def cli() -> str:
    path = os.environ.get("NMCI_CLI")
    assert path, "NMCI_CLI must name the nmci binary (scripts/python.sh sets it)"
    assert Path(path).is_file(), f"NMCI_CLI={path} does not exist"
    return path


def run_cli(args, stdin=""):
    return subprocess.run([cli(), *args], input=stdin, capture_output=True, text=True)


def spd(rng, n, scale=1.0):
    a = rng.standard_normal((n, n))
    return scale * (a @ a.T / n + 0.3 * np.eye(n))


def random_pattern(rng, n, p=0.6):
    """A pattern with at least one known zero and one unknown entry, not separable-trivial."""
    while True:
        m = rng.random((n, n)) < p
        if m.any() and not m.all():
            return m


PAPER = dict(pa=[[3.0, 0.0], [0.0, 1.0]], pb=[[1.0, 0.0], [0.0, 4.0]])
ONE_ZERO = [[True, True], [False, True]]

REQUESTS = [
    {**PAPER, "method": "ci"},
    {**PAPER, "method": "ci", "criterion": "logdet", "xa": [1.0, 2.0], "xb": [0.5, -1.0]},
    {**PAPER, "method": "nmci", "pab_unknown": [[True, False], [False, True]]},
    {**PAPER, "method": "sdp", "pab_unknown": [[True, False], [False, True]]},
    {**PAPER, "method": "sdp", "samples": 50, "sampler": "hit_and_run", "seed": 3},
    {**PAPER, "method": "sdp", "samples": 50, "sampler": "auto", "seed": 3},
    {**PAPER, "method": "sdp_cuts", "pab_unknown": ONE_ZERO},
    {**PAPER, "method": "certified", "pab_unknown": ONE_ZERO, "level": 2},
    {**PAPER, "method": "certified", "pab_unknown": ONE_ZERO, "sectors": 8},
    {
        "pa": [[3, 1, 0], [1, 2, 0.5], [0, 0.5, 1]],
        "pb": [[2, 0, 0.3], [0, 1, 0], [0.3, 0, 2]],
        "pab_unknown": [[True, False, True], [True, True, False], [False, True, True]],
        "method": "certified",
        "cones": 4,
    },
    {
        "pa": [[3, 1, 0], [1, 2, 0.5], [0, 0.5, 1]],
        "pb": [[2, 0, 0.3], [0, 1, 0], [0.3, 0, 2]],
        "pab_unknown": [[True, False, True], [True, True, False], [False, True, True]],
        "method": "certified",
        "max_cones": 6,
    },
    {**PAPER, "method": "sdp_cuts", "pab_unknown": ONE_ZERO, "cuts_tolerance": 1e-9},
    {**PAPER, "method": "ici"},
    {**PAPER, "method": "ei"},
    {**PAPER, "method": "naive"},
    {
        "method": "nmci",
        "estimates": [
            {"p": [[2.0, 0.3], [0.3, 1.0]], "x": [1.0, 0.0]},
            {"p": [[1.0, 0.0], [0.0, 3.0]]},
            {"p": [[1.5, -0.2], [-0.2, 2.0]]},
        ],
        "patterns": [{"i": 0, "j": 1, "pab_unknown": [[True, False], [False, True]]}],
    },
]

BAD_REQUESTS = [
    ({"pa": [[1, 2], [2, 1]], "pb": [[1, 0], [0, 1]], "method": "ci"}, nmci.InputError),
    ({"pa": [[1]], "pb": [[1]], "method": "ci", "oops": True}, nmci.RequestError),
    ({**PAPER, "method": "sdp", "samples": 0}, nmci.RequestError),
    ({**PAPER, "method": "ci", "level": 2}, nmci.RequestError),
    ({"pa": [[1, 0], [0, 1]], "pb": [[1]], "method": "nmci"}, nmci.InputError),
    ({**PAPER, "method": "sdp", "max_trials": 5}, nmci.SampleError),
    ({"pa": [[1.0, 0.5], [0.4, 1.0]], "pb": [[1, 0], [0, 1]], "method": "ci"}, nmci.InputError),
    ({"method": "ci"}, nmci.RequestError),
]


@pytest.mark.parametrize("request_", REQUESTS, ids=lambda r: r["method"])
def test_the_contract_returns_what_the_cli_returns_to_the_bit(request_):
    done = run_cli(["fuse"], json.dumps(request_))
    assert done.returncode == 0, done.stderr
    assert nmci.fuse(request_) == json.loads(done.stdout)


@pytest.mark.parametrize("request_,error", BAD_REQUESTS)
def test_bad_requests_raise_the_cli_s_message(request_, error):
    done = run_cli(["fuse"], json.dumps(request_))
    assert done.returncode != 0
    message = done.stderr.strip().removeprefix("nmci: ")
    with pytest.raises(error) as raised:
        nmci.fuse(request_)
    assert str(raised.value) == message
    assert isinstance(raised.value, nmci.NmciError)


def test_the_array_functions_return_the_contract_s_response():
    rng = np.random.default_rng(1)
    calls = {
        "ci": lambda a, b, m: nmci.ci(a, b, pab_unknown=m),
        "nmci": lambda a, b, m: nmci.nmci(a, b, pab_unknown=m),
        "sdp": lambda a, b, m: nmci.optimal(a, b, pab_unknown=m, samples=30, sampler="hit_and_run"),
        "sdp_cuts": lambda a, b, m: nmci.sdp_cuts(a, b, pab_unknown=m),
        "certified": lambda a, b, m: nmci.certified(a, b, pab_unknown=m),
        "ici": lambda a, b, m: nmci.ici(a, b, pab_unknown=m),
        "ei": lambda a, b, m: nmci.ei(a, b, pab_unknown=m),
        "naive": lambda a, b, m: nmci.naive(a, b, pab_unknown=m),
    }
    for method, call in calls.items():
        a, b, m = spd(rng, 3), spd(rng, 3), random_pattern(rng, 3)
        request = {"pa": a, "pb": b, "pab_unknown": m, "method": method}
        if method == "sdp":
            request.update(samples=30, sampler="hit_and_run")
        got = call(a, b, m)
        assert got.to_dict() == nmci.fuse(request), method
        assert isinstance(got.P, np.ndarray) and got.P.shape == (3, 3)
        assert np.array_equal(got.P, got["p"])
        assert got.method == method


@pytest.mark.parametrize("method", ["sdp", "sdp_cuts"])
def test_the_sdps_give_the_proven_bound_of_their_own_gain(method):
    # `gain_certified_p`: a symmetric numpy array whose trace, rounded up, is
    # `gain_certified_trace`; it dominates the true fused error covariance of the response's
    # own gains for cross-covariances drawn from the admissible set (the Rust tests search the
    # worst case), where the relaxation's `P` may not.
    a, b = np.array(PAPER["pa"], dtype=float), np.array(PAPER["pb"], dtype=float)
    r = {"sdp": nmci.optimal, "sdp_cuts": nmci.sdp_cuts}[method](a, b, pab_unknown=ONE_ZERO)
    bound = r.gain_certified_p
    assert isinstance(bound, np.ndarray) and bound.shape == (2, 2)
    assert np.array_equal(bound, bound.T) and bound.tolist() == r.to_dict()["gain_certified_p"]
    assert np.trace(bound) <= r.gain_certified_trace <= np.trace(bound) * (1 + 1e-14)
    assert r.gain_certified_trace >= r.lower_bound
    for P_ab in nmci.sample_cross_covariances(a, b, ONE_ZERO, count=500, seed=1):
        error = r.Ka @ a @ r.Ka.T + r.Kb @ b @ r.Kb.T + r.Ka @ P_ab @ r.Kb.T + r.Kb @ P_ab.T @ r.Ka.T
        assert np.linalg.eigvalsh(bound - error).min() >= -1e-12


@pytest.mark.parametrize("rule", ["ci", "nmci", "ici", "ei", "naive", "certified"])
def test_any_array_like_gives_the_response_of_float64_arrays(rule):
    # float64 arrays go straight to Rust, which reads any strides; lists, integer arrays and
    # the like are converted first. Both ways give one response.
    rng = np.random.default_rng(21)
    a, b, m = spd(rng, 3), spd(rng, 3), random_pattern(rng, 3)
    fuse = getattr(nmci, rule)
    want = fuse(a.tolist(), b.tolist(), [1.0, 2.0, 3.0], [0, 0, 0], pab_unknown=m.tolist()).to_dict()
    xa, xb = np.array([1.0, 2.0, 3.0]), np.zeros(3)
    assert fuse(a, b, xa, xb, pab_unknown=m).to_dict() == want
    wide = np.zeros((3, 6))
    wide[:, ::2] = a  # a view with strides (48, 16)
    assert fuse(wide[:, ::2], np.asfortranarray(b), xa, xb, pab_unknown=m).to_dict() == want
    whole = fuse(2 * np.eye(3, dtype=np.int64), np.eye(3, dtype=np.int32), pab_unknown=m).to_dict()
    assert whole == fuse(2 * np.eye(3), np.eye(3), pab_unknown=m).to_dict()


def test_a_response_read_field_by_field_is_the_whole_response():
    # A response converts the fields a filter reads one by one: reading them first changes
    # neither the fields, nor their order, nor the objects read.
    a, b = np.diag([3.0, 1.0]), np.diag([1.0, 4.0])
    whole = nmci.ci(a, b)
    keys, full = whole.keys(), whole.to_dict()
    piecewise = nmci.ci(a, b)
    P, x, omega, trace = piecewise.P, piecewise.x, piecewise.omega, piecewise.trace
    assert piecewise.P is P and piecewise.x is x and piecewise.omega is omega
    assert piecewise.structure_note is None and piecewise.det > 0
    assert piecewise.keys() == keys and piecewise.to_dict() == full
    assert piecewise.P is P and trace == full["trace"] and np.array_equal(P, full["p"])
    copy = pickle.loads(pickle.dumps(nmci.ci(a, b)))
    assert copy.keys() == keys and copy.to_dict() == full


def test_the_defaults_are_the_library_s_not_python_s():
    # Absent keyword arguments are left out of the request: the Rust plan fills in the one set
    # of defaults, so a call without options equals the bare contract request.
    rng = np.random.default_rng(11)
    a, b, m = spd(rng, 2), spd(rng, 2), random_pattern(rng, 2)
    bare = {"pa": a, "pb": b, "pab_unknown": m}
    for method, call in {
        "sdp": nmci.optimal,
        "ci": nmci.ci,
        "sdp_cuts": nmci.sdp_cuts,
    }.items():
        assert call(a, b, pab_unknown=m).to_dict() == nmci.fuse({**bare, "method": method}), method
    # The sampler's default seed and kind are the plan's too: the default call equals the
    # call with the plan's defaults spelled out (seed 0, the rejection sampler).
    default = nmci.sample_cross_covariances(a, b, m, count=20)
    spelled = nmci.sample_cross_covariances(a, b, m, count=20, seed=0, sampler="rejection")
    assert np.array_equal(default, spelled)


def test_every_response_field_is_a_typed_attribute_of_fused():
    rng = np.random.default_rng(2)
    keys = set()
    for request in REQUESTS:
        keys |= set(nmci.fuse(request))
    a, b = spd(rng, 2), spd(rng, 2)
    keys |= set(nmci.fuse({"pa": a, "pb": b, "method": "ci"}))
    keys |= set(nmci.fuse({"pa": [[3, 1e-13], [1e-13, 1]], "pb": [[1, 0], [0, 4]], "blocks": [[0], [1]], "method": "nmci"}))
    # The attributes are the fields the Rust response can carry (read from serde), exactly the
    # fields these requests make the contract emit, and exactly those the type stubs declare.
    assert keys == set(nmci.Fused.FIELDS), (keys ^ set(nmci.Fused.FIELDS))
    stub = ast.parse((Path(nmci.__file__).parent / "_nmci.pyi").read_text())
    fused = next(n for n in stub.body if isinstance(n, ast.ClassDef) and n.name == "Fused")
    attributes = {n.target.id for n in fused.body if isinstance(n, ast.AnnAssign)} - {"FIELDS", "ALIASES"}
    declared = {nmci.Fused.ALIASES.get(a, a) for a in attributes}
    assert keys == declared, (keys - declared, declared - keys)
    r = nmci.nmci(PAPER["pa"], PAPER["pb"], pab_unknown=np.eye(2, dtype=bool))
    assert r.lower_bound is None and r.blocks == [[0], [1]]
    with pytest.raises(AttributeError):
        r.no_such_field  # noqa: B018
    with pytest.raises(AttributeError):
        r.trace = 1.0


def test_options_cross_as_python_objects_and_results_pickle():
    # Options are read by serde from the Python objects: numpy scalars are numbers like any
    # other, and a call with them equals the call with plain ints and floats.
    a, b = np.diag([3.0, 1.0]), np.diag([1.0, 4.0])
    plain = nmci.optimal(a, b, samples=30, seed=4, time_limit=60.0)
    scalars = nmci.optimal(a, b, samples=np.int64(30), seed=np.uint8(4), time_limit=np.float32(60.0))
    assert plain.to_dict() == scalars.to_dict()
    blocks = nmci.nmci(a, b, blocks=[(np.int64(0),), [1]], coupling_tol=np.float64(0.0))
    assert blocks.blocks == [[0], [1]]
    # A result is an object of the extension, read-only and picklable (process pools).
    copy = pickle.loads(pickle.dumps(plain))
    assert isinstance(copy, nmci.Fused) and copy.to_dict() == plain.to_dict()
    assert np.array_equal(copy.P, plain.P) and copy.lower_bound == plain.lower_bound
    assert "lower_bound" in plain and "omega" not in plain and plain.omega is None
    with pytest.raises(KeyError):
        plain["omega"]
    with pytest.raises(AttributeError):
        plain.p  # noqa: B018 (the contract's `p` is the attribute `P`)


def ci_reference(a, b):
    """CI by scipy's bounded scalar minimiser on tr((ω A⁻¹ + (1 − ω) B⁻¹)⁻¹)."""
    ai, bi = np.linalg.inv(a), np.linalg.inv(b)
    f = lambda w: np.trace(np.linalg.inv(w * ai + (1 - w) * bi))  # noqa: E731
    res = scipy.optimize.minimize_scalar(f, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-12})
    best = min([(f(0.0), 0.0), (f(1.0), 1.0), (res.fun, res.x)])
    return best[1], best[0]


def test_ci_matches_a_scipy_reference_on_random_problems():
    rng = np.random.default_rng(3)
    for trial in range(60):
        n = int(rng.integers(1, 9))
        a, b = spd(rng, n, rng.uniform(0.1, 10)), spd(rng, n, rng.uniform(0.1, 10))
        r = nmci.ci(a, b)
        w_ref, t_ref = ci_reference(a, b)
        # nmci's ω is the exact minimiser: never worse than scipy's beyond rounding.
        assert r.trace <= t_ref * (1 + 1e-12), (trial, r.trace, t_ref)
        assert r.trace >= t_ref * (1 - 1e-8), (trial, r.trace, t_ref)
        w = r.omega[0]
        expected = np.linalg.inv(w * np.linalg.inv(a) + (1 - w) * np.linalg.inv(b))
        np.testing.assert_allclose(r.P, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
        np.testing.assert_allclose(r.Ka + r.Kb, np.eye(n), atol=1e-12)


@pytest.mark.parametrize("cond", [1e2, 1e6, 1e10, 1e13, 1e15])
def test_ci_ici_and_ei_keep_the_accuracy_their_conditioning_allows(cond):
    # Against 50-digit references (mpmath) of the same float inputs: the relative error of P
    # stays within 4 ε κ, κ the larger condition number of P_a, P_b. Through a pencil of P_a
    # against P_b alone it was 2e-6 at κ = 1e6, 0.7 at 1e8 and a false "not positive
    # definite" from 1e10 (the ratios' spread κ² entered instead of κ; scripts/accuracy.py,
    # whose references these are).
    import mpmath as mp

    sys.path.insert(0, str(ROOT / "scripts"))
    import accuracy as acc

    rng = np.random.default_rng(int(np.log10(cond)))

    def kappa(m):
        ev = mp.eigsy(acc.mat(m))[0]
        return float(max(ev) / min(ev))

    for n in (2, 3, 5):
        for _ in range(3):
            a, b = acc.rotated(rng, n, cond), acc.rotated(rng, n, cond)
            A, B = acc.mat(a), acc.mat(b)
            tol = 4 * np.finfo(float).eps * max(kappa(a), kappa(b))
            r = nmci.ci(a, b)
            assert acc.rel(r.P, acc.ci_ref(A, B, mp.mpf(r.omega[0]))) <= tol, ("ci", n)
            r = nmci.ici(a, b)
            assert acc.rel(r.P, acc.ici_ref(A, B, mp.mpf(r.omega[0]))) <= tol, ("ici", n)
            assert acc.rel(nmci.ei(a, b).P, acc.ei_ref(A, B)) <= tol, ("ei", n)


def admissible_cross(rng, a, b, mask, radius):
    """An admissible P_ab' drawn independently of nmci: zeros where `mask` is False, scaled so
    that ‖P_a^{-1/2} P_ab' P_b^{-1/2}‖₂ = radius < 1 (the joint covariance is then PD)."""
    c = rng.standard_normal(a.shape) * mask
    la, lb = np.linalg.cholesky(a), np.linalg.cholesky(b)
    whitened = np.linalg.solve(la, np.linalg.solve(lb, c.T).T)
    return c * radius / np.linalg.norm(whitened, 2)


def margin(fused, a, b, cross):
    k = np.hstack([fused.Ka, fused.Kb])
    joint = np.block([[a, cross], [cross.T, b]])
    return np.linalg.eigvalsh(fused.P - k @ joint @ k.T).min()


def test_conservative_rules_hold_on_sampled_cross_covariances():
    rng = np.random.default_rng(4)
    for trial in range(12):
        n = int(rng.integers(2, 4))
        a, b, m = spd(rng, n), spd(rng, n), random_pattern(rng, n)
        rules = {
            "ci": nmci.ci(a, b, pab_unknown=m),
            "nmci": nmci.nmci(a, b, pab_unknown=m),
            "certified": nmci.certified(a, b, pab_unknown=m),
        }
        crosses = list(nmci.sample_cross_covariances(a, b, m, count=50, sampler="hit_and_run", seed=trial))
        crosses += [admissible_cross(rng, a, b, m, r) for r in rng.uniform(0.5, 0.999999, 50)]
        for c in crosses:
            assert np.all(c[~m] == 0)
            for name, fused in rules.items():
                scale = np.abs(fused.P).max()
                assert margin(fused, a, b, c) >= -1e-10 * scale, (trial, name)
        # Certified at most 1e-14 relative above nmCI or CI in trace on these well-conditioned problems.
        assert rules["certified"].trace <= min(rules["ci"].trace, rules["nmci"].trace) * (1 + 1e-14)


@pytest.mark.parametrize("unit", [1e-8, 1e12])
def test_the_solver_based_rules_do_not_depend_on_the_units(unit):
    # km² for metre-level sensors, rad² for angles: before the power-of-two scaling the
    # sampled optimum at 1e-8 was 8 % above the robust optimum (2) and 1e12 failed to solve.
    a, b = np.diag([3.0, 1.0]), np.diag([1.0, 4.0])
    m = np.array([[True, True], [False, True]])
    opt = nmci.optimal(a * unit, b * unit, pab_unknown=m, samples=50)
    assert abs(opt.trace / unit - 2.0) < 1e-6
    assert 2.0 - 1e-6 < opt.lower_bound / unit <= opt.trace / unit
    assert nmci.certified(a * unit, b * unit, pab_unknown=m).trace / unit < 2.0 + 1e-6


def test_naive_fusion_is_caught_overconfident_by_the_index():
    a, b = np.diag([3.0, 1.0]), np.diag([1.0, 4.0])
    fused = nmci.naive(a, b)
    cross = np.diag([0.9 * np.sqrt(3.0), 0.9 * 2.0])
    k = np.hstack([fused.Ka, fused.Kb])
    error = k @ np.block([[a, cross], [cross.T, b]]) @ k.T
    assert nmci.conservativeness_index(fused.P, error) > 1
    assert nmci.conservativeness_index(nmci.ci(a, b).P, error) <= 1 + 1e-12
    # A singular error covariance is a valid E.
    assert nmci.conservativeness_index(np.eye(2), np.diag([0.5, 0.0])) == 0.5


def test_sampled_cross_covariances_are_admissible():
    rng = np.random.default_rng(5)
    a, b, m = spd(rng, 3), spd(rng, 3), random_pattern(rng, 3)
    for sampler in ("rejection", "hit_and_run"):
        stack = nmci.sample_cross_covariances(a, b, m, count=40, seed=1, sampler=sampler)
        assert stack.shape == (40, 3, 3)
        for c in stack:
            assert np.all(c[~m] == 0)
            assert np.linalg.eigvalsh(np.block([[a, c], [c.T, b]])).min() > 0
    again = nmci.sample_cross_covariances(a, b, m, count=40, seed=1)
    assert np.array_equal(again, nmci.sample_cross_covariances(a, b, m, count=40, seed=1))


def test_n_way_rules_take_numpy_estimates_and_patterns():
    rng = np.random.default_rng(6)
    ps = [spd(rng, 2) for _ in range(3)]
    xs = [rng.standard_normal(2) for _ in range(3)]
    r = nmci.ci_nway(list(zip(xs, ps)))
    assert r.weights.shape == (1, 3) and abs(r.weights.sum() - 1) < 1e-12
    assert r.gains.shape == (3, 2, 2)
    np.testing.assert_allclose(sum(r.gains), np.eye(2), atol=1e-12)
    np.testing.assert_allclose(r.x, sum(g @ x for g, x in zip(r.gains, xs)), atol=1e-12)
    # Diagonal covariances and diagonal cross patterns: two independent blocks.
    ds = [np.diag(rng.uniform(0.5, 3, 2)) for _ in range(3)]
    diag = np.eye(2, dtype=bool)
    by_map = nmci.nmci_nway(ds, patterns={(0, 1): diag, (0, 2): diag, (1, 2): diag})
    by_list = nmci.nmci_nway(ds, patterns=[(0, 1, diag), (0, 2, diag), (1, 2, diag)])
    assert by_map.to_dict() == by_list.to_dict()
    assert by_map.weights.shape == (2, 3) and by_map.blocks == [[0], [1]]
    assert by_map.trace <= nmci.ci_nway(ds).trace * (1 + 1e-12)


BAD_CALLS = [
    (lambda: nmci.ci(np.eye(2), np.eye(3)), nmci.InputError, "P_b has size 3, expected 2"),
    (lambda: nmci.ci(np.ones(3), np.eye(3)), nmci.InputError, "P_a must be a 2-D or 3-D array (got 1-D)"),
    (lambda: nmci.ci([["a"]], np.eye(1)), nmci.InputError, "P_a is not a numeric array"),
    (lambda: nmci.ci(np.eye(2) * np.nan, np.eye(2)), nmci.InputError, "non-finite"),
    (lambda: nmci.ci(np.eye(2), np.eye(2), criterion="volume"), nmci.RequestError, "unknown variant `volume`"),
    (lambda: nmci.nmci(np.eye(2), np.eye(2), pab_unknown=np.eye(2)), nmci.InputError, "array of booleans"),
    (lambda: nmci.nmci(np.eye(2), np.eye(2), xa=np.zeros(3)), nmci.InputError, "x_a has size 3"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), samples=0), nmci.RequestError, "`samples` must be at least 1"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), sampler="gibbs"), nmci.RequestError, "unknown variant `gibbs`"),
    (lambda: nmci.certified(np.eye(2), np.eye(2), level=99), nmci.RequestError, "`level` must be in 1..="),
    (lambda: nmci.certified(np.eye(2), np.eye(2), sectors=1), nmci.RequestError, "`sectors` must be in 2..=64 (got 1)"),
    (lambda: nmci.certified(np.eye(3), np.eye(3), cones=8), nmci.RequestError, "`cones` must be 4, 16 or 64 (got 8)"),
    (lambda: nmci.certified(np.eye(3), np.eye(3), max_cones=3), nmci.RequestError, "`max_cones` must be in 4..=256 (got 3)"),
    (lambda: nmci.certified(np.eye(3), np.eye(3), max_cones=8, cones=16), nmci.RequestError, "not both"),
    (lambda: nmci.certified(np.eye(2), np.eye(2), time_limit=-1), nmci.RequestError, "`time_limit` must be a positive number"),
    (lambda: nmci.sdp_cuts(np.eye(2), np.eye(2), cuts_tolerance=0.0), nmci.RequestError, "`cuts_tolerance` must be positive and finite (got 0)"),
    (lambda: nmci.optimal(np.eye(6), np.eye(6), max_trials=10), nmci.SampleError, "rejection sampler accepted only"),
    (lambda: nmci.ci_nway([np.eye(2)]), nmci.InputError, "invalid estimates"),
    (lambda: nmci.ci(np.eye(1001), np.eye(1001)), nmci.RequestError, 'method "ci" accepts at most 1000 states (`pa` has 1001)'),
    (lambda: nmci.optimal(np.eye(9), np.eye(9)), nmci.RequestError, "of at most 8 states; states [0, 1, 2, 3, 4, 5, 6, 7, 8] form one block of 9"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), samples=100_001), nmci.RequestError, "`samples` must be at most 100000 (got 100001)"),
    (lambda: nmci.conservativeness_index(np.eye(2), np.eye(3)), nmci.InputError, "E has size 3"),
    (lambda: nmci.conservativeness_index(-np.eye(2), np.eye(2)), nmci.InputError, "P is not positive definite"),
    (lambda: nmci.conservativeness_index(np.eye(2), np.full((2, 2), np.inf)), nmci.InputError, "E has a non-finite entry at (0, 0)"),
    (lambda: nmci.conservativeness_index(np.eye(2), np.array([[1.0, 2.0], [3.0, 1.0]])), nmci.InputError, "E is not symmetric"),
    (lambda: nmci.sample_cross_covariances(np.eye(2), np.eye(2), sampler="x"), nmci.RequestError, "`sampler`: unknown variant `x`, expected one of `rejection`, `hit_and_run`, `auto`"),
    (lambda: nmci.track({"runs": 0}), nmci.StudyError, "runs at least 1"),
    (lambda: nmci.track({"scenario": {"groups": 10**12}}), nmci.StudyError, "agents, above the limit of 64"),
    (lambda: nmci.sample_cross_covariances(np.eye(2), np.eye(2), count=10**9), nmci.RequestError, "above the limit of 1000000 samples per call"),
    (lambda: nmci.track({"rnus": 3}), nmci.StudyError, "unknown field `rnus`"),
    (lambda: nmci.track({"agent": 7, "watched": 1}), nmci.StudyError, "agent 7 has no link to agent 1"),
    (lambda: nmci.track("/no/such/study.toml"), nmci.StudyError, "cannot read /no/such/study.toml"),
    (lambda: nmci.merge([]), nmci.MergeError, "no shards to merge"),
    (lambda: nmci.Shard("{}"), nmci.MergeError, "not a study shard"),
    (lambda: nmci.fig2(runs=0), nmci.RequestError, "fig2 needs at least one run"),
    (lambda: nmci.ci(np.eye(2) * (1 + 1j), np.eye(2)), nmci.InputError, "P_a is complex"),
    (lambda: nmci.ci(np.eye(2) * 1e308, np.eye(2)), nmci.InputError, "P_a is out of the range nmci computes in"),
    (lambda: nmci.ci(np.eye(2) * 5e-324, np.eye(2)), nmci.InputError, "P_a is out of the range nmci computes in"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), time_limit=float("nan")), nmci.RequestError, "`time_limit` must be a positive number of seconds (got NaN)"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), seed=-1), nmci.RequestError, "`seed`: OverflowError: can't convert negative int to unsigned"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), samples=2.5), nmci.RequestError, "`samples`: TypeError: 'float' object cannot be interpreted as an integer"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), seed=2**70), nmci.RequestError, "`seed`: OverflowError: int too big to convert"),
    (lambda: nmci.sample_cross_covariances(np.eye(2), np.eye(2), count=-3), nmci.RequestError, "`count`: OverflowError: can't convert negative int to unsigned"),
    (lambda: nmci.sample_cross_covariances(np.eye(2), np.eye(2), count=2.5), nmci.RequestError, "`count`: TypeError: 'float' object cannot be interpreted as an integer"),
    (lambda: nmci.fuse({"pa": [[float("nan")]], "pb": [[1.0]], "method": "ci"}), nmci.RequestError, "`pa[0][0]` is NaN or infinite"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), samples=True), nmci.RequestError, "`samples`: a boolean is not a value of this field"),
    (lambda: nmci.nmci(np.eye(2), np.eye(2), blocks=[[0], "x"]), nmci.RequestError, "`blocks[1][0]`: TypeError"),
    (lambda: nmci._nmci.fuse_arrays("ci", np.eye(2), np.eye(2), colour=1), nmci.RequestError, "unknown field `colour`, expected one of criterion, samples"),
    (lambda: nmci._nmci.fuse_arrays("volume", np.eye(2), np.eye(2)), nmci.RequestError, "`method`: unknown variant `volume`"),
    (lambda: nmci.ci(np.eye(2), np.eye(2), np.array([np.nan, 0.0])), nmci.InputError, "x_a[0] is not finite"),
    (lambda: nmci.fuse({"pa": [[1.0]], "pb": [[1.0]], "method": "CI"}), nmci.RequestError, "(names are lower case: `ci`)"),
]


def test_request_errors_name_the_field_not_a_position_in_json_the_user_never_wrote():
    with pytest.raises(nmci.RequestError) as raised:
        nmci.fuse({"pa": [[1.0]], "pb": [[1.0]], "method": "CI"})
    assert raised.value.field == "method"
    with pytest.raises(nmci.RequestError) as raised:
        nmci.fuse({"pa": [[1.0]], "pb": [[1.0]], "samples": "many", "method": "sdp"})
    assert "line" not in str(raised.value) and "column" not in str(raised.value)
    with pytest.raises(nmci.RequestError) as raised:
        nmci.fuse([{"pa": [[1.0]], "pb": [[1.0]], "method": "ci"}, 3])
    assert "Wire" not in str(raised.value) and "a request is a JSON object (got a number)" in str(raised.value)
    with pytest.raises(nmci.InputError) as raised:
        nmci.ci(np.eye(2), np.eye(2), np.array([0.0, np.inf]))
    assert raised.value.field == "xa" and "x_a[1]" in str(raised.value)


@pytest.mark.parametrize("call,error,needle", BAD_CALLS, ids=[c[2] for c in BAD_CALLS])
def test_bad_input_raises_the_right_exception_with_its_message(call, error, needle):
    with pytest.raises(error) as raised:
        call()
    assert needle in str(raised.value)
    assert isinstance(raised.value, nmci.NmciError)
    assert isinstance(raised.value, (ValueError, RuntimeError))


def test_a_time_limit_raises_time_limit_error():
    rng = np.random.default_rng(7)
    a, b = spd(rng, 4), spd(rng, 4)
    # One known zero: a wholly unknown P_ab would take CI's bound without a solve.
    unknown = np.ones((4, 4), dtype=bool)
    unknown[1, 0] = False
    with pytest.raises(nmci.TimeLimitError) as raised:
        nmci.certified(a, b, pab_unknown=unknown, level=2, time_limit=1e-6)
    assert isinstance(raised.value, nmci.SolveError) and isinstance(raised.value, RuntimeError)
    assert "time limit" in str(raised.value)


def test_a_panic_becomes_internal_error_not_a_crash():
    with pytest.raises(nmci.InternalError) as raised:
        nmci._nmci._panic_for_test()
    assert "a panic raised on purpose" in str(raised.value)
    assert nmci.ci(np.eye(2), np.eye(2)).trace == 2.0  # the interpreter goes on


def test_the_gil_is_released_during_a_study():
    ticks = []
    state = {}

    def work():
        state["start"] = True
        nmci.track(runs=2, steps=150, coin=False)
        state["end"] = True

    worker = threading.Thread(target=work)
    worker.start()
    while "end" not in state:
        if "start" in state:
            ticks.append(1)
    worker.join()
    # With the GIL held for the whole study this loop could not run at all meanwhile.
    assert len(ticks) > 1000, len(ticks)


def shard(first_run, runs):
    return nmci.track(runs=runs, steps=25, seed=9, first_run=first_run)


def test_shards_from_a_process_pool_merge_into_one_run_bit_for_bit(tmp_path):
    whole = nmci.track(runs=5, steps=25, seed=9)
    with concurrent.futures.ProcessPoolExecutor(max_workers=2) as pool:
        shards = list(pool.map(shard, [3, 0, 1], [2, 1, 2]))
    assert [s.first_run for s in shards] == [3, 0, 1] and shards[1].has_coin
    merged = nmci.merge(shards)
    assert merged.summary == whole.summary and merged.config == whole.config
    for name in ("nees", "rmse", "two_sigma", "coin", "omega_nmci", "omega_ci", "omega_ici", "time"):
        assert np.array_equal(getattr(merged, name), getattr(whole, name)), name
    # Through files, and the CLI's files are those of Python's study.
    for s in shards:
        s.save(tmp_path / s.file_name)
    from_files = nmci.merge([tmp_path])
    assert from_files.summary == whole.summary
    assert pickle.loads(pickle.dumps(shards[0])).to_json() == shards[0].to_json()
    written = whole.write(tmp_path / "py")
    done = run_cli(["merge", str(tmp_path), "--out", str(tmp_path / "cli")])
    assert done.returncode == 0, done.stderr
    for f in written:
        name = Path(f).name
        assert (tmp_path / "cli" / name).read_bytes() == Path(f).read_bytes(), name
    # Refusals name the problem.
    with pytest.raises(nmci.MergeError, match=r"runs 1\.\.3 are in no shard"):
        nmci.merge([shards[1], shards[0]])
    with pytest.raises(nmci.MergeError, match="run 3 is in more than one shard"):
        nmci.merge(shards + [shard(3, 1)])


def test_a_study_from_a_configuration_file_and_overrides(tmp_path):
    cfg = tmp_path / "study.toml"
    cfg.write_text("steps = 7\nruns = 4\nseed = 5\ncoin = false\n")
    s = nmci.track(cfg, runs=2)
    assert (s.config["steps"], s.config["runs"], s.config["seed"], s.config["coin"]) == (7, 2, 5, False)
    assert s.coin.shape == (0, 7) and s.nees.shape == (5, 7)
    assert s.estimators == ["central", "ci", "nmci", "naive", "ici"]
    done = run_cli(["track", "--config", str(cfg), "--runs", "2", "--out", str(tmp_path / "cli")])
    assert done.returncode == 0, done.stderr
    assert json.loads((tmp_path / "cli" / "summary.json").read_text()) == s.summary
    assert nmci.track({"steps": 7, "runs": 2, "seed": 5, "coin": False}).summary == s.summary
    bad = tmp_path / "bad.toml"
    bad.write_text("steps = \n")
    with pytest.raises(nmci.StudyError, match="invalid configuration"):
        nmci.track(bad)


def test_fig2_matches_the_cli(tmp_path):
    f = nmci.fig2(runs=12, sizes=[1, 20], seed=2)
    done = run_cli(["fig2", "--runs", "12", "--sizes", "1,20", "--seed", "2", "--out", str(tmp_path)])
    assert done.returncode == 0, done.stderr
    lines = (tmp_path / "fig2.csv").read_text().strip().splitlines()
    header = lines[0].split(",")
    for row, line in zip(f.rows, lines[1:]):
        values = dict(zip(header, line.split(",")))
        assert int(values["samples"]) == row["samples"]
        assert float(values["dev_median"]) == row["dev"][0]
    assert f.dev.shape == (2, 3)
    # The same files, byte for byte.
    for written in f.write(tmp_path / "py"):
        name = Path(written).name
        assert Path(written).read_bytes() == (tmp_path / name).read_bytes(), name


def test_the_module_docstring_examples_run():
    failures, tried = doctest.testmod(nmci, verbose=False)
    assert tried > 0 and failures == 0


@pytest.mark.parametrize("example", sorted((ROOT / "examples" / "python").glob("*.py")), ids=lambda p: p.name)
def test_the_examples_run(example):
    done = subprocess.run(
        [sys.executable, str(example), "--quick"], capture_output=True, text=True, cwd=ROOT, timeout=600
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip()


def test_the_readme_python_example_runs_and_says_true_things():
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Python") :]
    block = section[section.index("```python\n") + len("```python\n") :]
    block = block[: block.index("```")]
    namespace = {}
    # The line that says "round-off absorbed" is the one the warning points at.
    with pytest.warns(nmci.StructureWarning, match="absorbed") as caught:
        exec(compile(block, "README.md", "exec"), namespace)
    absorbed = next(i for i, line in enumerate(block.split("\n"), 1) if "round-off absorbed" in line)
    assert [(w.filename, w.lineno) for w in caught] == [("README.md", absorbed)]
    # The block's own comment "proven: trace <cert> vs CI's <ci>" is the claim checked.
    cert, ci = re.search(r"proven: trace (\d\.\d{10}) vs CI's (\d\.\d{4})", block).groups()
    assert f"{namespace['cert'].trace:.10f}" == cert
    assert f"{namespace['ci'].trace:.4f}" == ci
    assert namespace["cuts"].gap_closed is True
    assert namespace["study"].nees.shape == (5, 400)


FIELD_CALLS = [
    (lambda: nmci.ci(-np.eye(2), np.eye(2)), "pa"),
    (lambda: nmci.ci(np.eye(2), np.eye(3)), "pb"),
    (lambda: nmci.ci(np.ones(3), np.eye(3)), "pa"),
    (lambda: nmci.nmci(np.eye(2), np.eye(2), xa=np.zeros(3)), "xa"),
    (lambda: nmci.nmci(np.eye(2), np.eye(2), pab_unknown=np.eye(2)), "pab_unknown"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), samples=0), "samples"),
    (lambda: nmci.certified(np.eye(2), np.eye(2), level=99), "level"),
    (lambda: nmci.sdp_cuts(np.eye(2), np.eye(2), sectors=65), "sectors"),
    (lambda: nmci.fuse({"pa": [[1]], "pb": [[1]], "method": "ci", "seed": 1}), "seed"),
    (lambda: nmci.fuse({"pa": [[1]], "pb": [[1]], "method": "ci", "colour": 1}), "colour"),
    (lambda: nmci.ci_nway([np.eye(2), -np.eye(2)]), "estimates[1].p"),
    (lambda: nmci.conservativeness_index(np.eye(2), np.eye(3)), "E"),
    (lambda: nmci.fig2(runs=0), "runs"),
    (lambda: nmci.optimal(np.eye(6), np.eye(6), max_trials=10), None),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), time_limit=float("inf")), "time_limit"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), seed=-1), "seed"),
    (lambda: nmci.certified(np.eye(2), np.eye(2), level="2"), "level"),
    (lambda: nmci.fuse({"pa": [[1.0]], "pb": np.array([[np.inf]]), "method": "ci"}), "pb"),
    (lambda: nmci.ci(np.eye(2), np.eye(2) * 1e308), "pb"),
    (lambda: nmci.nmci(np.eye(2), np.eye(2), blocks=[[0]]), "blocks"),
    (lambda: nmci.nmci(np.eye(2), np.eye(2), blocks=[[0], "x"]), "blocks"),
    (lambda: nmci.nmci([[2, 0.5], [0.5, 1]], np.eye(2), blocks=[[0], [1]]), "pa"),
    (lambda: nmci.nmci(np.eye(2), np.eye(2), blocks=[[0], [1]], pab_unknown=np.ones((2, 2), bool)), "pab_unknown"),
    (lambda: nmci.certified(np.eye(2), np.eye(2), coupling_tol=2.0), "coupling_tol"),
    (lambda: nmci.nmci_nway([np.eye(2), np.eye(2)], blocks=[[0, 1, 2]]), "blocks"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), seed=2**70), "seed"),
    (lambda: nmci.optimal(np.eye(2), np.eye(2), samples=True), "samples"),
    (lambda: nmci._nmci.fuse_arrays("ci", np.eye(2), np.eye(2), colour=1), "colour"),
    (lambda: nmci._nmci.fuse_arrays("volume", np.eye(2), np.eye(2)), "method"),
    (lambda: nmci.sample_cross_covariances(np.eye(2), np.eye(2), count=-3), "count"),
]


@pytest.mark.parametrize("call,field", FIELD_CALLS, ids=[str(c[1]) for c in FIELD_CALLS])
def test_errors_name_the_request_field_at_fault(call, field):
    with pytest.raises(nmci.NmciError) as raised:
        call()
    assert raised.value.field == field


def test_the_registry_of_rules_and_a_function_per_rule():
    rules = nmci.rules()
    names = [r["name"] for r in rules]
    assert names == ["ci", "nmci", "certified", "sdp", "sdp_cuts", "ici", "ei", "naive"]
    a, b = np.diag([3.0, 1.0]), np.diag([1.0, 4.0])
    function = {"sdp": nmci.optimal}
    for r in rules:
        fused = function.get(r["name"], getattr(nmci, r["name"], None))(a, b)
        assert fused.method == r["name"]
        # Every response states its rule's guarantee, as the registry does.
        assert fused.guarantee == r["guarantee"]
    assert {r["name"] for r in rules if r["nway"]} == {"ci", "nmci"}
    assert all(hasattr(nmci, f"{r['name']}_nway") for r in rules if r["nway"])


def test_the_installed_wheel_carries_both_licence_texts():
    from importlib.metadata import distribution
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    files = {Path(str(f)).name: f for f in distribution("nmci").files or []}
    for name in ("LICENSE-MIT", "LICENSE-APACHE"):
        assert name in files, sorted(files)
        assert Path(files[name].locate()).read_text() == (root / name).read_text()


def test_the_wheel_installs_where_researchers_work():
    """manylinux2014 (glibc 2.17): RHEL/Rocky 8 and 9 clusters take it, not only this machine."""
    from pathlib import Path

    wheels = list((Path(__file__).resolve().parents[2] / "target" / "wheels").glob("nmci-*.whl"))
    assert len(wheels) == 1, wheels
    assert "manylinux_2_17_x86_64" in wheels[0].name and "abi3" in wheels[0].name, wheels[0].name
