"""Simultaneous bearings of one track merged into one (two sensors reporting a track at once).

The crossing detector takes one bearing per track per time. When several sensors report one
track at the same time, :func:`merge_simultaneous` replaces those rows by their weighted
circular mean: weights ``1 / sigma^2`` from a ``sigma_bearing_deg`` column when the table has
one, equal weights otherwise.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["merge_simultaneous"]


def merge_simultaneous(
    columns: Mapping[str, Any],
) -> tuple[dict[str, NDArray], int]:
    """Rows of one track at one time replaced by their weighted circular mean.

    Parameters
    ----------
    columns : mapping
        ``track_id`` (int), ``time`` (s), ``bearing_deg`` (deg) and optionally
        ``sigma_bearing_deg`` (deg, > 0), shape (m,) each. Rows of track -1 (unknown origin)
        are kept as they are.

    Returns
    -------
    columns : dict
        ``track_id``, ``time``, ``bearing_deg`` (and ``sigma_bearing_deg`` when given: the
        merged bearing's sigma, ``(sum 1/sigma^2)^-1/2``), rows sorted by time then track
        (stable).
    n_merged : int
        Rows removed by merging (0: the table had no simultaneous rows).

    Notes
    -----
    The mean is that of unit vectors, ``atan2(sum w sin B, sum w cos B)``, so bearings either
    side of north average to north. With sigmas the weights are inverse variances (the
    maximum-likelihood combination of independent Gaussian bearings).

    Examples
    --------
    >>> cols, n = merge_simultaneous({"track_id": [1, 1, 2], "time": [0.0, 0.0, 0.0],
    ...                               "bearing_deg": [359.0, 1.0, 90.0]})
    >>> n, [round(float(b) % 360, 6) for b in cols["bearing_deg"]]
    (1, [0.0, 90.0])
    """
    tid = np.asarray(columns["track_id"], dtype=np.int64)
    t = np.asarray(columns["time"], dtype=float)
    b = np.asarray(columns["bearing_deg"], dtype=float)
    has_sigma = "sigma_bearing_deg" in columns
    sig = np.asarray(columns["sigma_bearing_deg"], dtype=float) if has_sigma else np.ones(t.size)
    if has_sigma and not np.all(np.isfinite(sig) & (sig > 0)):
        raise ValueError("column 'sigma_bearing_deg' must be finite and > 0")
    # group key of known tracks: (track, time); unknown rows each their own group
    order = np.lexsort((np.arange(t.size), tid, t))
    tk, tt = tid[order], t[order]
    start = np.ones(t.size, bool)
    start[1:] = (tk[1:] != tk[:-1]) | (tt[1:] != tt[:-1]) | (tk[1:] < 0)
    group = np.cumsum(start) - 1
    n_groups = int(group[-1]) + 1 if t.size else 0
    w = 1.0 / sig[order] ** 2
    rad = np.radians(b[order])
    sx = np.bincount(group, weights=w * np.sin(rad), minlength=n_groups)
    cx = np.bincount(group, weights=w * np.cos(rad), minlength=n_groups)
    sw = np.bincount(group, weights=w, minlength=n_groups)
    first = np.flatnonzero(start)
    mean = np.mod(np.degrees(np.arctan2(sx, cx)), 360.0)
    single = np.bincount(group, minlength=n_groups) == 1
    mean = np.where(single, b[order][first], mean)  # untouched rows keep their value exactly
    out: dict[str, NDArray] = {"track_id": tk[first], "time": tt[first], "bearing_deg": mean}
    if has_sigma:
        out["sigma_bearing_deg"] = np.where(single, sig[order][first], 1.0 / np.sqrt(sw))
    return out, int(t.size - n_groups)
