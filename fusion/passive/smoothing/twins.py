"""Twin tracks: two tracks that follow one source side by side, found and joined.

A camera that boxes one boat several times a fraction of a degree to a degree apart (bow, stern,
wake), beyond what same-scan merging joins, makes the tracker run two tracks along the one boat.
They look like a crossing that never ends, and each has only part of the boat's detections.
:func:`twin_groups` finds tracks that stay within a small bearing distance of each other over most
of their common time and groups them (transitively); the caller smooths each group's detections
as one track.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import wrap_angle
from fusion.passive.smoothing.types import SmoothedTrack

__all__ = ["twin_groups"]


def twin_groups(
    tracks: tuple[SmoothedTrack, ...], *, within: float, min_overlap: float = 0.5,
) -> list[list[int]]:
    """Groups of tracks (indices into `tracks`) that are twins of one another.

    Parameters
    ----------
    tracks : tuple of SmoothedTrack
        Smoothed tracks (bearings in rad).
    within : float, keyword-only
        Largest median bearing distance over the common time of two twins, rad.
    min_overlap : float, keyword-only
        Smallest common time of two twins, as a fraction of the shorter track's span.

    Returns
    -------
    list of list of int
        Every track in exactly one group, groups in order of their first track; a lone track is
        a group of one.

    Notes
    -----
    Two tracks are twins when their common time is at least `min_overlap` of the shorter span
    and the median of ``|wrap(theta_a(t) - theta_b(t))|`` over the states of the shorter one in
    the common time is at most `within`. Two tracks that cross meet only for a moment, so their
    median distance is large; twins stay close. Groups are the connected components of the twin
    relation.
    """
    n = len(tracks)
    parent = list(range(n))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a in range(n):
        ta = tracks[a]
        for b in range(a + 1, n):
            tb = tracks[b]
            lo, hi = max(ta.times[0], tb.times[0]), min(ta.times[-1], tb.times[-1])
            short = min(np.ptp(ta.times), np.ptp(tb.times))
            if hi <= lo or hi - lo < min_overlap * short:
                continue
            s, o = (ta, tb) if np.ptp(ta.times) <= np.ptp(tb.times) else (tb, ta)
            m = (s.times >= lo) & (s.times <= hi)
            if m.sum() < 2:
                continue
            theta_o = _interp_angle(s.times[m], o.times, o.bearing)
            if np.median(np.abs(wrap_angle(s.bearing[m] - theta_o))) <= within:
                parent[find(b)] = find(a)
    roots = [find(a) for a in range(n)]
    groups: dict[int, list[int]] = {}
    for a, r in enumerate(roots):
        groups.setdefault(r, []).append(a)
    return sorted(groups.values(), key=lambda g: g[0])


def _interp_angle(t: NDArray[np.float64], tt: NDArray[np.float64],
                  theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles `theta` at times `tt` interpolated to `t` on the circle, rad."""
    return np.angle(np.interp(t, tt, np.cos(theta)) + 1j * np.interp(t, tt, np.sin(theta)))
