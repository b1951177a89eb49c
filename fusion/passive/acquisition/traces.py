"""Program segments 46-48 generalised: fans of constant-bearing-rate traces in cosine-spaced beams.

The method's lines are straight in beam number, but the method also assumes beams equally spaced
in cosine (eqs. 5-11), where a target at a constant bearing rate draws a curve
(:func:`constant_rate_traces`). A fan here is the set of such traces through its anchor beam at
the latest update, one per candidate bearing rate, each read at the nearest beam as ``rateest``
reads its lines (:func:`best_traces_in_fans`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.passive.acquisition.lines import best_in_fans, check_fan_inputs

__all__ = ["TraceFanSearch", "best_traces_in_fans", "constant_rate_traces"]


def constant_rate_traces(
    end_beams: ArrayLike,
    rates_rad_s: ArrayLike,
    *,
    n_scans: int,
    n_beams: int,
    scan_period: float,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Fractional beam positions of constant-bearing-rate traces, latest update first.

    Parameters
    ----------
    end_beams : array_like
        Beam of each trace at the latest update (fractional allowed, in ``[0, n_beams - 1]``).
    rates_rad_s : array_like
        Bearing rate of each trace, rad/s, forward in time (positive: toward aft endfire);
        broadcast against `end_beams`.
    n_scans, n_beams : int
        BTR shape.
    scan_period : float
        Time between scans, s.

    Returns
    -------
    positions : ndarray, shape (..., n_scans)
        Fractional beam of the trace ``iscan`` updates before the latest,
        ``beam_from_bearing(theta_end - rate * iscan * scan_period)`` (eq. 5).
    n_used : ndarray of int, shape (...)
        Scans the trace spans before its bearing first leaves ``[0, pi]`` (the trace's step off
        the BTR, the method's ``break``).

    Notes
    -----
    The method's lines ``fbeam = a * iscan + anchor`` are straight in beam number; a target with
    a constant bearing rate moves along ``b(t) = (N - 1) (1 - cos theta(t)) / 2`` in the cosine
    beam spacing the method assumes (eqs. 5-11), a curve whose slope ``db/dt`` is eq. 11. These
    traces are the method's lines with that spacing taken into account: a fan is the set of
    traces through its anchor beam at the latest update, one per candidate bearing rate.
    """
    if int(n_beams) != n_beams or n_beams < 2:
        raise ValueError(f"n_beams must be an integer >= 2, got {n_beams!r}")
    if int(n_scans) != n_scans or n_scans < 1:
        raise ValueError(f"n_scans must be a positive integer, got {n_scans!r}")
    if not np.isfinite(scan_period) or scan_period <= 0:
        raise ValueError(f"scan_period must be positive, got {scan_period!r}")
    end, rate = np.broadcast_arrays(np.asarray(end_beams, dtype=float),
                                    np.asarray(rates_rad_s, dtype=float))
    theta_end = np.arccos(np.clip(1.0 - 2.0 * end / (n_beams - 1), -1.0, 1.0))  # eq. 6
    tau = np.arange(n_scans) * float(scan_period)  # time back from the latest update
    theta = theta_end[..., None] - rate[..., None] * tau
    eps = 1e-12
    inside = (theta >= -eps) & (theta <= math.pi + eps)
    n_used = np.where(inside.all(axis=-1), n_scans, np.argmin(inside, axis=-1)).astype(np.int64)
    positions = (n_beams - 1) * (1.0 - np.cos(theta)) / 2.0  # eq. 5
    return positions, n_used


def _sample_indices(
    positions: NDArray[np.float64], n_used: NDArray[np.int64], n_beams: int, sampling: str
) -> tuple[NDArray[np.int32], NDArray[np.float64] | None]:
    """Flat indices (and linear weights) of trace samples in a BTR flattened with a zero appended.

    Scans at or beyond a trace's ``n_used`` point at the appended zero (weight 0), so a sum over
    all scans is the sum over the scans used.
    """
    n_scans = positions.shape[-1]
    sentinel = n_scans * n_beams
    row = np.arange(n_scans) * n_beams
    used = np.arange(n_scans) < n_used[..., None]
    if sampling == "nearest":
        ibeam = np.clip(np.floor(positions + 0.5), 0, n_beams - 1).astype(np.int64)
        return np.where(used, row + ibeam, sentinel).astype(np.int32), None
    lo = np.clip(np.floor(positions), 0, n_beams - 2).astype(np.int64)
    w = np.where(used, positions - lo, 0.0)
    return np.where(used, row + lo, sentinel).astype(np.int32), w


@dataclass(frozen=True)
class _TraceTensors:
    """Sample indices of one fan's traces (see :func:`_sample_indices`) and their scans used."""

    index: NDArray[np.int32]  # (n_rates, n_scans)
    weight: NDArray[np.float64] | None  # (n_rates, n_scans), linear sampling only
    n_used: NDArray[np.int64]  # (n_rates,)


