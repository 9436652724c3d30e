"""nmci in Stone Soup: fuse tracks with the exactly optimal CI, nmCI or any other rule of nmci.

Install the built wheel with its extra, ``pip install "<the wheel's path>[stonesoup]"`` (README). The package is registered under Stone Soup's plugin
entry point, so ``from stonesoup.plugins.nmci import NmciUpdater`` works too, and under its YAML
entry point, so a saved configuration holding these components loads back.

- :class:`NmciUpdater` — a drop-in for ``ChernoffUpdater(None)`` (track-to-track fusion of a
  :class:`~stonesoup.types.detection.GaussianDetection` with a prediction), with the fusion rule
  chosen from nmci's registry and ``ω`` optimal instead of fixed (or fixed, to reproduce
  ``ChernoffUpdater``);
- :class:`NmciCovarianceIntersection` — N-way fusion of Gaussian states with optimal simplex
  weights, usable where Stone Soup's ``CovarianceIntersection`` mixture reducer is;
- :func:`fuse_tracks` — fuses a pair or a set of tracks at their common times;
- :func:`blocks_from_transition_model` — the state blocks of a
  ``CombinedLinearGaussianTransitionModel`` (a modelling claim: see its docs);
- :func:`chernoff_log_normaliser` and :func:`innovation_covariance` — the normaliser of the
  Chernoff product of two Gaussians and the innovation covariance derived from it;
- :class:`FusionInfo` — what a fusion reports, the declared Property ``fusion`` of the types
  :func:`with_fusion` extends (:mod:`nmci.stonesoup.types`);
- :func:`fixed_omega_ci` — CI at a fixed weight in its pseudo-inverse form (semi-definite
  covariances), and :func:`merge_coupled_blocks` — declared blocks merged where the data couple
  them.

The three-line switch from Stone Soup's fixed-ω fusion::

    from nmci.stonesoup import NmciUpdater, blocks_from_transition_model
    blocks = blocks_from_transition_model(transition_model)   # x and y axes: independent
    track_updater = NmciUpdater(measurement_model=None, rule="nmci", blocks=blocks)
"""

from .fuser import fuse_tracks
from .mixturereducer import NmciCovarianceIntersection
from .models import blocks_from_transition_model
from .types import FusionInfo, FusionRecord, with_fusion
from .updater import (
    NmciUpdater,
    chernoff_log_normaliser,
    fixed_omega_ci,
    innovation_covariance,
    merge_coupled_blocks,
)
from .serialise import yaml_init

__all__ = [
    "FusionInfo",
    "FusionRecord",
    "NmciCovarianceIntersection",
    "NmciUpdater",
    "blocks_from_transition_model",
    "chernoff_log_normaliser",
    "fixed_omega_ci",
    "fuse_tracks",
    "innovation_covariance",
    "merge_coupled_blocks",
    "with_fusion",
    "yaml_init",
]
