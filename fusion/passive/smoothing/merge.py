"""Detections of one scan closer than the sensor resolves, merged into one.

A camera's object detector often boxes one boat several times (bow, stern, wake), which gives
several bearings a fraction of a degree apart in one scan; a tracker then forms parallel twin
tracks that look like a permanent crossing. :func:`merge_scan_detections` replaces every group of
same-scan bearings whose neighbours lie within ``within`` by their circular mean.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import wrap_angle

__all__ = ["merge_scan_detections"]


def merge_scan_detections(
    times: ArrayLike, bearings: ArrayLike, *, within: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Merge same-scan detections closer than `within` (single linkage, around the circle).

    Parameters
    ----------
    times, bearings : array_like, shape (n,)
        Unlabeled detections (:mod:`fusion.passive.smoothing`).
    within : float, keyword-only
        Largest gap between neighbouring bearings of one group, rad (0: nothing merged).

    Returns
    -------
    times : ndarray, shape (m,)
        Times of the merged detections, s, sorted (stable).
    bearings : ndarray, shape (m,)
        Circular means of each group, rad, in [-pi, pi).
    group : ndarray of int, shape (n,)
        Index into the outputs of each input detection.

    Examples
    --------
    >>> t, z, g = merge_scan_detections([0, 0, 0, 1], np.radians([10, 10.4, 30, 10]),
    ...                                 within=np.radians(1.0))
    >>> np.round(np.degrees(z), 1).tolist(), g.tolist()
    ([10.2, 30.0, 10.0], [0, 0, 1, 2])
    """
    t = np.asarray(times, float)
    z = np.asarray(bearings, float)
    if t.shape != z.shape or t.ndim != 1:
        raise ValueError("times and bearings must be 1-D of equal length")
    if not within >= 0:
        raise ValueError(f"within must be >= 0, got {within!r}")
    order = np.lexsort((np.mod(z, 2 * np.pi), t))
    ts, zs = t[order], np.mod(z[order], 2 * np.pi)
    group_sorted = np.zeros(t.size, np.int64)
    out_t: list[float] = []
    out_z: list[float] = []
    starts = np.flatnonzero(np.r_[True, ts[1:] != ts[:-1]])
    stops = np.r_[starts[1:], t.size]
    for a, b in zip(starts, stops, strict=True):
        zz = zs[a:b]
        label = np.zeros(zz.size, np.int64)
        if zz.size > 1:
            gaps = np.diff(zz) > within
            label[1:] = np.cumsum(gaps)
            if 2 * np.pi - (zz[-1] - zz[0]) <= within and label[-1] > 0:  # joins across 0
                label[label == label[-1]] = 0
        for g in np.unique(label):
            m = label == g
            group_sorted[a:b][m] = len(out_t)
            out_t.append(float(ts[a]))
            out_z.append(float(np.angle(np.mean(np.exp(1j * zz[m])))))
    group = np.empty(t.size, np.int64)
    group[order] = group_sorted
    return np.asarray(out_t), np.asarray(wrap_angle(np.asarray(out_z)), float), group