@lru_cache(maxsize=128)
def _trace_tensors(
    n_scans: int, n_beams: int, anchor: int, rates_bytes: bytes, scan_period: float, sampling: str
) -> _TraceTensors:
    rates = np.frombuffer(rates_bytes, dtype=np.float64)
    pos, n_used = constant_rate_traces(float(anchor), rates, n_scans=n_scans, n_beams=n_beams,
                                       scan_period=scan_period)
    index, weight = _sample_indices(pos, n_used, n_beams, sampling)
    for arr in (index, weight, n_used):
        if arr is not None:
            arr.setflags(write=False)
    return _TraceTensors(index=index, weight=weight, n_used=n_used)


def _sum_along(flat_btr: NDArray[np.float64], index: NDArray[np.int32],
               weight: NDArray[np.float64] | None) -> NDArray[np.float64]:
    lo = flat_btr[index]
    if weight is None:
        return lo.sum(axis=-1)
    hi = flat_btr[np.minimum(index + 1, flat_btr.size - 1)]
    return (lo + weight * (hi - lo)).sum(axis=-1)


@dataclass(frozen=True)
class TraceFanSearch:
    """Best constant-bearing-rate trace of each fan.

    Attributes
    ----------
    anchors : ndarray of int, shape (n_fans,)
        Anchor beam of each fan (the beam its traces pass through at the latest update).
    rate_rad_s : ndarray, shape (n_fans,)
        Bearing rate of the best trace, rad/s forward in time (0 when no trace qualified).
    signal_plus_noise : ndarray, shape (n_fans,)
        Mean BTR value along the best trace (0 when no trace qualified).
    n_used : ndarray of int, shape (n_fans,)
        Scans the best trace spans before its bearing leaves ``[0, pi]`` (0 when none qualified).
    found : ndarray of bool, shape (n_fans,)
        Whether any trace of the fan met the minimum-scan rule with a positive mean.
    """

    anchors: NDArray[np.int64]
    rate_rad_s: NDArray[np.float64]
    signal_plus_noise: NDArray[np.float64]
    n_used: NDArray[np.int64]
    found: NDArray[np.bool_]


def best_traces_in_fans(
    btr_latest_first: ArrayLike,
    anchors: ArrayLike,
    rates_rad_s: ArrayLike,
    *,
    scan_period: float,
    min_scans: int,
    sampling: Literal["nearest", "linear"] = "nearest",
) -> TraceFanSearch:
    """Search each anchor beam's fan of constant-bearing-rate traces for the largest mean.

    Parameters
    ----------
    btr_latest_first : array_like, shape (n_scans, n_beams)
        IBW BTR with row 0 the latest update.
    anchors : array_like of int, shape (n_fans,)
        Anchor beams.
    rates_rad_s : array_like, shape (n_rates,)
        Candidate bearing rates, rad/s forward in time, increasing.
    scan_period : float
        Time between scans, s.
    min_scans : int
        The method's ``minscan``: fewest scans a trace must span before its bearing leaves
        ``[0, pi]``.
    sampling : {"nearest", "linear"}
        How a trace reads the BTR at its fractional beam: the nearest beam, ``floor(b + 0.5)``,
        the method's rounding (default); or linear interpolation between the two beams around it.

    Returns
    -------
    TraceFanSearch

    Notes
    -----
    ``rateest`` (segments 62-70) with the straight line ``fbeam = a * iscan + anchor`` replaced
    by the trace of :func:`constant_rate_traces`: the mean over the scans a trace spans, the
    minimum-scan rule, the strictly largest mean winning (the first trace in rate order on ties),
    the running maximum starting at 0. The sample indices of a fan depend only on the BTR's shape,
    the anchor, the rates and the scan period, and are cached; all traces of all fans are read
    with one gather.
    """
    if sampling not in ("nearest", "linear"):
        raise ValueError(f"sampling must be 'nearest' or 'linear', got {sampling!r}")
    rates = np.ascontiguousarray(np.asarray(rates_rad_s, dtype=float).reshape(-1))
    if rates.size == 0 or not np.all(np.isfinite(rates)):
        raise ValueError("candidate rates must be finite and not empty")
    btr, anc = check_fan_inputs(btr_latest_first, anchors, min_scans)
    n_scans, n_beams = btr.shape
    key = rates.tobytes()
    fans = [_trace_tensors(n_scans, n_beams, int(a), key, float(scan_period), sampling)
            for a in anc]
    flat = np.append(btr.ravel(), 0.0)
    means = np.full((anc.size, rates.size), -np.inf)
    for i, t in enumerate(fans):  # a few fans; each is one gather over all its traces and scans
        ok = t.n_used >= min_scans
        sums = _sum_along(flat, t.index[ok], None if t.weight is None else t.weight[ok])
        means[i, ok] = sums / t.n_used[ok]
    best, best_mean, found = best_in_fans(means)
    n_used = np.array([t.n_used[b] for t, b in zip(fans, best, strict=True)], dtype=np.int64)
    return TraceFanSearch(
        anchors=anc,
        rate_rad_s=np.where(found, rates[best], 0.0),
        signal_plus_noise=np.where(found, best_mean, 0.0),
        n_used=np.where(found, n_used, 0).astype(np.int64),
        found=found,
    )
