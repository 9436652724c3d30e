"""Track-to-track fusion of a pair or a set of tracks at their common times: :func:`fuse_tracks`."""

from typing import Optional, Sequence

from stonesoup.types.track import Track

from nmci._errors import RequestError

from .mixturereducer import NmciCovarianceIntersection


def fuse_tracks(tracks: Sequence[Track], reducer: Optional[NmciCovarianceIntersection] = None) -> Track:
    """One track: at every time all ``tracks`` have a state, their states fused by ``reducer``
    (default: N-way CI with optimal weights). Times that not every track has are left out; the
    states are taken as given (no prediction to a common time). Each fused state carries its
    ``.fusion``."""
    if len(tracks) < 2:
        raise RequestError(f"fuse_tracks needs two tracks or more (got {len(tracks)})", "tracks")
    reducer = reducer or NmciCovarianceIntersection()
    by_time = [{state.timestamp: state for state in track} for track in tracks]
    common = sorted(set(by_time[0]).intersection(*by_time[1:]))
    return Track([reducer.merge_components(*(states[t] for states in by_time)) for t in common])
