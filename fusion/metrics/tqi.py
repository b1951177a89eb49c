"""Scores of track quality indicator (TQI) outputs against a known condition history.

:func:`declaration_lag` measures how many updates a TQI took to declare a state (usually
``lost``) after the condition that calls for it began; :func:`state_changes` counts the changes
of state per track (the flicker that hysteresis is there to suppress).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.passive.quality import TrackQuality

__all__ = ["declaration_lag", "state_changes"]


def _states_2d(states: ArrayLike) -> NDArray[np.int64]:
    s = np.asarray(states)
    if s.ndim not in (1, 2) or s.shape[0] == 0:
        raise ValueError(f"states must have shape (n_updates,) or (n_updates, n_tracks), got {s.shape}")
    return (s[:, None] if s.ndim == 1 else s).astype(np.int64)


def declaration_lag(
    states: ArrayLike, onset: ArrayLike, *, state: TrackQuality = TrackQuality.LOST
) -> NDArray[np.float64]:
    """Updates from `onset` until the TQI first reports `state`, per track.

    Parameters
    ----------
    states : array_like of int, shape (n_updates,) or (n_updates, n_tracks)
        TQI state codes per update (:class:`fusion.passive.quality.TrackQuality`; ``-1`` before
        a track starts).
    onset : int or array_like of int, shape (n_tracks,)
        Update index at which the condition began (e.g. the target fell silent).
    state : TrackQuality, optional, keyword-only
        The state whose declaration is timed (default ``LOST``).

    Returns
    -------
    ndarray of float, shape (n_tracks,)
        ``k - onset`` for the first update ``k >= onset`` in `state`; ``inf`` when the TQI never
        reports it (so a later or missing declaration compares as larger).

    Examples
    --------
    >>> s = [3, 3, 2, 1, 0, 0]
    >>> declaration_lag(s, 2).tolist()
    [2.0]
    >>> declaration_lag(s, 2, state=TrackQuality.STRONG).tolist()
    [inf]
    """
    s = _states_2d(states)
    n_updates, n_tracks = s.shape
    k0 = np.broadcast_to(np.asarray(onset), (n_tracks,)).astype(np.int64)
    if np.any((k0 < 0) | (k0 >= n_updates)):
        raise ValueError(f"onset must lie in [0, {n_updates}), got {np.asarray(onset).tolist()!r}")
    hit = (s == int(state)) & (np.arange(n_updates)[:, None] >= k0[None, :])
    first = np.argmax(hit, axis=0)
    return np.where(hit.any(axis=0), first - k0, np.inf).astype(float)


def state_changes(states: ArrayLike) -> NDArray[np.int64]:
    """Changes of TQI state per track, not counting the start of a track.

    Parameters
    ----------
    states : array_like of int, shape (n_updates,) or (n_updates, n_tracks)
        TQI state codes per update (``-1`` before a track starts).

    Returns
    -------
    ndarray of int, shape (n_tracks,)

    Examples
    --------
    >>> state_changes([-1, 3, 3, 2, 3, 3]).tolist()
    [2]
    """
    s = _states_2d(states)
    return np.sum((s[1:] != s[:-1]) & (s[:-1] >= 0), axis=0)
