"""A pytest plugin that puts nmci's Stone Soup components where Stone Soup's own tests import
theirs, so those test files run unmodified against nmci (python/tests/test_stonesoup_upstream.py
loads it with ``-p``).

- ``stonesoup.updater.chernoff.ChernoffUpdater`` becomes :class:`nmci.stonesoup.NmciUpdater`
  (its arguments are in ``ChernoffUpdater``'s order);
- ``stonesoup.mixturereducer.gaussianmixture.CovarianceIntersection`` becomes nmci's reducer at
  Stone Soup's fixed equal weights (``weighting="equal"``), called on the class as Stone Soup's
  tests call theirs.
"""

import stonesoup.mixturereducer.gaussianmixture as gaussianmixture
import stonesoup.updater.chernoff as chernoff
from stonesoup.base import Property

from nmci.stonesoup import NmciCovarianceIntersection, NmciUpdater


class EqualWeightsCovarianceIntersection(NmciCovarianceIntersection):
    """nmci's reducer at Stone Soup's default: equal weights."""

    weighting: str = Property(default="equal", doc="Stone Soup's default.")


def pytest_configure(config):
    chernoff.ChernoffUpdater = NmciUpdater
    gaussianmixture.CovarianceIntersection = EqualWeightsCovarianceIntersection
