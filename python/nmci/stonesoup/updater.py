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

Declared blocks the data violate
--------------------------------
Declared blocks are a modelling claim. A range-bearing radar, for one, couples the axes of its
tracks, and then the estimates carry entries between blocks far above ``coupling_tol``. With
``on_violation="merge"`` (the default) the updater merges every pair of blocks such an entry links
(in ``A`` or ``B``, relative to the square root of its diagonal entries, as nmci compares it) and
fuses the merged blocks by the rule: CI over a merged block is still conservative for every
cross-covariance, so the guarantee stands and only the per-block weights are lost there. It
warns once per track (a ``StructureWarning`` naming the coupling found) and records the merge in
``update.fusion.merged``. ``on_violation="raise"`` raises nmci's ``InputError`` instead.

Degenerate covariances
----------------------
A fixed ``ω`` uses the pseudo-inverse form of CI, as ``ChernoffUpdater`` does:
:math:`P = (ω A^+ + (1-ω) B^+)^+`, :math:`x = P (ω A^+ a + (1-ω) B^+ b)`. It is conservative
whenever :math:`ω A^+ + (1-ω) B^+` is invertible: the gains :math:`K_a = P ω A^+`,
:math:`K_b = P (1-ω) B^+` sum to the identity and, since :math:`A^+ A A^+ = A^+`,
:math:`K_a (A/ω) K_a^T + K_b (B/(1-ω)) K_b^T = P`, which bounds the error covariance for every
cross-covariance (the inequality of "The innovation covariance"). Where it is singular (no
information at all in some direction) the update is refused with the field named.
"""

import warnings
from typing import Optional, Sequence

import numpy as np
from stonesoup.base import Property
from stonesoup.types.prediction import MeasurementPrediction
from stonesoup.types.update import Update
from stonesoup.updater.base import Updater

import nmci
from nmci._errors import InputError, RequestError, StructureWarning

from .types import FusionInfo, target_type

#: The rules' default coupling tolerance (nmci's ``coupling_tol``), used to find the blocks the
#: data couple.
DEFAULT_COUPLING_TOL = 1e-9


def _block_list(blocks: Optional[Sequence[Sequence[int]]], n: int) -> list:
    return [list(range(n))] if blocks is None else [list(b) for b in blocks]


def _relative(P: np.ndarray, i: int, j: int) -> float:
    d = np.sqrt(abs(P[i, i] * P[j, j]))
    return abs(P[i, j]) / d if d > 0 else (np.inf if P[i, j] != 0 else 0.0)


def merge_coupled_blocks(blocks, matrices, tol=DEFAULT_COUPLING_TOL):
    """The declared ``blocks`` with every pair that an entry of one of ``matrices`` couples
    beyond ``tol`` (relative to the square root of its diagonal entries, as nmci compares it)
    merged, and one sentence per merge naming the strongest such entry.

    Parameters
    ----------
    blocks : sequence of sequence of int
        A partition of the states.
    matrices : mapping of str to array_like
        The covariances to check, by name (``{"measurement": A, "prediction": B}``).
    tol : float
        The coupling tolerance.

    Returns
    -------
    merged : list of list of int
        The blocks, coupled ones merged, ordered by first state.
    notes : list of str
        What was merged and why.
    """
    blocks = [sorted(int(i) for i in b) for b in blocks]
    owner = {i: k for k, b in enumerate(blocks) for i in b}
    parent = list(range(len(blocks)))

    def root(k):
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    strongest = {}
    for name, P in matrices.items():
        P = np.asarray(P, dtype=float)
        for i in owner:
            for j in owner:
                if i < j and owner[i] != owner[j]:
                    r = _relative(P, i, j)
                    if r > tol:
                        key = (min(owner[i], owner[j]), max(owner[i], owner[j]))
                        if key not in strongest or r > strongest[key][0]:
                            strongest[key] = (r, name, i, j, P[i, j])
    notes = []
    for (k, m), (r, name, i, j, value) in sorted(strongest.items()):
        parent[root(m)] = root(k)
        notes.append(f"{name}[{i}][{j}] = {value:.6g} couples declared blocks {blocks[k]} and {blocks[m]} "
                     f"({r:.3g} relative, above coupling_tol {tol:g}): fused as one block")
    groups = {}
    for k, b in enumerate(blocks):
        groups.setdefault(root(k), []).extend(b)
    merged = sorted((sorted(g) for g in groups.values()), key=lambda g: g[0])
    return merged, notes


def chernoff_log_normaliser(a, A, b, B, omega: float) -> float:
    r"""The log of the Chernoff normaliser :math:`\int N(x; a, A)^ω N(x; b, B)^{1-ω} dx`.

    Parameters
    ----------
    a, b : array_like
        The two means.
    A, B : array_like
        Their covariances (positive definite).
    omega : float
        The weight on ``(a, A)``, in ``(0, 1)``.

    Returns
    -------
    float
        :math:`\log Z(ω) = \log κ(ω) + \log N(a; b, V(ω))` (module docs).

    References
    ----------
    .. [1] Hurley, M. B., "An information theoretic justification for covariance intersection
       and its generalization", Proc. FUSION 2002.
    """
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
    r"""The innovation covariance ``V`` of Chernoff fusion (module docs).

    Parameters
    ----------
    A : array_like
        The measurement's covariance (``n × n``, or one that numpy broadcasts to it, as
        ``ChernoffUpdater`` takes a measurement model's).
    B : array_like
        The prediction's covariance (``n × n``).
    omega : float or sequence of float, optional
        One weight per block (or one for all); a block whose ``ω`` is 0 or 1, or
        ``omega=None``, takes the family's least-trace
        :math:`ω_k = \sqrt{\operatorname{tr} A_k} / (\sqrt{\operatorname{tr} A_k} + \sqrt{\operatorname{tr} B_k})`.
    blocks : sequence of sequence of int, optional
        The blocks (default: one block).

    Returns
    -------
    numpy.ndarray
        ``V``, block-diagonal over ``blocks``, block ``k`` being :math:`A_k/ω_k + B_k/(1-ω_k)`.
    """
    B = np.asarray(B, dtype=float)
    A = _broadcast(A, B.shape)
    n = B.shape[0]
    blocks = _block_list(blocks, n)
    weights = [None] * len(blocks) if omega is None else list(np.broadcast_to(np.asarray(omega, dtype=float), (len(blocks),)))
    V = np.zeros_like(B)
    for block, w in zip(blocks, weights):
        ix = np.ix_(block, block)
        Ak, Bk = A[ix], B[ix]
        if w is None or not 0.0 < w < 1.0:
            ra, rb = np.sqrt(max(np.trace(Ak), 0.0)), np.sqrt(max(np.trace(Bk), 0.0))
            w = ra / (ra + rb) if ra + rb > 0 else 0.5
            w = min(max(w, np.finfo(float).eps), 1 - np.finfo(float).eps)
        V[ix] = Ak / w + Bk / (1.0 - w)
    return V


def _broadcast(A, shape) -> np.ndarray:
    """``A`` as an array of ``shape``, broadcast as numpy (and ``ChernoffUpdater``) does."""
    A = np.asarray(A, dtype=float)
    try:
        return np.array(np.broadcast_to(A, shape))
    except ValueError:
        raise InputError(f"the measurement model's covariance has shape {A.shape}, which does not "
                         f"broadcast to the state's {shape}", "measurement_model") from None


def fixed_omega_ci(a, A, b, B, omega: float):
    r"""CI at a fixed weight in its pseudo-inverse form (module docs, "Degenerate covariances"),
    as ``ChernoffUpdater`` computes it.

    Parameters
    ----------
    a, b : array_like
        The means (measurement, prediction).
    A, B : array_like
        Their covariances: positive semi-definite, with :math:`ω A^+ + (1-ω) B^+` invertible.
    omega : float
        The weight on ``(a, A)``, in ``[0, 1]``.

    Returns
    -------
    x : numpy.ndarray
        The fused mean (a column).
    P : numpy.ndarray
        Its bound, conservative for every cross-covariance.
    """
    a, b = np.reshape(np.asarray(a, dtype=float), (-1, 1)), np.reshape(np.asarray(b, dtype=float), (-1, 1))
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    for name, M in (("measurement.covar", A), ("prediction.covar", B)):
        if not np.all(np.isfinite(M)):
            raise InputError(f"`{name}` has a non-finite entry", name)
        if np.min(np.linalg.eigvalsh((M + M.T) / 2)) < -1e-12 * max(np.max(np.abs(M)), 1e-300):
            raise InputError(f"`{name}` is not positive semi-definite", name)
    w = float(omega)
    information = w * np.linalg.pinv(A, hermitian=True) + (1 - w) * np.linalg.pinv(B, hermitian=True)
    if np.linalg.matrix_rank(information, hermitian=True) < information.shape[0]:
        raise InputError(f"at omega = {w} the two estimates carry no information in some direction "
                         "(ω A⁺ + (1 − ω) B⁺ is singular): no bound exists there", "omega")
    P = np.linalg.inv(information)
    x = P @ (w * np.linalg.pinv(A, hermitian=True) @ a + (1 - w) * np.linalg.pinv(B, hermitian=True) @ b)
    return x, (P + P.T) / 2


def _check_omega(value):
    if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, np.floating))
                              or not 0.0 <= float(value) <= 1.0):
        raise RequestError(f"`omega` must be a number in [0, 1] (got {value!r})", "omega")


def _check_pair(omega, rule):
    if omega is not None and rule is not None and rule != "ci":
        raise RequestError(f"a fixed `omega` is CI's weight; rule {rule!r} chooses its own", "omega")


class NmciUpdater(Updater):
    r"""Track-to-track fusion by one of nmci's rules: a drop-in for ``ChernoffUpdater``.

    The measurement is a Gaussian estimate ``(a, A)`` — a
    :class:`~stonesoup.types.detection.GaussianDetection`, e.g. from
    ``Tracks2GaussianDetectionFeeder`` — and the prediction ``(b, B)``. With ``omega`` set the
    rule is CI at that fixed weight on the measurement, which is ``ChernoffUpdater``'s update
    (to rounding); otherwise the rule's own weights: the exactly optimal ``ω`` of ``ci``, nmCI's
    ``ω`` per independent block, the certified rule's gains, ... (module docs). The arguments
    are in ``ChernoffUpdater``'s order: ``NmciUpdater(measurement_model, omega)``.

    Which rules fit a tracker's per-update budget: ``ci`` and ``nmci`` are closed form;
    ``certified``, ``sdp`` and ``sdp_cuts`` solve programs per update. One update per rule,
    beside ``ChernoffUpdater``, is measured in ``docs/benchmarks.md`` ("Stone Soup: one update
    per rule").

    Each update carries a :class:`~nmci.stonesoup.types.FusionInfo` as ``update.fusion``, a
    declared Property: the update is of the kind Stone Soup would build, extended by it
    (:mod:`nmci.stonesoup.types`). The hypothesis's ``measurement_prediction`` carries the same
    ``fusion``, which is where it survives ``PHDUpdater``, which rebuilds its components from
    the mean and covariance alone.

    References
    ----------
    .. [1] Julier, S. J., Uhlmann, J. K., "A non-divergent estimation algorithm in the presence
       of unknown correlations", Proc. American Control Conference, 1997.
    .. [2] Funk, Dagan, Noack, Ahmed, "Exploiting Structure for Optimal Multi-Agent Bayesian
       Decentralized Estimation".
    """

    omega: Optional[float] = Property(
        default=None,
        doc="A fixed weight on the measurement in [0, 1] (rule ``ci`` only), as "
            "``ChernoffUpdater``'s ``omega``; default: the rule's optimum.")
    rule: str = Property(default="ci", doc="The fusion rule: a name of :func:`nmci.rules`.")
    criterion: str = Property(default="trace", doc="``trace`` or ``logdet``.")
    pab_unknown: Optional[np.ndarray] = Property(
        default=None,
        doc="Which entries of the cross-covariance may be non-zero (default: all).")
    blocks: Optional[list] = Property(
        default=None,
        doc="A partition of the states into blocks with independent errors (e.g. "
            ":func:`blocks_from_transition_model`): a modelling claim, checked against the data.")
    coupling_tol: Optional[float] = Property(
        default=None, doc="Couplings between blocks absorbed up to this relative size (nmci's default 1e-9).")
    on_violation: str = Property(
        default="merge",
        doc="Where the data couple declared blocks beyond ``coupling_tol``: ``merge`` (fuse the "
            "coupled blocks as one, warn once per track) or ``raise``.")
    options: Optional[dict] = Property(
        default=None, doc="The rule's other options (``level``, ``time_limit``, ``samples``, ...).")

    @omega.setter
    def omega(self, value):
        _check_omega(value)
        _check_pair(value, getattr(self, "_property_rule", None))
        self._property_omega = value

    @rule.setter
    def rule(self, value):
        names = [r["name"] for r in nmci.rules()]
        if value not in names:
            raise RequestError(f"`rule` must be one of {', '.join(names)} (got {value!r})", "rule")
        _check_pair(getattr(self, "_property_omega", None), value)
        self._property_rule = value

    @criterion.setter
    def criterion(self, value):
        if value is None:
            value = "trace"
        if value not in ("trace", "logdet"):
            raise RequestError(f"`criterion` must be trace or logdet (got {value!r})", "criterion")
        self._property_criterion = value

    @on_violation.setter
    def on_violation(self, value):
        if value not in ("merge", "raise"):
            raise RequestError(f"`on_violation` must be merge or raise (got {value!r})", "on_violation")
        self._property_on_violation = value

    @coupling_tol.setter
    def coupling_tol(self, value):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, np.floating))
                                  or not 0.0 <= float(value) <= 1.0):
            raise RequestError(f"`coupling_tol` must be a number in [0, 1] (got {value!r})", "coupling_tol")
        self._property_coupling_tol = value

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._warned = set()

    def _blocks_for(self, A, B, key=None):
        """The blocks to fuse over, and the merges the data forced (module docs)."""
        if self.blocks is None:
            return None, ()
        tol = DEFAULT_COUPLING_TOL if self.coupling_tol is None else float(self.coupling_tol)
        merged, notes = merge_coupled_blocks(self.blocks, {"measurement.covar": A, "prediction.covar": B}, tol)
        if not notes or self.on_violation == "raise":
            return self.blocks, ()
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(f"NmciUpdater: the declared blocks do not hold for this track: {'; '.join(notes)}",
                          StructureWarning, stacklevel=3)
        return merged, tuple(notes)

    def _request(self, A, B, blocks, a=None, b=None) -> dict:
        request = {"method": self.rule, "pa": A, "pb": B, **(self.options or {})}
        if self.criterion != "trace":
            request["criterion"] = self.criterion
        if self.pab_unknown is not None:
            request["pab_unknown"] = np.asarray(self.pab_unknown, dtype=bool)
        if blocks is not None:
            request["blocks"] = blocks
            if self.pab_unknown is not None and blocks != self.blocks:
                # Merged blocks: the cross pattern between the blocks merged is unknown.
                mask = np.asarray(self.pab_unknown, dtype=bool).copy()
                for g in blocks:
                    mask[np.ix_(g, g)] = True
                request["pab_unknown"] = mask
        if self.coupling_tol is not None:
            request["coupling_tol"] = self.coupling_tol
        if a is not None:
            request["xa"], request["xb"] = np.ravel(a), np.ravel(b)
        return request

    def _weights(self, A, B, key=None):
        """The weight of each block for ``V``, and the blocks."""
        if self.omega is not None:
            return [float(self.omega)], None
        blocks, _ = self._blocks_for(A, B, key)
        if self.rule in ("ci", "nmci"):
            try:
                r = nmci.fuse(self._request(A, B, blocks))
            except InputError:
                # A covariance without a bound of its own (semi-definite, e.g. a measurement
                # model's broadcast row): the least-trace member of the family, still a bound.
                return None, blocks
            return r["omega"], r.get("blocks")
        return None, blocks

    def _square(self, measurement_model, predicted_state):
        if measurement_model.ndim_meas != predicted_state.ndim or \
                list(measurement_model.mapping) != list(range(predicted_state.ndim)):
            raise InputError(
                "the measurement model must map the whole state (a track as a measurement: "
                f"mapping {list(range(predicted_state.ndim))}), got mapping {list(measurement_model.mapping)}",
                "measurement_model")

    def predict_measurement(self, predicted_state, measurement_model=None, measurement_noise=True, **kwargs):
        r"""The measurement prediction of Chernoff fusion.

        Parameters
        ----------
        predicted_state : :class:`~stonesoup.types.state.GaussianState`
            The prediction ``(b, B)``.
        measurement_model : :class:`~stonesoup.models.measurement.linear.LinearGaussian`, optional
            The model of the measurement (default: the updater's); it must map the whole state,
            and its covariance is broadcast to the state's, as ``ChernoffUpdater`` does.
        measurement_noise : bool
            With ``False``, the predicted covariance ``B`` itself, as ``ChernoffUpdater`` gives.

        Returns
        -------
        :class:`~stonesoup.types.prediction.GaussianMeasurementPrediction`
            The predicted state, and as innovation covariance ``V`` at the rule's weights
            (module docs), with ``cross_covar`` the predicted covariance.
        """
        measurement_model = self._check_measurement_model(measurement_model)
        self._square(measurement_model, predicted_state)
        B = np.asarray(predicted_state.covar, dtype=float)
        if measurement_noise:
            A = _broadcast(measurement_model.covar(), B.shape)
            omega, blocks = self._weights(A, B)
            V = innovation_covariance(A, B, omega, blocks)
        else:
            V = B
        return MeasurementPrediction.from_state(
            predicted_state, predicted_state.state_vector, V, predicted_state.timestamp,
            cross_covar=predicted_state.covar)

    def update(self, hypothesis, force_symmetric_covariance=False, **kwargs):
        r"""The fused state.

        Parameters
        ----------
        hypothesis : :class:`~stonesoup.types.hypothesis.SingleHypothesis`
            The prediction and a Gaussian measurement (a track from another node).
        force_symmetric_covariance : bool
            Symmetrise the covariance (it is symmetric already for every rule but the SDPs').

        Returns
        -------
        :class:`~stonesoup.types.update.Update`
            An update of the kind Stone Soup builds for the prediction, with the declared
            Property ``fusion`` (:class:`~nmci.stonesoup.types.FusionInfo`); the hypothesis's
            ``measurement_prediction`` is replaced by the same one with that ``fusion`` (class
            docs).
        """
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
        if A.shape != B.shape:
            raise InputError(f"the measurement's covariance is {A.shape[0]}×{A.shape[1] if A.ndim > 1 else 1}, "
                             f"the prediction's {n}×{n}", "measurement")
        if self.omega is not None:
            w = float(self.omega)
            x, P = fixed_omega_ci(a, A, b, B, w)
            info = FusionInfo("ci", (w,), (tuple(range(n)),),
                              "conservative: CI at a fixed weight bounds the error for every cross-covariance")
        else:
            metadata = getattr(measurement, "metadata", None) or {}
            key = metadata.get("track_id", id(measurement))
            blocks, merged = self._blocks_for(A, B, key)
            r = nmci.fuse(self._request(A, B, blocks, a, b))
            x, P = np.reshape(r["x"], (n, 1)), np.asarray(r["p"], dtype=float)
            guarantee = r["guarantee"]
            # The SDPs' own `p` is a relaxation's: the bound proven for their gain is the
            # covariance a filter can carry on with (module docs).
            if r.get("gain_certified_p") is not None:
                P, guarantee = np.asarray(r["gain_certified_p"], dtype=float), "conservative"
            omega, blocks_used = r.get("omega"), r.get("blocks")
            info = FusionInfo(
                self.rule,
                None if omega is None else tuple(float(w) for w in omega),
                None if blocks_used is None else tuple(tuple(b) for b in blocks_used),
                guarantee,
                merged)
        if force_symmetric_covariance:
            P = (P + P.T) / 2
        mp = hypothesis.measurement_prediction
        hypothesis.measurement_prediction = MeasurementPrediction.from_state(
            mp, target_type=target_type(MeasurementPrediction, mp), fusion=info)
        return Update.from_state(
            prediction, state_vector=x, covar=P, hypothesis=hypothesis, timestamp=measurement.timestamp,
            target_type=target_type(Update, prediction), fusion=info)
