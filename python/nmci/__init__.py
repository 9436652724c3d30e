"""nmci — conservative fusion when the cross-covariance is unknown except for known zeros.

Two estimates ``(x_a, P_a)``, ``(x_b, P_b)`` are fused into ``x = K_a x_a + K_b x_b`` with a
bound ``P`` that holds for every cross-covariance ``P_ab`` consistent with what is known: the
joint covariance is positive definite and the entries of ``P_ab`` marked ``False`` in
``pab_unknown`` are zero. This package is a thin layer over nmci's Rust crate: the same rules,
defaults, checks and messages as the CLI (``nmci fuse``) and the browser explorer, with numpy
arrays in and out, and the GIL released during every solve and study.

>>> import numpy as np, nmci
>>> Pa, Pb = np.diag([3.0, 1.0]), np.diag([1.0, 4.0])
>>> known_zero_off_diagonal = np.eye(2, dtype=bool)
>>> r = nmci.nmci(Pa, Pb, pab_unknown=known_zero_off_diagonal)
>>> r.P
array([[1., 0.],
       [0., 1.]])
>>> r.omega
array([0., 1.])
>>> round(nmci.ci(Pa, Pb).trace, 4)  # CI ignores the known zeros
3.0882

**Stacks.** :func:`ci`, :func:`nmci`, :func:`ici`, :func:`ei` and :func:`naive` also take ``k``
pairs at once: ``Pa``, ``Pb`` of shape ``(k, n, n)``, means ``(k, n)``, ``pab_unknown`` of shape
``(n, n)`` (every pair's) or ``(k, n, n)``. They return a :class:`FusedStack` of arrays stacked
along the first axis (``x``, ``P``, ``Ka``, ``Kb``, ``trace``, ``det``, ``omega`` per state), each
pair's numbers those of the single call; an error names the pair (``pa[17]``).

Rules: :func:`ci`, :func:`nmci`, :func:`optimal` (the paper's sampled SDP), :func:`sdp_cuts`
(cutting planes with a proven bracket), :func:`certified` (a bound proven by a sum-of-squares
certificate), :func:`ici`, :func:`ei`, :func:`naive`, and N-way :func:`ci_nway`,
:func:`nmci_nway`; :func:`fuse` is the JSON contract itself. Tools:
:func:`conservativeness_index`, :func:`sample_cross_covariances`. The paper's studies:
:func:`track` (the 16-agent tracking study; shards with ``first_run`` and :func:`merge` split it
across processes and machines) and :func:`fig2`.
"""

from __future__ import annotations

import json
import math
import os
import re
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _errors, _nmci
from ._errors import (
    InputError,
    InternalError,
    MergeError,
    NmciError,
    OutputError,
    RequestError,
    SampleError,
    SimulationError,
    SolveError,
    StructureWarning,
    StudyError,
    TimeLimitError,
)
from ._nmci import Fused, FusedStack, Shard

__version__: str = _nmci.__version__

ArrayLike = Any
PathLike = Union[str, "os.PathLike[str]"]

__all__ = [
    "Fused",
    "FusedStack",
    "Study",
    "Shard",
    "Fig2",
    "fuse",
    "ci",
    "nmci",
    "optimal",
    "sdp_cuts",
    "certified",
    "ici",
    "ei",
    "naive",
    "ci_nway",
    "nmci_nway",
    "conservativeness_index",
    "sample_cross_covariances",
    "track",
    "merge",
    "load_shard",
    "default_config",
    "fig2",
    "rules",
    *_errors.__all__,
]


# ---------------------------------------------------------------------------------------------
# Fusion


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def fuse(
    request: Union[Mapping[str, Any], Sequence[Mapping[str, Any]]]
) -> Union[Dict[str, Any], List[Dict[str, Any]]]:
    """Runs a request of the JSON contract and returns its response, exactly as ``nmci fuse``.

    ``request`` is the contract's object (numpy arrays may stand for nested lists); the
    response is a plain dict with lists. A list of requests gives the list of their responses
    (the first that fails raises, its field ``[i].field``). Errors raise the exceptions of this
    package with the CLI's messages.
    """
    try:
        text = json.dumps(request, default=_jsonable, allow_nan=False)
    except (TypeError, ValueError) as e:
        # JSON has no NaN or infinity: name where the first one is (searched only then).
        at = _non_finite(request, "")
        if at is not None:
            # The top field (`pa`), or in a list the element's (`[1].pa`).
            field = re.match(r"(?:\[\d+\]\.)?[^.\[]*", at).group(0)
            raise RequestError(f"invalid request: `{at}` is NaN or infinite (JSON has no such numbers)", field) from None
        raise RequestError(f"invalid request: {e}") from None
    return json.loads(_nmci.fuse_json(text))


