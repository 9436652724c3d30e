"""N-way fusion of Gaussian states with optimal weights: :class:`NmciCovarianceIntersection`."""

import functools
from typing import Optional

import numpy as np
from scipy.linalg import pinv
from stonesoup.base import Property
from stonesoup.mixturereducer.base import MixtureReducer
from stonesoup.types.state import GaussianState

import nmci
from nmci._errors import InputError, RequestError

from .types import FusionInfo, with_fusion


class _class_or_instance:
    """A method that works on the class as on an instance: called on the class it runs on an
    instance with every property at its default (Stone Soup calls
    ``CovarianceIntersection.merge_components`` on the class)."""

    def __init__(self, method):
        self.method = method
        functools.update_wrapper(self, method)

    def __get__(self, instance, owner):
        return functools.partial(self.method, owner() if instance is None else instance)


class NmciCovarianceIntersection(MixtureReducer):
    r"""Covariance intersection of ``N`` Gaussian states, usable where Stone Soup's
    ``CovarianceIntersection`` is: :math:`C^{-1} = \sum_i ω_i C_i^{-1}`,
    :math:`x = C \sum_i ω_i C_i^{-1} x_i`, with ``ω`` on the simplex.

    Stone Soup's reducer takes equal weights unless given; this one takes by default the weights
    that minimise the criterion (nmci's N-way CI, ``rule="ci"``), or one weight vector per
    independent block of the states (N-way nmCI, ``rule="nmci"`` with ``blocks``);
    ``weighting="equal"`` gives Stone Soup's equal weights. Where the criterion is flat (equal
    covariances) the optimal weights are the middle of the optimal set, so equal covariances give
    the average of the means. Given ``weights`` are used as given (normalised to sum 1) in Stone
    Soup's pseudo-inverse form, conservative whenever :math:`\sum_i ω_i C_i^+` is invertible
    (the argument of :mod:`nmci.stonesoup.updater`, "Degenerate covariances"). The result carries a
    :class:`~nmci.stonesoup.FusionInfo` as ``.fusion`` (``omega``: the weights, per block for nmCI,
    flattened block after block).

    References
    ----------
    .. [1] Niehsen, W., "Information fusion based on fast covariance intersection filtering",
       Proc. FUSION 2002.
    """

    rule: str = Property(default="ci", doc="``ci`` or ``nmci``.")
    weighting: str = Property(
        default="optimal", doc="``optimal`` (the criterion's minimiser) or ``equal`` (Stone Soup's default).")
    criterion: Optional[str] = Property(default=None, doc="``trace`` (default) or ``logdet``.")
    blocks: Optional[list] = Property(
        default=None, doc="A partition of the states into blocks with independent errors (nmCI).")
    coupling_tol: Optional[float] = Property(
        default=None, doc="Couplings between blocks absorbed up to this relative size (nmCI).")

    @rule.setter
    def rule(self, value):
        if value not in ("ci", "nmci"):
            raise RequestError(f"`rule` must be ci or nmci for N-way fusion (got {value!r})", "rule")
        self._property_rule = value

    @weighting.setter
    def weighting(self, value):
        if value not in ("optimal", "equal"):
            raise RequestError(f"`weighting` must be optimal or equal (got {value!r})", "weighting")
        self._property_weighting = value

    @_class_or_instance
    def merge_components(self, *components, weights=None):
        """The fused state of ``components``.

        Parameters
        ----------
        *components : :class:`~stonesoup.types.state.GaussianState`
            Gaussian states of one size; a single one is passed through.
        weights : sequence of float, optional
            Fixed weights (normalised to sum 1); default: ``weighting``'s.

        Returns
        -------
        :class:`~stonesoup.types.state.GaussianState`
            The merged state, of the first component's kind extended by the declared Property
            ``fusion`` (:func:`~nmci.stonesoup.types.with_fusion`).
        """
        if not components:
            raise RequestError("no components to merge", "components")
        if len(components) == 1 and weights is None:
            return components[0]
        estimates = [(np.ravel(c.state_vector), np.asarray(c.covar, dtype=float)) for c in components]
        if weights is None and self.weighting == "equal":
            weights = np.ones(len(components))
        if weights is not None:
            w = np.asarray(weights, dtype=float)
            if w.shape != (len(components),) or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
                raise RequestError(
                    f"`weights` must be {len(components)} non-negative numbers with a positive sum (got {weights!r})",
                    "weights")
            w = w / sum(w)
            # Stone Soup's own arithmetic, step for step (its tests compare to the bit).
            infos = [wi * pinv(P) for wi, (_, P) in zip(w, estimates)]
            total = sum(infos)
            if np.linalg.matrix_rank(total) < total.shape[0]:
                raise InputError("the weighted states carry no information in some direction "
                                 "(the sum of ω_i C_i⁺ is singular): no bound exists there", "components")
            C = pinv(total)
            x = C @ sum(I @ np.reshape(xi, (-1, 1)) for I, (xi, _) in zip(infos, estimates))
            info = FusionInfo("ci", tuple(float(v) for v in w), None,
                              "conservative: CI at fixed weights bounds the error for every cross-covariance")
        else:
            if self.rule == "ci":
                f = nmci.ci_nway(estimates, criterion=self.criterion)
            else:
                f = nmci.nmci_nway(estimates, criterion=self.criterion, blocks=self.blocks,
                                   coupling_tol=self.coupling_tol)
            x, C = np.reshape(np.asarray(f.x), (-1, 1)), np.asarray(f.P)
            weights_ = np.ravel(f["weights"]) if "weights" in f else None
            blocks = f["blocks"] if "blocks" in f else None
            info = FusionInfo(
                self.rule,
                None if weights_ is None else tuple(float(v) for v in weights_),
                None if blocks is None else tuple(tuple(b) for b in blocks),
                f.guarantee)
        return GaussianState.from_state(components[0], state_vector=x, covar=C, fusion=info,
                                        target_type=with_fusion(type(components[0])))
