"""Short chains linked to a later track instead of being dropped (issue 18, late starts).

A close-range target whose bearing rate changes fast (closest approach) breaks the
initial tracker's track into short pieces before a crossing: each piece, and the chain the
constant-rate links make of them, has fewer than ``min_length`` detections and is dropped,
and the target is followed only from a segment after the crossing ("late start" in
:func:`fusion.metrics.crossings.crossing_failure_causes`). :func:`link_short_chains` offers
the last end of every chain about to be dropped one more assignment to the first starts of
later chains that have no predecessor, with the white-noise bearing acceleration of the link
covariance raised from `q` to `q_link` (rad^2/s^3): a rate that changed nonlinearly across the
gap (a constant-acceleration allowance is too rigid: bearing and rate offsets of closest
approach do not share one acceleration). Only ends of
chains that would be dropped and starts of chains that begin a track take part: the links of
:func:`~fusion.passive.smoothing.linking.link_segments` are kept.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fusion.passive.smoothing.linking import _assign, _link_distances

__all__ = ["link_short_chains"]


def link_short_chains(chains: list[list[int]], sizes: NDArray[np.int64], ends: list[tuple],
                      scan_times: NDArray[np.float64], *, q: float, min_length: int,
                      gate: float, q_link: float, max_gap_scans: int) -> list[list[int]]:
    """Chains with the short ones linked forward where one more assignment allows it.

    Parameters
    ----------
    chains : list of list of int
        Segment indices per chain, in time order (:func:`~fusion.passive.smoothing.linking.
        link_segments`).
    sizes : ndarray of int
        Detections per segment.
    ends : list of tuple
        Segment ends (``(s0, x0, P0, s1, x1, P1)``).
    q : float
        White-noise bearing acceleration PSD, rad^2/s^3.
    min_length : int
        Chains with fewer detections would be dropped: only their last ends take part.
    gate : float
        Gate on the squared Mahalanobis distance of a link (2 degrees of freedom).
    q_link : float
        White-noise bearing acceleration PSD of these links, rad^2/s^3 (not above `q`: no
        pass, `chains` returned).
    max_gap_scans : int
        Longest gap, in scan periods.
    """
    if q_link <= q or len(chains) < 2:
        return chains
    period = float(np.median(np.diff(scan_times))) if scan_times.size > 1 else 1.0
    total = np.array([int(sizes[ch].sum()) for ch in chains])
    tail = np.array([ch[-1] for ch in chains])
    head = np.array([ch[0] for ch in chains])
    short = np.flatnonzero(total < min_length)
    if short.size == 0:
        return chains
    t_end = scan_times[[int(ends[p][3]) for p in tail]]
    t_start = scan_times[[int(ends[p][0]) for p in head]]
    dt = t_start[None, :] - t_end[short][:, None]
    ok = (dt > 0) & (dt <= max_gap_scans * period)
    ok[np.arange(short.size), short] = False
    ri, ci = np.nonzero(ok)
    cost = np.full(ok.shape, np.inf)
    if ri.size:
        n = len(ends)
        d2, lndet = _link_distances(ends, tail[short[ri]], head[ci], dt[ri, ci], q_link,
                                    np.zeros(n), np.zeros(n))
        inside = d2 <= gate
        cost[ri[inside], ci[inside]] = d2[inside] + lndet[inside]
    nxt = {int(short[r]): c for r, c in _assign(cost).items()}
    if not nxt:
        return chains
    # follow the new links (a short chain may now lead into another short chain)
    has_prev = set(nxt.values())
    out = []
    for c in range(len(chains)):
        if c in has_prev:
            continue
        merged, k, seen = list(chains[c]), c, {c}
        while k in nxt and nxt[k] not in seen:
            k = nxt[k]
            seen.add(k)
            merged.extend(chains[k])
        out.append(merged)
    return out