def _field(name: str) -> str:
    """The JSON request field of an input named ``name`` in messages (``P_a`` → ``pa``)."""
    return _nmci.request_field(name)


def _array(name: str, a: ArrayLike, ndim: Union[int, Tuple[int, ...]]) -> np.ndarray:
    """``a`` as a contiguous float64 array of ``ndim`` dimensions (one of them, given a tuple),
    or an ``InputError``."""
    dims = (ndim,) if isinstance(ndim, int) else ndim
    if np.iscomplexobj(a):
        raise InputError(f"{name} is complex: covariances and means are real", _field(name))
    try:
        m = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name} is not a numeric array: {e}", _field(name)) from None
    if m.ndim not in dims:
        want = " or ".join(f"{d}-D" for d in dims)
        raise InputError(f"{name} must be a {want} array (got {m.ndim}-D)", _field(name))
    return np.ascontiguousarray(m)


def _matrix(name: str, a: ArrayLike) -> np.ndarray:
    return _array(name, a, 2)


def _vector(name: str, a: Optional[ArrayLike], ndim: int = 1) -> Optional[np.ndarray]:
    return None if a is None else _array(name, a, ndim)


def _pattern(name: str, a: Optional[ArrayLike], ndim: Tuple[int, ...] = (2,)) -> Optional[np.ndarray]:
    if a is None:
        return None
    m = np.asarray(a)
    if m.dtype != np.bool_:
        raise InputError(
            f"{name} must be an array of booleans (True = may be non-zero, False = known zero), got dtype {m.dtype}",
            _field(name),
        )
    if m.ndim not in ndim:
        want = " or ".join(f"{d}-D" for d in ndim)
        raise InputError(f"{name} must be a {want} array (got {m.ndim}-D)", _field(name))
    return np.ascontiguousarray(m)


def _non_finite(value: Any, path: str) -> Optional[str]:
    """The path of the first NaN or infinity in a request (``pa[0][1]``), if any."""
    if isinstance(value, Mapping):
        return next((p for k, v in value.items() if (p := _non_finite(v, f"{path}.{k}" if path else str(k)))), None)
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fc" and not np.all(np.isfinite(value)):
            index = tuple(int(i) for i in np.argwhere(~np.isfinite(value))[0])
            return path + "".join(f"[{i}]" for i in index)
        return None
    if isinstance(value, (list, tuple)):
        return next((p for i, v in enumerate(value) if (p := _non_finite(v, f"{path}[{i}]"))), None)
    if isinstance(value, (float, np.floating)) and not math.isfinite(value):
        return path
    return None


def _two(
    method: str,
    Pa: ArrayLike,
    Pb: ArrayLike,
    xa: Optional[ArrayLike],
    xb: Optional[ArrayLike],
    pab_unknown: Optional[ArrayLike],
    criterion: Optional[str] = None,
    **options: Any,
) -> Union[Fused, FusedStack]:
    """A two-estimate rule on any inputs: converted (or refused, named) here, then fused.

    The closed-form rules first hand their arguments to ``_fuse_arrays`` as they are: one pair
    of float64 arrays goes straight to Rust, which reads any strides and checks every number.
    What it cannot take as given (another dtype, a list, a stack) it refuses with a
    ``TypeError`` before any work, and the rule comes here. ``fuse_arrays`` issues a structure
    note as a ``StructureWarning`` at the first frame outside this package.
    """
    pa = _array("P_a", Pa, (2, 3))
    if pa.ndim == 3:
        # A stack of pairs: `(k, n, n)` covariances, `(k, n)` means, one pattern or one each.
        return _nmci.fuse_stack(
            method,
            pa,
            _array("P_b", Pb, 3),
            _vector("x_a", xa, 2),
            _vector("x_b", xb, 2),
            _pattern("pab_unknown", pab_unknown, (2, 3)),
            criterion=criterion,
            **options,
        )
    return _fuse_arrays(
        method,
        pa,
        _matrix("P_b", Pb),
        _vector("x_a", xa),
        _vector("x_b", xb),
        _pattern("pab_unknown", pab_unknown),
        criterion,
        **options,
    )


