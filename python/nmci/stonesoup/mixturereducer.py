"""N-way fusion of Gaussian states with optimal weights: :class:`NmciCovarianceIntersection`."""

from typing import Optional

import numpy as np
from stonesoup.base import Property
from stonesoup.mixturereducer.base import MixtureReducer
from stonesoup.types.state import GaussianState

import nmci
from nmci._errors import RequestError

from .updater import FusionInfo


class NmciCovarianceIntersection(MixtureReducer):
    r"""Covariance intersection of ``N`` Gaussian states, usable where Stone Soup's
    ``CovarianceIntersection`` is: :math:`C^{-1} = \sum_i ω_i C_i^{-1}`,
    :math:`x = C \sum_i ω_i C_i^{-1} x_i`, with ``ω`` on the simplex.

    Stone Soup's reducer takes equal weights unless given; this one takes the weights that
    minimise the criterion (nmci's N-way CI, ``rule="ci"``), or one weight vector per independent
    block of the states (N-way nmCI, ``rule="nmci"`` with ``blocks``). Given ``weights`` are used
    as given (normalised to sum 1), as Stone Soup does. The result carries a
    :class:`~nmci.stonesoup.FusionInfo` as ``.fusion`` (``omega``: the weights, per block for
    nmCI, flattened block after block).
    """

    rule: str = Property(default="ci", doc="``ci`` or ``nmci``.")
    criterion: Optional[str] = Property(default=None, doc="``trace`` (default) or ``logdet``.")
    blocks: Optional[list] = Property(
        default=None, doc="A partition of the states into blocks with independent errors (nmCI).")
    coupling_tol: Optional[float] = Property(
        default=None, doc="Couplings between blocks absorbed up to this relative size (nmCI).")

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if self.rule not in ("ci", "nmci"):
            raise RequestError(f"`rule` must be ci or nmci for N-way fusion (got {self.rule!r})", "rule")

    def merge_components(self, *components, weights=None):
        """The fused state of ``components`` (Gaussian states of one size)."""
        if not components:
            raise RequestError("no components to merge", "components")
        estimates = [(np.ravel(c.state_vector), np.asarray(c.covar, dtype=float)) for c in components]
        if weights is not None:
            w = np.asarray(weights, dtype=float)
            if w.shape != (len(components),) or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
                raise RequestError(
                    f"`weights` must be {len(components)} non-negative numbers with a positive sum (got {weights!r})",
                    "weights")
            w = w / w.sum()
            infos = [wi * np.linalg.inv(P) for wi, (_, P) in zip(w, estimates)]
            C = np.linalg.inv(sum(infos))
            x = C @ sum(I @ xi for I, (xi, _) in zip(infos, estimates))
            info = FusionInfo("ci", tuple(float(v) for v in w), None,
                              "conservative: CI at fixed weights bounds the error for every cross-covariance")
        else:
            if self.rule == "ci":
                f = nmci.ci_nway(estimates, criterion=self.criterion)
            else:
                f = nmci.nmci_nway(estimates, criterion=self.criterion, blocks=self.blocks,
                                   coupling_tol=self.coupling_tol)
            x, C = np.asarray(f.x), np.asarray(f.P)
            weights_ = np.ravel(f["weights"]) if "weights" in f else None
            blocks = f["blocks"] if "blocks" in f else None
            info = FusionInfo(
                self.rule,
                None if weights_ is None else tuple(float(v) for v in weights_),
                None if blocks is None else tuple(tuple(b) for b in blocks),
                f.guarantee)
        merged = GaussianState.from_state(components[0], state_vector=np.reshape(x, (-1, 1)), covar=C)
        merged.fusion = info
        return merged
