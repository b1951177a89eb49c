"""Batch entry point of the crossing detector: a whole bearing table in, its alerts out.

:func:`detect_crossings` resamples an irregularly sampled bearing table onto the detector's grid
(:func:`~fusion.passive.bearing_grid.resample_bearings`) and feeds it to a
:class:`~fusion.passive.crossing.detector.CrossingDetector` one grid time at a time.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np

from fusion.passive.bearing_grid import estimate_period, resample_bearings
from fusion.passive.crossing.detector import CrossingDetector
from fusion.passive.crossing.types import CrossingAlert

__all__ = ["detect_crossings"]

logger = logging.getLogger(__name__)


def detect_crossings(
    table: Any,
    *,
    J: int = 10,
    K: float | None = None,
    horizon_s: float | None = None,
    min_rate_diff_deg_per_s: float = 1e-9,
    merge_window_s: float | None = None,
    max_gap_s: float | None = None,
    n_windows: int = 1,
    level: float | None = 0.95,
    max_interval_s: float | None = None,
    lead_windows: float = 1.0,
    confirm: int = 1,
    curve_alpha: float | None = None,
    split_repeats: bool = True,
    ladder_alpha: float | None = None,
    revise: bool = False,
    confirm_overlap: bool = False,
    calibrate: bool = False,
    curvature: bool = False,
    confirm_lead_windows: float | None = None,
) -> list[CrossingAlert]:
    """Crossing alerts of a whole bearing table (batch entry point).

    Parameters
    ----------
    table : fusion.io.Table or mapping
        Columns ``track_id`` (int), ``time`` (s) and ``bearing_deg`` (deg), shape (m,) each;
        rows with ``track_id`` -1 (unknown origin) are ignored.
    J : int, optional
        Samples per least-squares window.
    K : float, optional
        Sample period, s (default: the median time step within tracks).
    horizon_s, min_rate_diff_deg_per_s, merge_window_s, max_gap_s, n_windows, level, \
max_interval_s, lead_windows, confirm, curve_alpha, split_repeats, ladder_alpha, revise, \
confirm_overlap, calibrate, curvature, confirm_lead_windows
        As in :class:`CrossingDetector` (`max_gap_s` also bounds interpolation gaps).

    Returns
    -------
    list of CrossingAlert
        Sorted by time, then pair, predicted before detected.

    Notes
    -----
    The table is resampled onto the grid ``t_min + k K`` (:func:`resample_bearings`) and fed
    to a :class:`CrossingDetector` one grid time at a time. :func:`crossing_settings` gives
    `J`, `K`, `horizon_s` and `n_windows` from windows in seconds.
    """
    cols: Mapping[str, Any] = table.columns if hasattr(table, "columns") else table
    for name in ("track_id", "time", "bearing_deg"):
        if name not in cols:
            raise ValueError(f"bearing table has no column {name!r}")
    tid = np.asarray(cols["track_id"])
    n_unknown = int(np.sum(tid < 0))
    if n_unknown:
        logger.info("ignoring %d detection(s) of unknown origin (track_id -1)", n_unknown)
    keep = tid >= 0
    period = estimate_period(tid[keep], np.asarray(cols["time"])[keep]) if K is None else K
    det = CrossingDetector(
        J=J, K=period, horizon_s=horizon_s, min_rate_diff_deg_per_s=min_rate_diff_deg_per_s,
        merge_window_s=merge_window_s, max_gap_s=max_gap_s, n_windows=n_windows, level=level,
        max_interval_s=max_interval_s, lead_windows=lead_windows, confirm=confirm,
        curve_alpha=curve_alpha, split_repeats=split_repeats, ladder_alpha=ladder_alpha,
        revise=revise, confirm_overlap=confirm_overlap,
        calibrate=calibrate, curvature=curvature, confirm_lead_windows=confirm_lead_windows,
    )
    rs = resample_bearings(
        tid, cols["time"], cols["bearing_deg"], period_s=det.K, max_gap_s=det.max_gap_s
    )
    for k in np.unique(rs.track_id):
        if np.sum(rs.track_id == k) < det.J:
            logger.warning("track %d has fewer than J=%d samples on the grid: never paired", k, det.J)
    alerts: list[CrossingAlert] = []
    if rs.time.size == 0:
        return alerts
    bounds = np.flatnonzero(np.diff(rs.time)) + 1
    starts = np.concatenate([[0], bounds])
    stops = np.concatenate([bounds, [rs.time.size]])
    for s0, s1 in zip(starts.tolist(), stops.tolist(), strict=True):
        alerts += det.step(float(rs.time[s0]), rs.track_id[s0:s1], rs.bearing_deg[s0:s1])
    return alerts