_fuse_arrays = _nmci.fuse_arrays


def ci(
    Pa: ArrayLike,
    Pb: ArrayLike,
    xa: Optional[ArrayLike] = None,
    xb: Optional[ArrayLike] = None,
    *,
    pab_unknown: Optional[ArrayLike] = None,
    criterion: Optional[str] = None,
) -> Union[Fused, FusedStack]:
    """Covariance intersection with the exactly optimal ``ω`` (``criterion`` "trace" or
    "logdet"): conservative for every cross-covariance. ``omega`` is ``[ω]``.

    Stacks (``Pa``, ``Pb`` of shape ``(k, n, n)``) give a :class:`FusedStack`.
    """
    try:
        return _fuse_arrays("ci", Pa, Pb, xa, xb, pab_unknown, criterion)
    except TypeError:
        pass  # not one pair of float64 arrays (`_two`)
    return _two("ci", Pa, Pb, xa, xb, pab_unknown, criterion)


def nmci(
    Pa: ArrayLike,
    Pb: ArrayLike,
    xa: Optional[ArrayLike] = None,
    xb: Optional[ArrayLike] = None,
    *,
    pab_unknown: Optional[ArrayLike] = None,
    blocks: Optional[Sequence[Sequence[int]]] = None,
    coupling_tol: Optional[float] = None,
    criterion: Optional[str] = None,
) -> Union[Fused, FusedStack]:
    """Non-monolithic CI: one ``ω`` per independent block of the known-zero pattern
    (``blocks``, ``omega``); conservative for every admissible cross-covariance.

    ``blocks`` declares a partition of the states into blocks with independent errors (it
    implies ``pab_unknown`` when that is not given); entries of ``Pa``, ``Pb`` between blocks up
    to ``coupling_tol`` relative (default ``1e-9``; ``0``: exact zeros only) are absorbed into a
    proven block-diagonal bound, reported in ``structure``.
    Stacks (``Pa``, ``Pb`` of shape ``(k, n, n)``) give a :class:`FusedStack`.
    """
    try:
        return _fuse_arrays("nmci", Pa, Pb, xa, xb, pab_unknown, criterion, blocks=blocks, coupling_tol=coupling_tol)
    except TypeError:
        pass  # not one pair of float64 arrays (`_two`)
    return _two("nmci", Pa, Pb, xa, xb, pab_unknown, criterion, blocks=blocks, coupling_tol=coupling_tol)


def optimal(
    Pa: ArrayLike,
    Pb: ArrayLike,
    xa: Optional[ArrayLike] = None,
    xb: Optional[ArrayLike] = None,
    *,
    pab_unknown: Optional[ArrayLike] = None,
    blocks: Optional[Sequence[Sequence[int]]] = None,
    coupling_tol: Optional[float] = None,
    samples: Optional[int] = None,
    seed: Optional[int] = None,
    sampler: Optional[str] = None,
    max_trials: Optional[int] = None,
    time_limit: Optional[float] = None,
    level: Optional[int] = None,
    sectors: Optional[int] = None,
    cones: Optional[int] = None,
    max_cones: Optional[int] = None,
) -> Fused:
    """The paper's sampled SDP (method "sdp"): the tightest bound over ``samples`` sampled
    cross-covariances — a lower bound on the robust optimum, not guaranteed conservative.
    The response carries the proven bracket ``[lower_bound, upper_bound]`` on the robust
    optimum.

    ``blocks`` declares a partition of the states into blocks with independent errors (it
    implies ``pab_unknown`` when that is not given). Entries of ``Pa``, ``Pb`` between blocks up
    to ``coupling_tol`` relative (default ``1e-9``; ``0``: exact zeros only) are absorbed for the
    bracket's upper ends, proven on the absorbed problem (a block-diagonal bound that dominates
    them); the relaxation itself solves the *deflated* problem (those entries dropped, the
    diagonals lowered by as much), so that its proven lower end holds for the given covariances.
    Reported in ``structure``.
    """
    return _two(
        "sdp",
        Pa,
        Pb,
        xa,
        xb,
        pab_unknown,
        blocks=blocks,
        coupling_tol=coupling_tol,
        samples=samples,
        seed=seed,
        sampler=sampler,
        max_trials=max_trials,
        time_limit=time_limit,
        level=level,
        sectors=sectors,
        cones=cones,
        max_cones=max_cones,
    )


