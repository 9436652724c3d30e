r"""Track-to-track fusion in Stone Soup by nmci's rules: :class:`NmciUpdater`.

The measurement is a Gaussian estimate ``(a, A)`` — a
:class:`~stonesoup.types.detection.GaussianDetection`, e.g. from
``Tracks2GaussianDetectionFeeder`` — and the prediction is ``(b, B)``. The updater fuses them by
one of nmci's rules (``ci``, ``nmci``, ``certified``, ``sdp``, ``sdp_cuts``, ``ici``, ``ei``,
``naive``: :func:`nmci.rules`), with ``ω`` the weight on the measurement, as in Stone Soup's
``ChernoffUpdater``.

The innovation covariance
-------------------------
Gating and PHD weights need the likelihood of the measurement given the prediction. For the
Chernoff fusion rule it is the normaliser of the fused density,

.. math::

    Z(ω) = \int N(x; a, A)^{ω} N(x; b, B)^{1-ω} \, dx,  \qquad ω ∈ (0, 1).

Since :math:`N(x; a, A)^{ω} = |2πA|^{(1-ω)/2} ω^{-n/2} N(x; a, A/ω)` and the integral of a
product of two Gaussian densities in ``x`` is a Gaussian density of the difference of their means,

.. math::

    Z(ω) = κ(ω) \, N(a; b, V(ω)), \qquad V(ω) = \frac{A}{ω} + \frac{B}{1-ω}, \qquad
    κ(ω) = |2πA|^{(1-ω)/2} |2πB|^{ω/2} ω^{-n/2} (1-ω)^{-n/2}

(:func:`chernoff_log_normaliser` computes ``log Z``; a test checks it against numerical
integration). :meth:`NmciUpdater.predict_measurement` returns ``V(ω)``, the covariance of the
Gaussian factor, as Stone Soup's updaters do (the factor ``κ`` is not a covariance; it is left out
there as in ``ChernoffUpdater``).

``ChernoffUpdater`` uses ``A/(1-ω) + B/ω`` instead: the two agree at ``ω = 0.5`` only. At any
other ``ω`` Stone Soup's matrix is ``V(1 - ω)``, the normaliser of the product with the weights
swapped (a test shows the difference against the integral).

``V(ω)`` is also a bound on the innovation covariance whatever the correlation of the two errors:
for errors ``e_a``, ``e_b`` with any cross-covariance ``C``, expanding
:math:`0 ⪯ E[(\sqrt{t} e_a + e_b / \sqrt{t})(\cdot)^T]` gives
:math:`-C - C^T ⪯ t A + B/t`, so with ``t = (1 - ω)/ω``

.. math::

    \operatorname{Cov}(a - b) = A + B - C - C^T ⪯ A/ω + B/(1-ω) = V(ω)

(a test checks it on random joint covariances). Gating with ``V`` therefore never rejects a true
association more often than the gate's level says.

The covariance of the update is the rule's bound ``p``, except for the SDPs (``sdp``,
``sdp_cuts``): their ``p`` is a relaxation's, imposed for finitely many cross-covariances only,
so a track carrying it could become overconfident. Where their response carries
``gain_certified_p`` — a bound proven for their own gain and every admissible cross-covariance,
rounding included (blocks of up to four states; see :attr:`nmci.Fused.gain_certified_p`) — the
update takes that, with the same estimate, and ``update.fusion.guarantee`` says
``"conservative"``; otherwise ``p``, and the guarantee says ``"relaxation"``.

Blocks: where the states split into blocks with no entries of ``A``, ``B`` or ``C`` between them
(nmCI's blocks, or declared ``blocks``), the densities factor over the blocks, each block with its
own ``ω_k``, and ``V`` is block-diagonal with blocks ``V_k(ω_k)``. A block fused at an endpoint
(``ω_k`` 0 or 1: one estimate alone) has a flat normaliser (``V_k`` infinite); there, and for the
rules without a CI weight (``certified``, ``sdp``, ``sdp_cuts``, ``ei``, ``naive``, ``ici``),
the block of ``V`` is the member of the family with the least trace,
``ω_k = √tr A_k / (√tr A_k + √tr B_k)``: still a bound on the innovation covariance, so gating
keeps the guarantee above. ``V`` is formed from the diagonal blocks of ``A`` and ``B`` as given:
where the entries between blocks are exact zeros the bound is exact; where the rule absorbed
couplings within ``coupling_tol`` (its ``structure``), ``Cov(a - b)`` has entries between blocks
of that relative size that ``V`` does not hold, so there the bound holds up to them.
"""

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np
from stonesoup.base import Property
from stonesoup.types.prediction import MeasurementPrediction
from stonesoup.types.update import Update
from stonesoup.updater.base import Updater

import nmci
from nmci._errors import InputError, RequestError


