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
from numpy.typing import NDArray

from fusion.passive.bearing_grid import estimate_period, resample_bearings
from fusion.passive.crossing.detector import CrossingDetector
from fusion.passive.crossing.types import CrossingAlert

__all__ = ["detect_crossings", "step_grid", "warn_unpaired"]

logger = logging.getLogger(__name__)


def detect_crossings(
    table: Any,
    *,
    K: float | None = None,
    **options: Any,
) -> list[CrossingAlert]:
    """Crossing alerts of a whole bearing table (batch entry point).

    Parameters
    ----------
    table : fusion.io.Table or mapping
        Columns ``track_id`` (int), ``time`` (s) and ``bearing_deg`` (deg), shape (m,) each;
        rows with ``track_id`` -1 (unknown origin) are ignored.
    K : float, optional
        Sample period, s (default: the median time step within tracks).
    **options
        The other keywords of :class:`CrossingDetector` (``J``, ``horizon_s``,
        ``merge_window_s``, ``max_gap_s``, ``n_windows``, ``level``, ``lead_windows``,
        ``confirm``, ``curve_alpha``, ...), with its defaults; `max_gap_s` also bounds
        interpolation gaps.

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
    det = CrossingDetector(K=period, **options)
    rs = resample_bearings(
        tid, cols["time"], cols["bearing_deg"], period_s=det.K, max_gap_s=det.max_gap_s
    )
    warn_unpaired(det, rs.track_id)
    return step_grid(det, rs.track_id, rs.time, rs.bearing_deg)


def step_grid(
    det: CrossingDetector,
    track_id: NDArray[np.int64],
    time: NDArray[np.float64],
    bearing_deg: NDArray[np.float64],
) -> list[CrossingAlert]:
    """One :meth:`CrossingDetector.step` per grid time of grid rows sorted by time.

    Parameters
    ----------
    det : CrossingDetector
        The detector, stepped in place.
    track_id, time, bearing_deg : ndarray, shape (m,)
        Grid rows (:func:`resample_bearings` or :class:`~fusion.passive.crossing.stream.StreamingGrid`),
        sorted by time.

    Returns
    -------
    list of CrossingAlert
        The alerts of the steps, in order.
    """
    alerts: list[CrossingAlert] = []
    if time.size == 0:
        return alerts
    bounds = np.flatnonzero(np.diff(time)) + 1
    starts = np.concatenate([[0], bounds])
    stops = np.concatenate([bounds, [time.size]])
    for s0, s1 in zip(starts.tolist(), stops.tolist(), strict=True):
        alerts += det.step(float(time[s0]), track_id[s0:s1], bearing_deg[s0:s1])
    return alerts


def warn_unpaired(det: CrossingDetector, track_id: NDArray[np.int64]) -> None:
    """Warn of each track with fewer than ``det.J`` samples among grid rows `track_id`."""
    tracks, counts = np.unique(track_id, return_counts=True)
    for k in tracks[counts < det.J].tolist():
        logger.warning("track %d has fewer than J=%d samples on the grid: never paired", k, det.J)
