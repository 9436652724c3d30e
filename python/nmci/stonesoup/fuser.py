"""Track-to-track fusion of a pair or a set of tracks: :func:`fuse_tracks`."""

import warnings
from typing import Optional, Sequence

from stonesoup.types.track import Track

from nmci._errors import RequestError

from .mixturereducer import NmciCovarianceIntersection


def fuse_tracks(tracks: Sequence[Track], reducer: Optional[NmciCovarianceIntersection] = None,
                predictor=None) -> Track:
    """One track fused from ``tracks``.

    Parameters
    ----------
    tracks : sequence of :class:`~stonesoup.types.track.Track`
        Two tracks or more.
    reducer : :class:`NmciCovarianceIntersection`, optional
        How the states of one time are fused (default: N-way CI with optimal weights).
    predictor : :class:`~stonesoup.predictor.base.Predictor`, optional
        Without one, the states are fused at the times every track has, as given. With one,
        at every time of any track from the first time every track has a state on: each track's
        latest state at or before that time, predicted to it.

    Returns
    -------
    :class:`~stonesoup.types.track.Track`
        The fused states, each with its ``.fusion``. A ``UserWarning`` says how many times were
        left out (times not every track has, without a predictor; times before every track has
        begun, with one).
    """
    if len(tracks) < 2:
        raise RequestError(f"fuse_tracks needs two tracks or more (got {len(tracks)})", "tracks")
    reducer = reducer or NmciCovarianceIntersection()
    by_time = [{state.timestamp: state for state in track} for track in tracks]
    every = sorted(set().union(*by_time))
    if predictor is None:
        kept = sorted(set(by_time[0]).intersection(*by_time[1:]))
        fused = [reducer.merge_components(*(states[t] for states in by_time)) for t in kept]
        hint = " (pass predictor= to predict the tracks to each other's times)"
    else:
        begun = max(min(states) for states in by_time)
        kept = [t for t in every if t >= begun]
        fused = []
        for t in kept:
            aligned = []
            for states in by_time:
                last = max(s for s in states if s <= t)
                state = states[last]
                aligned.append(state if last == t else predictor.predict(state, timestamp=t))
            fused.append(reducer.merge_components(*aligned))
        hint = " (before every track has begun)"
    dropped = len(every) - len(kept)
    if dropped:
        warnings.warn(f"fuse_tracks: {dropped} of {len(every)} times left out{hint}", UserWarning, stacklevel=2)
    return Track(fused)
