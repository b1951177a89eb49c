"""Prediction and detection of bearing-track crossings.

Implements *Target Track Crossing Prediction/Detection* (the method text of that title): every
K seconds each track's bearing rate ``B'`` and bearing intercept ``B0`` come from a least-squares
line over its most recent J samples (regression routine 104A); for every pair of tracks the
crossing time ``t_c`` follows from equation (2); pairs whose ``t_c`` falls outside an accepted
range are dropped (in-range check 104C); inequality (3) predicts a crossing and inequality (4)
detects one (104D, 104E), and either raises an alert (output 106).

Beyond the method text, each alert carries a confidence interval of ``t_c`` from the covariance
of the two window fits (Fieller's interval), an alert is raised only when that interval is
bounded and no wider than the horizon, and a pair whose bearing-rate difference the J-sample
window cannot resolve is tried again on windows of 2 J, 4 J, ... samples (``n_windows``).

Pieces:

- :class:`~fusion.passive.line_fit.SlidingLineFit` - recursive least-squares lines over a
  sliding window for many tracks at once, with their covariance;
- :func:`~fusion.passive.crossing_pairs.evaluate_pairs` - equation (2), the in-range check and
  inequalities (3)/(4) for all pairs at once;
- :class:`~fusion.passive.crossing_detector.CrossingDetector` - the streaming component
  (``step``), window ladder and alert de-duplication;
- :func:`detect_crossings` - the batch entry point for a bearing table sampled irregularly, and
  :func:`crossing_settings` - window, horizon and period in seconds from the data.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np

from fusion.passive.bearing_grid import ResampledBearings, estimate_period, resample_bearings
from fusion.passive.crossing_detector import CrossingDetector
from fusion.passive.crossing_pairs import evaluate_pairs
from fusion.passive.crossing_score import CrossingScore, IntervalScore, score_alerts, score_intervals
from fusion.passive.crossing_settings import (
    DEFAULT_CONFIRM,
    DEFAULT_HORIZON_S,
    DEFAULT_LEAD_WINDOWS,
    DEFAULT_LEVEL,
    DEFAULT_N_WINDOWS,
    DEFAULT_WINDOW_S,
    MAX_SAMPLES_PER_WINDOW,
    MIN_SAMPLES_PER_WINDOW,
    CrossingSettings,
    crossing_settings,
)
from fusion.passive.crossing_types import AlertKind, CrossingAlert, PairCheck
from fusion.passive.line_fit import LineStats, SlidingLineFit

__all__ = [
    "DEFAULT_CONFIRM",
    "DEFAULT_HORIZON_S",
    "DEFAULT_LEAD_WINDOWS",
    "DEFAULT_LEVEL",
    "DEFAULT_N_WINDOWS",
    "DEFAULT_WINDOW_S",
    "MAX_SAMPLES_PER_WINDOW",
    "MIN_SAMPLES_PER_WINDOW",
    "Alert",
    "AlertKind",
    "CrossingAlert",
    "CrossingDetector",
    "CrossingScore",
    "CrossingSettings",
    "IntervalScore",
    "LineStats",
    "PairCheck",
    "ResampledBearings",
    "SlidingLineFit",
    "crossing_settings",
    "detect_crossings",
    "estimate_period",
    "evaluate_pairs",
    "resample_bearings",
    "score_alerts",
    "score_intervals",
]

logger = logging.getLogger(__name__)

#: Short name of :class:`CrossingAlert`.
Alert = CrossingAlert


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
max_interval_s, lead_windows, confirm
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