def sdp_cuts(
    Pa: ArrayLike,
    Pb: ArrayLike,
    xa: Optional[ArrayLike] = None,
    xb: Optional[ArrayLike] = None,
    *,
    pab_unknown: Optional[ArrayLike] = None,
    blocks: Optional[Sequence[Sequence[int]]] = None,
    coupling_tol: Optional[float] = None,
    seed: Optional[int] = None,
    time_limit: Optional[float] = None,
    level: Optional[int] = None,
    sectors: Optional[int] = None,
    cones: Optional[int] = None,
    max_cones: Optional[int] = None,
    cuts_tolerance: Optional[float] = None,
) -> Fused:
    """The robust SDP by cutting planes: worst-case cross-covariances as constraints, with a
    proven bracket on the robust optimum (``lower_bound``, ``upper_bound``, ``gap_closed``,
    ``stop``). The loop stops when the worst violation it finds is below ``cuts_tolerance``
    times ``max(tr P̄, 1)`` (default ``1e-7``); where the proof of its own rule leaves a
    three-state bracket open, it goes on once to ``1e-10`` and proves again.

    ``blocks`` declares a partition of the states into blocks with independent errors (it
    implies ``pab_unknown`` when that is not given). Entries of ``Pa``, ``Pb`` between blocks are
    *not* absorbed: the loop stops on a bracket computed on the problem it solves, so it solves
    the covariances as given, the blocks such entries couple merged into one; ``structure``
    says so (``absorbed``: ``False``, and its note).
    """
    return _two(
        "sdp_cuts",
        Pa,
        Pb,
        xa,
        xb,
        pab_unknown,
        blocks=blocks,
        coupling_tol=coupling_tol,
        seed=seed,
        time_limit=time_limit,
        level=level,
        sectors=sectors,
        cones=cones,
        max_cones=max_cones,
        cuts_tolerance=cuts_tolerance,
    )


def certified(
    Pa: ArrayLike,
    Pb: ArrayLike,
    xa: Optional[ArrayLike] = None,
    xb: Optional[ArrayLike] = None,
    *,
    pab_unknown: Optional[ArrayLike] = None,
    blocks: Optional[Sequence[Sequence[int]]] = None,
    coupling_tol: Optional[float] = None,
    level: Optional[int] = None,
    sectors: Optional[int] = None,
    cones: Optional[int] = None,
    max_cones: Optional[int] = None,
    time_limit: Optional[float] = None,
) -> Fused:
    """A bound proven to dominate ``K P' Kᵀ`` for every admissible ``P'`` by a sum-of-squares
    certificate of level ``level`` (``levels`` per block), or, on blocks of two states, by a
    level-1 certificate on each of ``sectors`` sectors of directions (by default the library's
    count, chosen by measurement, unless ``level`` is set; ``sectors`` per block, 0 where none), and on blocks of three states,
    when ``cones`` (4, 16 or 64) is given, on each of that many cones of directions, or when
    ``max_cones`` (4 to 256) is given, on at most that many cones cut where the bound is
    tight; its
    trace never above that of CI's (nmCI's) bound made a proven matrix: within ``1e-14`` of
    their traces on well-conditioned blocks, up to 1.44 % above on near-singular ones.

    ``blocks`` declares a partition of the states into blocks with independent errors (it
    implies ``pab_unknown`` when that is not given); entries of ``Pa``, ``Pb`` between blocks up
    to ``coupling_tol`` relative (default ``1e-9``; ``0``: exact zeros only) are absorbed into a
    proven block-diagonal bound, reported in ``structure``.
    """
    return _two(
        "certified",
        Pa,
        Pb,
        xa,
        xb,
        pab_unknown,
        blocks=blocks,
        coupling_tol=coupling_tol,
        level=level,
        sectors=sectors,
        cones=cones,
        max_cones=max_cones,
        time_limit=time_limit,
    )