@dataclass(frozen=True)
class FusionInfo:
    """What a fusion by nmci reports, attached to each update as ``update.fusion``.

    ``omega``: the weight on the measurement of each block (``None`` for rules without one);
    ``blocks``: the blocks of states (``None`` when the rule reports none); ``guarantee``: the
    rule's guarantee, as nmci states it (``"conservative"``, a bracket, ...).
    """

    rule: str
    omega: Optional[Tuple[float, ...]]
    blocks: Optional[Tuple[Tuple[int, ...], ...]]
    guarantee: str


def _block_list(blocks: Optional[Sequence[Sequence[int]]], n: int) -> list:
    return [list(range(n))] if blocks is None else [list(b) for b in blocks]


def chernoff_log_normaliser(a, A, b, B, omega: float) -> float:
    """``log ∫ N(x; a, A)^ω N(x; b, B)^(1-ω) dx`` for ``ω`` in ``(0, 1)`` (module docs)."""
    a, b = np.ravel(a), np.ravel(b)
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    if not 0.0 < omega < 1.0:
        raise RequestError(f"`omega` must be in (0, 1) for the normaliser (got {omega})", "omega")
    n = len(a)
    V = A / omega + B / (1.0 - omega)
    _, logdet_a = np.linalg.slogdet(2 * np.pi * A)
    _, logdet_b = np.linalg.slogdet(2 * np.pi * B)
    _, logdet_v = np.linalg.slogdet(2 * np.pi * V)
    d = a - b
    gauss = -0.5 * (logdet_v + d @ np.linalg.solve(V, d))
    kappa = 0.5 * ((1 - omega) * logdet_a + omega * logdet_b) - 0.5 * n * (np.log(omega) + np.log1p(-omega))
    return float(kappa + gauss)


def innovation_covariance(A, B, omega=None, blocks: Optional[Sequence[Sequence[int]]] = None) -> np.ndarray:
    """``V``: block-diagonal over ``blocks`` (default: one block), block ``k`` being
    ``A_k/ω_k + B_k/(1-ω_k)`` (module docs). ``omega`` holds one weight per block (or one for
    all); a block whose ``ω`` is 0 or 1, or ``omega=None``, takes the family's least-trace
    ``ω_k = √tr A_k / (√tr A_k + √tr B_k)``."""
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    n = A.shape[0]
    blocks = _block_list(blocks, n)
    weights = [None] * len(blocks) if omega is None else list(np.broadcast_to(np.asarray(omega, dtype=float), (len(blocks),)))
    V = np.zeros_like(A)
    for block, w in zip(blocks, weights):
        ix = np.ix_(block, block)
        Ak, Bk = A[ix], B[ix]
        if w is None or not 0.0 < w < 1.0:
            ra, rb = np.sqrt(np.trace(Ak)), np.sqrt(np.trace(Bk))
            w = ra / (ra + rb)
        V[ix] = Ak / w + Bk / (1.0 - w)
    return V


