"""Stone Soup types carrying nmci's fusion details as a declared Property: :class:`FusionInfo`,
:func:`with_fusion`.

An update by :class:`~nmci.stonesoup.NmciUpdater` (or a merge by
:class:`~nmci.stonesoup.NmciCovarianceIntersection`) is of the kind Stone Soup would build —
``GaussianStateUpdate`` for a ``GaussianStatePrediction``, ``TaggedWeightedGaussianStateUpdate``
for a PHD component, ... — extended by one declared Property, ``fusion``, the last of its
properties (so positional construction is Stone Soup's). The extended class is
``Nmci<Stone Soup's class>``, a subclass of both Stone Soup's class and :class:`FusionRecord`:
``isinstance`` checks, ``from_state`` copies, ``repr`` and pickling treat it as any Stone Soup type.

``PHDUpdater`` (and the other point-process updaters) rebuild each component from the update's
mean and covariance alone, so their components cannot carry it; they keep the hypotheses, and the
updater records the details there too: each hypothesis's ``measurement_prediction`` is of an
extended kind whose ``fusion`` is the update's (``mixture_update.hypothesis[i][j]
.measurement_prediction.fusion``).
"""

from dataclasses import dataclass
from typing import Dict, Optional, Tuple

from stonesoup.base import Base, Property
from stonesoup.types.state import CreatableFromState


@dataclass(frozen=True)
class FusionInfo:
    """What a fusion by nmci reports: the ``fusion`` Property of the types of this module.

    Attributes
    ----------
    rule : str
        The rule that fused (``ci`` for a fixed ``omega``).
    omega : tuple of float or None
        The weight on the measurement of each block (``None`` for rules without one).
    blocks : tuple of tuple of int or None
        The blocks of states the rule used (``None`` when the rule reports none).
    guarantee : str
        The rule's guarantee, as nmci states it (``"conservative"``, ``"relaxation"``, ...).
    merged : tuple of str
        One sentence per pair of declared blocks merged because the data couple them
        (:mod:`nmci.stonesoup.updater`, "Declared blocks the data violate"); empty when the
        declared blocks held.
    """

    rule: str
    omega: Optional[Tuple[float, ...]]
    blocks: Optional[Tuple[Tuple[int, ...], ...]]
    guarantee: str
    merged: Tuple[str, ...] = ()


class FusionRecord(Base):
    """The mark of a Stone Soup type extended by :func:`with_fusion` (the extension declares
    ``fusion``): ``isinstance(update, FusionRecord)`` tells an nmci fusion's result."""


_EXTENDED: Dict[type, type] = {}


def with_fusion(cls: type) -> type:
    """Stone Soup's type ``cls`` with the declared Property ``fusion`` (a :class:`FusionInfo`,
    default ``None``) after its own.

    Parameters
    ----------
    cls : type
        A Stone Soup ``Base`` type (an update, a prediction, a state).

    Returns
    -------
    type
        ``Nmci<cls.__name__>``, a subclass of ``cls`` and :class:`FusionRecord`, created once and
        kept in this module (so a pickle finds it by name).
    """
    if issubclass(cls, FusionRecord):
        return cls
    extended = _EXTENDED.get(cls)
    if extended is None:
        name = f"Nmci{cls.__name__}"
        extended = type(name, (cls, FusionRecord), {
            "__module__": __name__,
            "__qualname__": name,
            "__doc__": f"Stone Soup's :class:`~{cls.__module__}.{cls.__name__}` with nmci's "
                       "fusion details, the declared Property ``fusion``.",
            "__annotations__": {"fusion": FusionInfo},
            "fusion": Property(default=None, doc="What the fusion by nmci reports (:class:`FusionInfo`)."),
        })
        _EXTENDED[cls] = extended
        globals()[name] = extended
    return extended


def target_type(kind: type, state) -> type:
    """The type Stone Soup's ``kind.from_state(state, ...)`` builds (``kind`` ``Update``,
    ``MeasurementPrediction``, ...), extended by :func:`with_fusion`."""
    mapping = CreatableFromState.class_mapping[kind]
    state_type = next(t for t in type(state).mro() if t in mapping)
    return with_fusion(mapping[state_type])


def __getattr__(name: str) -> type:
    # An extended type a pickle names before this process created it.
    if name.startswith("Nmci"):
        wanted = name[len("Nmci"):]
        for mapping in CreatableFromState.class_mapping.values():
            for cls in mapping.values():
                if cls.__name__ == wanted:
                    return with_fusion(cls)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