def ici(
    Pa: ArrayLike,
    Pb: ArrayLike,
    xa: Optional[ArrayLike] = None,
    xb: Optional[ArrayLike] = None,
    *,
    pab_unknown: Optional[ArrayLike] = None,
    criterion: Optional[str] = None,
) -> Union[Fused, FusedStack]:
    """Inverse covariance intersection: conservative for common-information correlation only
    (``guarantee``: ``"common_information"``).

    Stacks (``Pa``, ``Pb`` of shape ``(k, n, n)``) give a :class:`FusedStack`.
    """
    try:
        return _fuse_arrays("ici", Pa, Pb, xa, xb, pab_unknown, criterion)
    except TypeError:
        pass  # not one pair of float64 arrays (`_two`)
    return _two("ici", Pa, Pb, xa, xb, pab_unknown, criterion)


def ei(
    Pa: ArrayLike,
    Pb: ArrayLike,
    xa: Optional[ArrayLike] = None,
    xb: Optional[ArrayLike] = None,
    *,
    pab_unknown: Optional[ArrayLike] = None,
) -> Union[Fused, FusedStack]:
    """Ellipsoidal intersection: not guaranteed conservative.

    Stacks (``Pa``, ``Pb`` of shape ``(k, n, n)``) give a :class:`FusedStack`.
    """
    try:
        return _fuse_arrays("ei", Pa, Pb, xa, xb, pab_unknown)
    except TypeError:
        pass  # not one pair of float64 arrays (`_two`)
    return _two("ei", Pa, Pb, xa, xb, pab_unknown)


def naive(
    Pa: ArrayLike,
    Pb: ArrayLike,
    xa: Optional[ArrayLike] = None,
    xb: Optional[ArrayLike] = None,
    *,
    pab_unknown: Optional[ArrayLike] = None,
) -> Union[Fused, FusedStack]:
    """Naive fusion (as if the estimates were independent): not conservative when they are
    correlated.

    Stacks (``Pa``, ``Pb`` of shape ``(k, n, n)``) give a :class:`FusedStack`.
    """
    try:
        return _fuse_arrays("naive", Pa, Pb, xa, xb, pab_unknown)
    except TypeError:
        pass  # not one pair of float64 arrays (`_two`)
    return _two("naive", Pa, Pb, xa, xb, pab_unknown)


Estimates = Sequence[Union[ArrayLike, Tuple[Optional[ArrayLike], ArrayLike]]]
Patterns = Union[Mapping[Tuple[int, int], ArrayLike], Sequence[Tuple[int, int, ArrayLike]]]


def _nway(
    method: str,
    estimates: Estimates,
    patterns: Optional[Patterns],
    criterion: Optional[str],
    blocks: Optional[Sequence[Sequence[int]]] = None,
    coupling_tol: Optional[float] = None,
) -> Fused:
    items = []
    for k, e in enumerate(estimates):
        if isinstance(e, tuple):
            if len(e) != 2:
                raise InputError(f"estimate {k} must be P or a pair (x, P)", f"estimates[{k}]")
            x, P = e
        else:
            x, P = None, e
        items.append((_vector(f"estimates[{k}].x", x), _matrix(f"estimates[{k}].p", P)))
    pairs = None
    if patterns is not None:
        entries = patterns.items() if isinstance(patterns, Mapping) else patterns
        pairs = []
        for entry in entries:
            (i, j), mask = entry if isinstance(patterns, Mapping) else ((entry[0], entry[1]), entry[2])
            pairs.append((int(i), int(j), _pattern(f"pattern ({i}, {j})", mask)))
    return _nmci.fuse_arrays(
        method, estimates=items, patterns=pairs, criterion=criterion, blocks=blocks, coupling_tol=coupling_tol
    )


def ci_nway(
    estimates: Estimates, *, patterns: Optional[Patterns] = None, criterion: Optional[str] = None
) -> Fused:
    """N-way CI: one weight per estimate on the simplex (``weights``, ``gains``). Each estimate
    is ``P`` or ``(x, P)``; ``patterns`` maps a pair ``(i, j)`` to the pattern of ``P_ij``
    (pairs not listed are fully unknown; CI does not use them)."""
    return _nway("ci", estimates, patterns, criterion)