class NmciUpdater(Updater):
    """Fuses a Gaussian measurement (a track from another node) with the prediction by one of
    nmci's rules: a drop-in for ``ChernoffUpdater(None)`` (module docs).

    With ``omega`` set, the rule is CI at that fixed weight on the measurement, which is
    ``ChernoffUpdater``'s update (to rounding). Otherwise the rule's own weights: the exactly
    optimal ``ω`` of ``ci``, nmCI's ``ω`` per independent block, the certified rule's gains, ...
    Each update carries a :class:`FusionInfo` as ``update.fusion``.
    """

    rule: str = Property(default="ci", doc="The fusion rule: a name of :func:`nmci.rules`.")
    omega: Optional[float] = Property(
        default=None,
        doc="A fixed weight on the measurement in [0, 1] (rule ``ci`` only); default: the rule's optimum.")
    criterion: Optional[str] = Property(default=None, doc="``trace`` (default) or ``logdet``.")
    pab_unknown: Optional[np.ndarray] = Property(
        default=None,
        doc="Which entries of the cross-covariance may be non-zero (default: all).")
    blocks: Optional[list] = Property(
        default=None,
        doc="A partition of the states into blocks with independent errors (e.g. "
            ":func:`blocks_from_transition_model`).")
    coupling_tol: Optional[float] = Property(
        default=None, doc="Couplings between blocks absorbed up to this relative size (nmci's default 1e-9).")
    options: Optional[dict] = Property(
        default=None, doc="The rule's other options (``level``, ``time_limit``, ``samples``, ...).")

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        names = [r["name"] for r in nmci.rules()]
        if self.rule not in names:
            raise RequestError(f"`rule` must be one of {', '.join(names)} (got {self.rule!r})", "rule")
        if self.omega is not None:
            if isinstance(self.omega, bool) or not isinstance(self.omega, (int, float, np.floating)) \
                    or not 0.0 <= float(self.omega) <= 1.0:
                raise RequestError(f"`omega` must be a number in [0, 1] (got {self.omega!r})", "omega")
            if self.rule != "ci":
                raise RequestError(f"a fixed `omega` is CI's weight; rule {self.rule!r} chooses its own", "omega")

    def _structure(self) -> dict:
        fields = {
            "pab_unknown": None if self.pab_unknown is None else np.asarray(self.pab_unknown, dtype=bool),
            "blocks": self.blocks,
            "coupling_tol": self.coupling_tol,
            "criterion": self.criterion,
        }
        return {k: v for k, v in fields.items() if v is not None}

    def _fuse(self, A, B, a=None, b=None) -> dict:
        request = {"method": self.rule, "pa": A, "pb": B, **self._structure(), **(self.options or {})}
        if a is not None:
            request["xa"], request["xb"] = np.ravel(a), np.ravel(b)
        return nmci.fuse(request)

    def _weights(self, A, B):
        """The weight of each block for ``V``, and the blocks."""
        if self.omega is not None:
            return [float(self.omega)], None
        if self.rule in ("ci", "nmci"):
            r = self._fuse(A, B)
            return r["omega"], r.get("blocks")
        return None, self.blocks or None

    def _square(self, measurement_model, predicted_state):
        if measurement_model.ndim_meas != predicted_state.ndim or \
                list(measurement_model.mapping) != list(range(predicted_state.ndim)):
            raise InputError(
                "the measurement model must map the whole state (a track as a measurement: "
                f"mapping {list(range(predicted_state.ndim))}), got mapping {list(measurement_model.mapping)}",
                "measurement_model")

    def predict_measurement(self, predicted_state, measurement_model=None, measurement_noise=True, **kwargs):
        """The measurement prediction: the predicted state, and as innovation covariance ``V``
        at the rule's weights (module docs); ``measurement_noise=False`` gives the predicted
        covariance, as ``ChernoffUpdater`` does."""
        measurement_model = self._check_measurement_model(measurement_model)
        self._square(measurement_model, predicted_state)
        B = np.asarray(predicted_state.covar, dtype=float)
        if measurement_noise:
            A = np.asarray(measurement_model.covar(), dtype=float)
            omega, blocks = self._weights(A, B)
            V = innovation_covariance(A, B, omega, blocks)
        else:
            V = B
        return MeasurementPrediction.from_state(
            predicted_state, predicted_state.state_vector, V, predicted_state.timestamp,
            cross_covar=predicted_state.covar)

    def update(self, hypothesis, force_symmetric_covariance=False, **kwargs):
        """The fused state, an ``Update`` of the prediction's kind, with ``update.fusion``."""
        measurement, prediction = hypothesis.measurement, hypothesis.prediction
        if hypothesis.measurement_prediction is None:
            hypothesis.measurement_prediction = self.predict_measurement(
                prediction, measurement_model=measurement.measurement_model, **kwargs)
        covar = getattr(measurement, "covar", None)
        if covar is None:
            raise InputError("the measurement has no covariance: NmciUpdater fuses Gaussian "
                             "estimates (GaussianDetection, e.g. from Tracks2GaussianDetectionFeeder)",
                             "measurement")
        a, A = np.asarray(measurement.state_vector, dtype=float), np.asarray(covar, dtype=float)
        b, B = np.asarray(prediction.state_vector, dtype=float), np.asarray(prediction.covar, dtype=float)
        n = B.shape[0]
        if self.omega is not None:
            w = float(self.omega)
            Ai, Bi = np.linalg.inv(A), np.linalg.inv(B)
            P = np.linalg.inv(w * Ai + (1 - w) * Bi)
            x = P @ (w * Ai @ a + (1 - w) * Bi @ b)
            info = FusionInfo("ci", (w,), (tuple(range(n)),),
                              "conservative: CI at a fixed weight bounds the error for every cross-covariance")
        else:
            r = self._fuse(A, B, a, b)
            x, P = np.reshape(r["x"], (n, 1)), np.asarray(r["p"], dtype=float)
            guarantee = r["guarantee"]
            # The SDPs' own `p` is a relaxation's: the bound proven for their gain is the
            # covariance a filter can carry on with (module docs).
            if r.get("gain_certified_p") is not None:
                P, guarantee = np.asarray(r["gain_certified_p"], dtype=float), "conservative"
            omega, blocks = r.get("omega"), r.get("blocks")
            info = FusionInfo(
                self.rule,
                None if omega is None else tuple(float(w) for w in omega),
                None if blocks is None else tuple(tuple(b) for b in blocks),
                guarantee)
        if force_symmetric_covariance:
            P = (P + P.T) / 2
        update = Update.from_state(prediction, x, P, hypothesis, measurement.timestamp)
        update.fusion = info
        return update
