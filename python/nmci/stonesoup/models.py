"""State blocks from a Stone Soup transition model: :func:`blocks_from_transition_model`."""

from typing import List

from stonesoup.models.transition.base import CombinedGaussianTransitionModel


def blocks_from_transition_model(model) -> List[List[int]]:
    """The states of each model of a ``CombinedLinearGaussianTransitionModel`` (or any
    ``CombinedGaussianTransitionModel``), in order: ``[[0, 1], [2, 3]]`` for two constant-velocity
    axes; one block for any other model.

    Declaring these blocks (``blocks=`` of :class:`NmciUpdater`) is a modelling claim: that the
    errors of different blocks are independent, in each estimate and between the two. It holds
    when the axes evolve independently, their process noises are independent and every sensor
    measures each block separately with independent noise (e.g. position sensors with
    axis-aligned noise). It does not hold for a range-bearing radar, whose converted noise couples
    the axes, nor after any step that mixes blocks. nmci checks the estimates against the claim
    (entries between blocks beyond ``coupling_tol`` are refused), not the cross-covariance, which
    nobody knows; where the data violate it, :class:`NmciUpdater` merges the coupled blocks
    (``on_violation``).

    Parameters
    ----------
    model : :class:`~stonesoup.models.transition.base.TransitionModel`
        The transition model of the tracks.

    Returns
    -------
    list of list of int
        The states of each component model, in order.
    """
    if isinstance(model, CombinedGaussianTransitionModel):
        blocks, start = [], 0
        for sub in model.model_list:
            blocks.append(list(range(start, start + sub.ndim_state)))
            start += sub.ndim_state
        return blocks
    return [list(range(model.ndim_state))]