def nmci_nway(
    estimates: Estimates,
    *,
    patterns: Optional[Patterns] = None,
    criterion: Optional[str] = None,
    blocks: Optional[Sequence[Sequence[int]]] = None,
    coupling_tol: Optional[float] = None,
) -> Fused:
    """N-way nmCI: one weight vector per independent block of the pairs' known-zero patterns.

    ``blocks`` declares a partition of the states into blocks with independent errors (pairs
    not in ``patterns`` then take the pattern it implies); entries of each estimate's ``P``
    between blocks up to ``coupling_tol`` relative (default ``1e-9``) are absorbed into a
    proven block-diagonal bound, reported in ``structure``."""
    return _nway("nmci", estimates, patterns, criterion, blocks, coupling_tol)


def conservativeness_index(P: ArrayLike, E: ArrayLike) -> float:
    """``λ_max(P^{-1/2} E P^{-1/2})``: ``≤ 1`` exactly when ``P`` bounds the error covariance ``E``.

    ``P`` must be a covariance and ``E`` of its size, finite and symmetric (``InputError``
    otherwise); ``E`` need not be definite. An index beyond the largest float is ``inf``."""
    return _nmci.conservativeness_index(_matrix("P", P), _matrix("E", E))


def sample_cross_covariances(
    Pa: ArrayLike,
    Pb: ArrayLike,
    pab_unknown: Optional[ArrayLike] = None,
    *,
    count: int = 100,
    seed: Optional[int] = None,
    sampler: Optional[str] = None,
    max_trials: Optional[int] = None,
) -> np.ndarray:
    """``count`` admissible cross-covariances ``P_ab'`` (an array ``count × n × n``): the
    paper's rejection sampler, "hit_and_run" (any dimension; correlated samples) or "auto" (the
    rejection sampler where a pilot finds its acceptance workable, hit-and-run otherwise)."""
    stack, _trials = _nmci.sample_cross_covariances(
        _matrix("P_a", Pa),
        _matrix("P_b", Pb),
        _pattern("pab_unknown", pab_unknown),
        count,
        seed=seed,
        sampler=sampler,
        max_trials=max_trials,
    )
    return stack


# ---------------------------------------------------------------------------------------------
# Studies


class Study:
    """A tracking study's results: ``config`` and ``summary`` (the CLI's ``summary.json``) as
    dicts, and the per-step series as numpy arrays — ``nees``, ``rmse``, ``two_sigma``, ``coin``
    (``estimators × steps``; ``coin`` is empty without COIN), ``omega_ci``, ``omega_ici``
    (per step), ``omega_nmci`` (``blocks × steps``), ``time`` (seconds)."""

    def __init__(self, inner: "_nmci.Study") -> None:
        self._inner = inner
        self.config: Dict[str, Any] = inner.config()
        self.summary: Dict[str, Any] = inner.report()
        self.estimators: List[str] = inner.estimators()
        self.nees: np.ndarray = inner.series2("nees")
        self.rmse: np.ndarray = inner.series2("rmse")
        self.two_sigma: np.ndarray = inner.series2("two_sigma")
        self.coin: np.ndarray = inner.series2("coin")
        self.omega_nmci: np.ndarray = inner.series2("omega_nmci")
        self.omega_ci: np.ndarray = inner.series1("omega_ci")
        self.omega_ici: np.ndarray = inner.series1("omega_ici")
        self.nees_bounds: Tuple[float, float] = inner.nees_bounds()
        steps = self.config["steps"]
        self.time: np.ndarray = np.arange(1, steps + 1) * self.config["scenario"]["dt"]

    def write(self, out: PathLike) -> List[str]:
        """Writes what ``nmci track`` writes (summary.json, CSVs, SVG charts, network.svg) into
        the folder ``out``; returns the files."""
        return self._inner.write(os.fspath(out))

    def __repr__(self) -> str:
        c = self.config
        return f"Study(runs={c['runs']}, steps={c['steps']}, seed={c['seed']}, estimators={self.estimators})"


def rules() -> List[Dict[str, Any]]:
    """Every fusion rule, from the registry the CLI and the page read (``nmci::rules::RULES``): its
    ``name`` (the ``method`` of the JSON contract), ``label``, ``legend``, ``colour``,
    ``guarantee`` (``conservative``, ``relaxation``, ``common_information`` or ``none``),
    ``criteria``, ``options`` (the method-specific request fields it takes), ``nway``,
    ``explorer`` and ``limits`` (``max_dim``, ``max_block``: the largest problem the contract
    accepts for it)."""
    return _nmci.rules()


