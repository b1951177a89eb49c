"""Program segments 46-48 of the acquisition method, literally: fans of straight lines in beam number.

``rateest`` (segments 62-70): each anchor beam's fan holds the lines ``fbeam = a * iscan + anchor``
(``a`` in beams per update, ``iscan`` counted back from the latest update); each line is followed
until it leaves the BTR, its mean over the scans used is kept if it spans at least ``minscan``
scans, and the line with the strictly largest mean wins. :func:`best_lines_in_fans` evaluates all
lines of all fans at once. The rules shared with the constant-bearing-rate fans
(:mod:`fusion.passive.acquisition.traces`) are :func:`check_fan_inputs` and :func:`best_in_fans`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["FanSearch", "best_in_fans", "best_lines_in_fans", "check_fan_inputs", "slope_grid"]


def slope_grid(min_slope: float, max_slope: float, step: float) -> NDArray[np.float64]:
    """Candidate slopes ``min_slope, min_slope + step, ... <= max_slope`` (beams per update)."""
    if not (np.isfinite(min_slope) and np.isfinite(max_slope) and np.isfinite(step)):
        raise ValueError("slope grid bounds and step must be finite")
    if step <= 0 or max_slope < min_slope:
        raise ValueError(
            f"need step > 0 and max_slope >= min_slope, got {min_slope}, {max_slope}, {step}"
        )
    n = int(math.floor((max_slope - min_slope) / step + 1e-9)) + 1
    return min_slope + step * np.arange(n)


@dataclass(frozen=True)
class _LineTensors:
    """Index tensors of every line of a fan, independent of the anchor beam.

    ``flat`` indexes a BTR padded with ``pad`` zero columns on each side and flattened, so a line
    anchored at beam ``b`` reads ``btr_pad.ravel()[b + flat]``. ``n_used[s, b]`` is the number of
    scans line ``s`` anchored at beam ``b`` spans before its first step off the BTR.
    """

    flat: NDArray[np.int64]  # (n_slopes, n_scans)
    n_used: NDArray[np.int64]  # (n_slopes, n_beams)
    pad: int


@lru_cache(maxsize=64)
def _line_tensors(n_scans: int, n_beams: int, slopes_bytes: bytes) -> _LineTensors:
    a = np.frombuffer(slopes_bytes, dtype=np.float64)
    k = np.arange(n_scans)
    off = np.floor(a[:, None] * k[None, :] + 0.5).astype(np.int64)  # round(a * iscan)
    # A line is cut at its first step off the BTR, so n_beams of padding suffice: the offsets
    # of the scans a line uses are below pad in magnitude; those of later scans are clipped to
    # +-pad so that every anchor b in [0, n_beams - 1] reads inside its own padded row
    # (b + pad + off in [0, n_beams - 1 + 2 pad]).
    pad = int(min(np.abs(off).max(), n_beams)) + 1
    width = n_beams + 2 * pad
    flat = k[None, :] * width + pad + np.clip(off, -pad, pad)
    lo = np.minimum.accumulate(off, axis=1)[:, :, None]  # running extremes along the line
    hi = np.maximum.accumulate(off, axis=1)[:, :, None]
    b = np.arange(n_beams)[None, None, :]
    n_used = ((b + lo >= 0) & (b + hi <= n_beams - 1)).sum(axis=1)  # (n_slopes, n_beams)
    for arr in (flat, n_used):
        arr.setflags(write=False)
    return _LineTensors(flat=flat, n_used=n_used, pad=pad)


@dataclass(frozen=True)
class FanSearch:
    """Best line of each fan.

    Attributes
    ----------
    anchors : ndarray of int, shape (n_fans,)
        Anchor beam of each fan (the beam the lines pass through at the latest update).
    slope : ndarray, shape (n_fans,)
        Slope of the best line, beams per update *going back in time* (the method's ``a``;
        0 when no line qualified).
    signal_plus_noise : ndarray, shape (n_fans,)
        Mean BTR value along the best line (0 when no line qualified).
    n_used : ndarray of int, shape (n_fans,)
        Scans the best line spans before leaving the BTR (0 when no line qualified).
    found : ndarray of bool, shape (n_fans,)
        Whether any line of the fan met the minimum-scan rule with a positive mean.
    """

    anchors: NDArray[np.int64]
    slope: NDArray[np.float64]
    signal_plus_noise: NDArray[np.float64]
    n_used: NDArray[np.int64]
    found: NDArray[np.bool_]


def check_fan_inputs(
    btr_latest_first: ArrayLike, anchors: ArrayLike, min_scans: int
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Checked BTR (scans latest first, beams) and anchor beams of a fan search."""
    btr = np.asarray(btr_latest_first, dtype=float)
    if btr.ndim != 2:
        raise ValueError(f"btr must be 2-D (scans, beams), got shape {btr.shape}")
    n_scans, n_beams = btr.shape
    anc = np.asarray(anchors, dtype=np.int64).reshape(-1)
    if int(min_scans) != min_scans or not 1 <= min_scans <= n_scans:
        raise ValueError(f"min_scans must be an integer in [1, {n_scans}], got {min_scans!r}")
    if anc.size and (anc.min() < 0 or anc.max() >= n_beams):
        raise ValueError(f"anchor beams must lie in [0, {n_beams - 1}]")
    return btr, anc


