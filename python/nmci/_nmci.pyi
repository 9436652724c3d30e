"""Type stubs of the extension module ``nmci._nmci`` (python/src/); use the functions of
``nmci`` instead, which wrap these with documented signatures."""

from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

__version__: str

Array = npt.NDArray[np.float64]

class Fused:
    """A fused estimate: the contract's response (docs/contract.md), written by serde from the
    Rust response, with numpy arrays for the estimate, the bound, the gains and the weights.

    Every field of the contract is an attribute, ``None`` where the method does not report it;
    ``P``, ``Ka`` and ``Kb`` are the contract's ``p``, ``ka`` and ``kb``. ``r["field"]`` reads the
    response by its contract name, ``r.to_dict()`` gives it with lists, as ``nmci fuse`` prints
    it. Read-only; picklable."""

    FIELDS: List[str]
    """The contract's fields a response can carry (``nmci::contract::response_fields``)."""
    ALIASES: Dict[str, str]
    """``{"P": "p", "Ka": "ka", "Kb": "kb"}``."""

    method: str
    criterion: str
    x: Array
    P: Array
    Ka: Optional[Array]
    Kb: Optional[Array]
    gains: Optional[Array]
    weights: Optional[Array]
    trace: float
    det: float
    omega: Optional[Array]
    blocks: Optional[List[List[int]]]
    samples: Optional[int]
    status: Optional[str]
    iterations: Optional[int]
    acceptance_rate: Optional[float]
    sampler_choice: Optional[Dict[str, Any]]
    lmis: Optional[int]
    worst_sample_margin: Optional[float]
    lower_bound: Optional[float]
    upper_bound: Optional[float]
    upper_bound_rule: Optional[str]
    gap: Optional[float]
    gap_relative: Optional[float]
    repair: Optional[float]
    gain_certified_trace: Optional[float]
    gain_certified_p: Optional[Array]
    """``sdp``, ``sdp_cuts``: a bound proven for the method's own gain (``Ka``, ``Kb``) and every
    admissible cross-covariance; ``(x, gain_certified_p)`` is a conservative estimate where
    ``(x, P)`` (the relaxation's) is not. ``gain_certified_trace`` is its trace rounded up."""
    levels: Optional[List[int]]
    sectors: Optional[List[int]]
    stop: Optional[str]
    violation: Optional[float]
    converged: Optional[bool]
    gap_closed: Optional[bool]
    own_rule_proven: Optional[bool]
    proof_rounds: Optional[int]
    guarantee: str
    structure: Optional[Dict[str, Any]]

    def __init__(self, fields: Dict[str, Any]) -> None: ...
    @property
    def structure_note(self) -> Optional[str]:
        """How the blocks were found, when that is worth saying (near-zero couplings absorbed,
        declared blocks, a weak coupling keeping blocks merged): ``structure["note"]``. Also
        issued as a ``StructureWarning`` when the response is made."""
    def __getitem__(self, key: str) -> Any: ...
    def __contains__(self, key: str) -> bool: ...
    def keys(self) -> List[str]:
        """The contract's fields present in this response."""
    def to_dict(self) -> Dict[str, Any]:
        """The response with lists instead of arrays (the JSON ``nmci fuse`` prints)."""

class FusedStack:
    """``k`` pairs fused by one closed-form rule (``ci``, ``nmci``, ``ici``, ``ei``, ``naive``),
    each pair's numbers those of the single call: arrays stacked along the first axis."""

    method: str
    x: Array
    """Fused estimates, ``(k, n)``."""
    P: Array
    """Bounds, ``(k, n, n)``."""
    Ka: Array
    Kb: Array
    trace: Array
    """``tr P`` of each pair, ``(k,)``."""
    det: Array
    omega: Optional[Array]
    """The weight of each state, ``(k, n)``: CI's and ICI's ``ω`` on every state, nmCI's ``ω`` of
    the state's block; ``None`` for EI and naive fusion."""
    blocks: Optional[List[List[List[int]]]]
    """nmCI: the blocks of each pair."""
    structure_notes: List[Optional[str]]
    def __len__(self) -> int: ...

def fuse_stack(
    method: str,
    pa: npt.NDArray[np.float64],
    pb: npt.NDArray[np.float64],
    xa: Optional[Array] = None,
    xb: Optional[Array] = None,
    pab_unknown: Optional[npt.NDArray[np.bool_]] = None,
    **options: Any,
) -> FusedStack: ...
def fuse_json(request: str) -> str: ...
def fuse_arrays(
    method: str,
    pa: Optional[Array] = None,
    pb: Optional[Array] = None,
    xa: Optional[npt.NDArray[np.float64]] = None,
    xb: Optional[npt.NDArray[np.float64]] = None,
    pab_unknown: Optional[npt.NDArray[np.bool_]] = None,
    criterion: Optional[str] = None,
    estimates: Optional[Sequence[Tuple[Optional[Array], Array]]] = None,
    patterns: Optional[Sequence[Tuple[int, int, npt.NDArray[np.bool_]]]] = None,
    **options: Any,
) -> Fused: ...
def conservativeness_index(P: Array, E: Array) -> float: ...
def sample_cross_covariances(
    pa: Array,
    pb: Array,
    pab_unknown: Optional[npt.NDArray[np.bool_]],
    count: int,
    **options: Any,
) -> Tuple[Array, int]: ...
def config_from_toml(text: str) -> Dict[str, Any]: ...
def default_config() -> Dict[str, Any]: ...
def rules() -> List[Dict[str, Any]]: ...
def request_field(name: str) -> str: ...
def run_study(config: Dict[str, Any]) -> Study: ...
def run_shard(config: Dict[str, Any], first_run: int) -> Shard: ...
def merge(shards: List[Shard]) -> Study: ...
def shard_files(dir: str) -> List[str]: ...
def fig2(runs: int, sizes: List[int], seed: int) -> Fig2Rows: ...

class Study:
    def config(self) -> Dict[str, Any]: ...
    def report(self) -> Dict[str, Any]: ...
    def estimators(self) -> List[str]: ...
    def series2(self, name: str) -> Array: ...
    def series1(self, name: str) -> Array: ...
    def nees_bounds(self) -> Tuple[float, float]: ...
    def write(self, out: str) -> List[str]: ...

class Shard:
    """Runs ``first_run .. first_run + runs`` of a study: merge shards with ``nmci.merge``.
    Picklable (process pools, Dask, Ray)."""

    def __init__(self, text: str) -> None: ...
    def to_json(self) -> str: ...
    def save(self, path: str) -> None: ...
    @property
    def file_name(self) -> str: ...
    @property
    def first_run(self) -> int: ...
    @property
    def runs(self) -> int: ...
    @property
    def has_coin(self) -> bool: ...

class Fig2Rows:
    def rows(self) -> List[Dict[str, Any]]: ...
    def write(self, out: str) -> List[str]: ...
