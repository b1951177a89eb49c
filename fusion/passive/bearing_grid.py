"""Bearing tables on a common time grid: the sample period K and resampling onto ``t0 + k K``.

The crossing method (*Target Track Crossing Prediction/Detection*) takes a bearing from every
track every K seconds; recorded tables are irregular, start and stop, and may be far denser than
the grid. :func:`estimate_period` reads K from the data and :func:`resample_bearings` puts the
tracks on the grid (interpolating sparse tracks, averaging dense ones).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._validation import check_grid

__all__ = ["ResampledBearings", "estimate_period", "resample_bearings"]


@dataclass(frozen=True)
class ResampledBearings:
    """Bearing tracks on a common K-second grid.

    Attributes
    ----------
    track_id : ndarray of int64, shape (m,)
        Track of each row.
    time : ndarray, shape (m,)
        Grid times ``origin + k K``, s; rows sorted by time, then track id.
    bearing_deg : ndarray, shape (m,)
        Bearings, deg in [0, 360).
    period_s : float
        K, s.
    """

    track_id: NDArray[np.int64]
    time: NDArray[np.float64]
    bearing_deg: NDArray[np.float64]
    period_s: float


def estimate_period(track_id: ArrayLike, time: ArrayLike) -> float:
    """Median positive time step within tracks, s (a default for K)."""
    tid = np.asarray(track_id)
    tt = np.asarray(time, dtype=float)
    order = np.lexsort((tt, tid))
    tid, tt = tid[order], tt[order]
    dt = np.diff(tt)[(np.diff(tid) == 0)]
    dt = dt[dt > 0]
    if dt.size == 0:
        raise ValueError("cannot infer the sample period: no track has two distinct times")
    return float(np.median(dt))


def resample_bearings(
    track_id: ArrayLike,
    time: ArrayLike,
    bearing_deg: ArrayLike,
    *,
    period_s: float,
    max_gap_s: float | None = None,
    origin_s: float | None = None,
) -> ResampledBearings:
    """Put bearing tracks on a common grid ``origin + k K`` by linear interpolation.

    Parameters
    ----------
    track_id : array_like of int, shape (m,)
        Track of each sample (negative ids, detections of unknown origin, are dropped).
    time : array_like, shape (m,)
        Sample times, s, in any order; irregular spacing allowed.
    bearing_deg : array_like, shape (m,)
        Bearings, deg.
    period_s : float
        Grid step K, s.
    max_gap_s : float, optional
        Grid points inside a gap longer than this between two samples of a track are left
        out, so the track stops and starts again (default ``3 K``).
    origin_s : float, optional
        Grid origin, s (default: the earliest sample time).

    Returns
    -------
    ResampledBearings

    Notes
    -----
    Each track's bearings are unwrapped in time order and linearly interpolated at the grid
    points inside its own time span (a track that starts late or stops early covers only its
    span). Samples at equal times are averaged (on the unwrapped values). A track sampled more
    densely than the grid is first decimated: its samples are averaged (times and unwrapped
    bearings) within each grid cell ``[t_k - K/2, t_k + K/2)``, and the cell means are
    interpolated, so no sample is thrown away. Input already on the grid is returned
    unchanged.
    """
    tid = np.asarray(track_id)
    tt = np.asarray(time, dtype=float)
    bb = np.asarray(bearing_deg, dtype=float)
    if not (tid.shape == tt.shape == bb.shape) or tid.ndim != 1:
        raise ValueError("track_id, time and bearing_deg must be 1-D arrays of one length")
    if not (np.all(np.isfinite(tt)) and np.all(np.isfinite(bb))):
        raise ValueError("time and bearing_deg must be finite")
    if not (np.isfinite(period_s) and period_s > 0):
        raise ValueError(f"period K must be > 0 s, got {period_s!r}")
    gap = 3.0 * period_s if max_gap_s is None else float(max_gap_s)
    if not gap > 0:
        raise ValueError(f"max_gap_s must be > 0, got {max_gap_s!r}")
    keep = tid >= 0
    tid, tt, bb = tid[keep].astype(np.int64), tt[keep], bb[keep]
    if tid.size == 0:
        return ResampledBearings(np.zeros(0, np.int64), np.zeros(0), np.zeros(0), float(period_s))
    t0 = float(tt.min()) if origin_s is None else float(origin_s)
    eps = 1e-9 * period_s
    out_id, out_t, out_b = [], [], []
    for k in np.unique(tid):
        m = tid == k
        ts, inv = np.unique(tt[m], return_inverse=True)
        order = np.argsort(tt[m], kind="stable")
        unw = np.empty(m.sum())
        unw[order] = np.degrees(np.unwrap(np.radians(bb[m][order])))
        ys = np.bincount(inv, weights=unw) / np.bincount(inv)  # mean at equal times
        cell = np.floor((ts - t0) / period_s + 0.5).astype(np.int64)
        if ts.size > 1 and np.any(np.diff(cell) == 0):  # denser than the grid: cell means
            _, ci, cn = np.unique(cell, return_inverse=True, return_counts=True)
            ts = np.bincount(ci, weights=ts) / cn
            ys = np.bincount(ci, weights=ys) / cn
        k_lo = int(np.ceil((ts[0] - t0) / period_s - 1e-9))
        k_hi = int(np.floor((ts[-1] - t0) / period_s + 1e-9))
        if k_hi < k_lo:
            continue
        check_grid(k_hi + 1 - k_lo, f"track {k}: a time grid of {period_s:g} s steps from "
                   f"{ts[0]:g} s to {ts[-1]:g} s")
        grid = t0 + np.arange(k_lo, k_hi + 1) * period_s
        grid = np.clip(grid, ts[0], ts[-1]) if ts.size > 1 else grid
        if ts.size == 1:
            vals = np.full(grid.size, ys[0])
            ok = np.abs(grid - ts[0]) <= eps
        else:
            vals = np.interp(grid, ts, ys)
            # Leave out grid points inside long gaps (the track stopped meanwhile).
            j = np.clip(np.searchsorted(ts, grid, side="right") - 1, 0, ts.size - 2)
            on_sample = np.isclose(grid, ts[j], rtol=0, atol=eps) | np.isclose(
                grid, ts[j + 1], rtol=0, atol=eps)
            ok = on_sample | ((ts[j + 1] - ts[j]) <= gap)
        n_ok = int(ok.sum())
        out_id.append(np.full(n_ok, k, np.int64))
        out_t.append(t0 + np.arange(k_lo, k_hi + 1)[ok] * period_s)
        out_b.append(np.mod(vals[ok], 360.0))
    if not out_id:
        return ResampledBearings(np.zeros(0, np.int64), np.zeros(0), np.zeros(0), float(period_s))
    rid, rt, rb = np.concatenate(out_id), np.concatenate(out_t), np.concatenate(out_b)
    order = np.lexsort((rid, rt))
    return ResampledBearings(rid[order], rt[order], rb[order], float(period_s))