def best_in_fans(
    means: NDArray[np.float64],
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_]]:
    """Best candidate of each fan (rows): index, mean, and whether it beat the method's start 0.

    ``argmax`` takes the first maximum, the method's strict ">" in candidate order; the method's
    running maximum starts at 0, so a fan whose best mean is not positive found nothing.
    """
    best = np.argmax(means, axis=1)
    best_mean = means[np.arange(means.shape[0]), best]
    return best, best_mean, best_mean > 0.0


def best_lines_in_fans(
    btr_latest_first: ArrayLike,
    anchors: ArrayLike,
    slopes: ArrayLike,
    *,
    min_scans: int,
) -> FanSearch:
    """Search each anchor beam's fan of lines for the one with the largest mean BTR value.

    Parameters
    ----------
    btr_latest_first : array_like, shape (n_scans, n_beams)
        IBW BTR with row 0 the latest update (the method's ``btr[iscan][ibeam]``).
    anchors : array_like of int, shape (n_fans,)
        Anchor beams.
    slopes : array_like, shape (n_slopes,)
        Candidate slopes ``a``, beams per update, increasing (line ``fbeam = a * iscan + anchor``).
    min_scans : int
        Minimum number of scans a line must span before it leaves the BTR to be considered (the
        method's ``minscan``; ``n_scans`` means lines that leave the BTR are never used).

    Returns
    -------
    FanSearch

    Notes
    -----
    The ``rateest`` function of the method (segments 62-70): each line is followed from the
    latest update backwards, ``ibeam = round(a * iscan + anchor)``, until it leaves the BTR; its
    mean over the scans used is kept if it spans at least ``minscan`` scans, and the line with the
    strictly largest mean wins (the first such line on ties, slopes in increasing order). Rounding
    is ``floor(x + 0.5)``: the text's ``(int)(x + 0.5)`` truncates toward zero, which would take
    positions down to -1.5 as beam 0. All lines of all fans are evaluated at once: the rounded
    offsets of the lines and where they leave the BTR depend only on the slopes and the BTR's
    shape, and are cached.
    """
    sl = np.asarray(slopes, dtype=float).reshape(-1)
    if sl.size == 0:
        raise ValueError("no candidate slopes")
    btr, anc = check_fan_inputs(btr_latest_first, anchors, min_scans)
    n_scans, n_beams = btr.shape
    lt = _line_tensors(n_scans, n_beams, np.ascontiguousarray(sl).tobytes())
    # scans each line spans before its first step off the BTR (the method's break)
    n_used = lt.n_used[:, anc].T  # (fans, slopes)
    padded = np.zeros((n_scans, n_beams + 2 * lt.pad))
    padded[:, lt.pad:lt.pad + n_beams] = btr
    # gather only the lines that meet the minimum-scan rule
    fan_i, slope_i = np.nonzero(n_used >= min_scans)
    vals = padded.ravel()[anc[fan_i, None] + lt.flat[slope_i]]  # (n_lines, n_scans)
    used = n_used[fan_i, slope_i]
    csum = np.cumsum(vals, axis=-1)
    means = np.full(n_used.shape, -np.inf)
    means[fan_i, slope_i] = csum[np.arange(used.size), used - 1] / used
    best, best_mean, found = best_in_fans(means)
    rows = np.arange(anc.size)
    return FanSearch(
        anchors=anc,
        slope=np.where(found, sl[best], 0.0),
        signal_plus_noise=np.where(found, best_mean, 0.0),
        n_used=np.where(found, n_used[rows, best], 0).astype(np.int64),
        found=found,
    )
