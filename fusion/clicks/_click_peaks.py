"""Peak picking on the click detector's statistic: local maxima with a minimum separation, and
the ringing test (a click near a much stronger one is dropped); steps 40-42 of
:mod:`fusion.clicks.detect`."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["local_maxima", "not_echo", "not_ringing"]


def local_maxima(s: NDArray[np.float32], threshold: float, distance: int) -> NDArray[np.int64]:
    """Indices of local maxima of `s` above `threshold`, the larger kept of any two closer than
    `distance` samples (the few samples above the threshold are tested, not the whole series)."""
    c = np.flatnonzero(s[1:-1] > threshold) + 1
    c = c[(s[c] >= s[c - 1]) & (s[c] > s[c + 1])]
    if c.size < 2 or distance <= 1 or np.min(np.diff(c)) >= distance:
        return c
    keep = np.ones(c.size, dtype=bool)
    for i in np.argsort(-s[c], kind="stable"):  # strongest first
        if keep[i]:
            lo, hi = np.searchsorted(c, [c[i] - distance + 1, c[i] + distance])
            keep[lo:hi] = False
            keep[i] = True
    return c[keep]


def not_ringing(
    times: NDArray[np.float64], power: NDArray[np.float64], window_s: float, ratio: float
) -> NDArray[np.bool_]:
    """Mask of clicks with no other click within `window_s` at least `ratio` times stronger."""
    keep = np.ones(times.size, dtype=bool)
    if times.size < 2 or window_s <= 0:
        return keep
    lo = np.searchsorted(times, times - window_s, side="left")
    hi = np.searchsorted(times, times + window_s, side="right")
    for i in np.flatnonzero(hi - lo > 1):
        keep[i] = power[lo[i]:hi[i]].max() < ratio * power[i]
    return keep


def not_echo(times: NDArray[np.float64], power: NDArray[np.float64], lo_s: float,
             hi_s: float) -> NDArray[np.bool_]:
    """Mask of clicks with no stronger click ``lo_s`` to ``hi_s`` before them (its echo)."""
    keep = np.ones(times.size, dtype=bool)
    if times.size < 2 or hi_s <= 0:
        return keep
    a = np.searchsorted(times, times - hi_s, side="left")
    b = np.searchsorted(times, times - lo_s, side="right")
    for i in np.flatnonzero(b > a):
        keep[i] = power[a[i]:b[i]].max() <= power[i]
    return keep