def default_config() -> Dict[str, Any]:
    """The default study configuration (``configs/paper.toml``) as a dict."""
    return _nmci.default_config()


def _config(config: Union[None, Mapping[str, Any], PathLike]) -> Dict[str, Any]:
    if config is None:
        return default_config()
    if isinstance(config, Mapping):
        return dict(config)
    path = os.fspath(config)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise StudyError(f"cannot read {path}: {e.strerror}") from None
    return _nmci.config_from_toml(text)


def track(
    config: Union[None, Mapping[str, Any], PathLike] = None,
    *,
    runs: Optional[int] = None,
    steps: Optional[int] = None,
    seed: Optional[int] = None,
    coin: Optional[bool] = None,
    first_run: Optional[int] = None,
) -> Union[Study, Shard]:
    """Runs the 16-agent tracking study on every core (``nmci track``).

    ``config`` is ``None`` (the defaults), a dict of configuration keys (the form of
    ``configs/paper.toml``; missing keys take their defaults) or the path of a TOML file;
    ``runs``, ``steps``, ``seed`` and ``coin`` override it. With ``first_run`` the call runs
    only runs ``first_run .. first_run + runs`` and returns a :class:`Shard`; :func:`merge`
    puts shards back together into exactly the :class:`Study` of one call.
    """
    cfg = _config(config)
    for key, value in (("runs", runs), ("steps", steps), ("seed", seed), ("coin", coin)):
        if value is not None:
            cfg[key] = value
    if first_run is not None:
        return _nmci.run_shard(cfg, int(first_run))
    return Study(_nmci.run_study(cfg))


def load_shard(path: PathLike) -> Shard:
    """Reads a shard file (``Shard.save``, ``nmci track --first-run``)."""
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise MergeError(f"cannot read {path}: {e.strerror}") from None
    return Shard(text)


def merge(shards: Iterable[Union[Shard, PathLike]]) -> Study:
    """Merges shards (objects, shard files, or folders of ``shard-*.json`` files) into the one
    study they are slices of, bit for bit (``nmci merge``)."""
    items: List[Shard] = []
    for s in shards:
        if isinstance(s, Shard):
            items.append(s)
            continue
        path = os.fspath(s)
        if os.path.isdir(path):
            files = _nmci.shard_files(path)
            if not files:
                raise MergeError(f"{path} holds no shard-*.json file")
            items.extend(load_shard(f) for f in files)
        else:
            items.append(load_shard(path))
    return Study(_nmci.merge(items))


class Fig2:
    """The paper's fig. 2 (``nmci fig2``): per sample-set size, the median, minimum and maximum
    over the runs of ``‖P_nmCI − P_opt‖₂`` (``dev``), of ``λ_min(P − K P_true Kᵀ)`` for nmCI and
    the sampled SDP (``eig_nmci``, ``eig_opt``) and of their COIN; arrays ``sizes × 3``."""

    def __init__(self, inner: "_nmci.Fig2Rows", runs: int) -> None:
        self._inner = inner
        rows: List[Dict[str, Any]] = inner.rows()
        self.rows = rows
        self.runs = runs
        self.samples: np.ndarray = np.array([r["samples"] for r in rows])
        self.failures: np.ndarray = np.array([r["failures"] for r in rows])
        column = lambda k: np.array([r[k] for r in rows], dtype=np.float64)  # noqa: E731
        self.dev: np.ndarray = column("dev")
        self.eig_nmci: np.ndarray = column("eig_nmci")
        self.eig_opt: np.ndarray = column("eig_opt")
        self.coin_nmci: np.ndarray = column("coin_nmci")
        self.coin_opt: np.ndarray = column("coin_opt")

    def write(self, out: PathLike) -> List[str]:
        """Writes what ``nmci fig2`` writes (fig2.csv, fig2.svg) into the folder ``out``; returns
        the files."""
        return self._inner.write(os.fspath(out))

    def __repr__(self) -> str:
        return f"Fig2(runs={self.runs}, samples={self.samples.tolist()})"


def fig2(
    runs: int = 1000,
    sizes: Sequence[int] = (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000),
    seed: int = 0,
) -> Fig2:
    """The paper's fig. 2 on the 2-D example, in parallel over runs."""
    return Fig2(_nmci.fig2(int(runs), [int(s) for s in sizes], int(seed)), int(runs))
