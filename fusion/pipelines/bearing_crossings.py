"""Crossings of a bearing table with settings fitted to it: ``fusion crossings`` as a call.

:func:`find_crossings` takes the rows of a bearings file (a :class:`fusion.types.Table` from
:func:`fusion.io.read_bearings`, or a mapping of arrays ``track_id``, ``time``, ``bearing_deg``
and optionally ``sigma_bearing_deg``), merges rows of one track at one time (unless `strict`),
chooses the window, horizon and grid period from the data
(:func:`fusion.passive.crossing.settings.crossing_settings`) and runs the detector
(:func:`fusion.passive.crossing.detect_crossings`). ``fusion crossings`` reading a whole file
calls :func:`crossing_setup` and :func:`detect_with` below, and its streamed path gives the same
alerts bit for bit, so a script and the command agree. Angles in degrees, times in seconds.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.passive.crossing import CrossingAlert, detect_crossings
from fusion.passive.crossing.merge import merge_simultaneous
from fusion.passive.crossing.settings import CrossingSettings, crossing_settings

__all__ = [
    "CrossingsResult",
    "alert_columns",
    "check_spans",
    "crossing_setup",
    "detect_with",
    "find_crossings",
]


@dataclass(frozen=True)
class CrossingsResult:
    """Alerts of a bearing table and the settings that found them.

    Attributes
    ----------
    alerts : list of CrossingAlert
        Sorted by time, then pair, predicted before detected.
    settings : CrossingSettings
        Window, horizon, period (``settings.describe()`` is the command's summary).
    n_merged : int
        Rows of one track at one time merged before detection.
    """

    alerts: list[CrossingAlert]
    settings: CrossingSettings
    n_merged: int

    def columns(self) -> dict[str, NDArray[Any]]:
        """The rows of ``fusion crossings``' output file (:func:`alert_columns`)."""
        return alert_columns(self.alerts)


def check_spans(settings: CrossingSettings, spans_s: Any) -> None:
    """Refuse a table in which fewer than two tracks span the shortest window."""
    n_samples = np.floor(np.asarray(spans_s) / settings.period_s + 1e-9).astype(int) + 1
    if np.sum(n_samples >= settings.J) < 2:
        raise ValueError(
            f"fewer than two tracks span --window-samples J={settings.J} samples at "
            f"K={settings.period_s:g} s (longest: {int(n_samples.max())}); no crossing can be tested"
        )


def crossing_setup(table: Mapping[str, Any] | Any, *, strict: bool = False,
                   on_merged: Callable[[Mapping[str, Any], int], None] | None = None,
                   **options: Any) -> tuple[Mapping[str, Any], CrossingSettings, int]:
    """The rows to detect on, the settings fitted to them and how many rows were merged.

    Parameters
    ----------
    table : Table or mapping
        Columns ``track_id``, ``time`` (s), ``bearing_deg`` (deg), optional
        ``sigma_bearing_deg``.
    strict : bool, keyword-only
        Keep the rows as they are (no merging of a track's simultaneous rows).
    on_merged : callable, keyword-only
        ``on_merged(columns, n)`` right after the merging (the command says how many rows).
    **options
        Keywords of :func:`~fusion.passive.crossing.settings.crossing_settings` (``window_s``,
        ``horizon_s``, ``period_s``, ``J``, ``n_windows``, ``lead_windows``, ``confirm``,
        ``level``, ``curve_alpha`` (None: straight lines only), ``ladder_alpha``,
        ``revise``, ``confirm_overlap``, ``calibrate``); the others
        are estimated from the rows.

    Raises
    ------
    ValueError
        Fewer than two tracks, or than two tracks spanning the window; bad options.
    """
    cols: Any = table
    n_merged = 0
    if not strict:
        columns = table.columns if hasattr(table, "columns") else table
        cols, n_merged = merge_simultaneous(columns)
        if on_merged is not None:
            on_merged(cols, n_merged)
    tid = np.asarray(cols["track_id"])
    known = tid >= 0
    if np.unique(tid[known]).size < 2:
        raise ValueError("needs at least two tracks (track_id >= 0)")
    times = np.asarray(cols["time"], dtype=float)
    st = crossing_settings(tid, times, **options)
    check_spans(st, [np.ptp(times[tid == k]) for k in np.unique(tid[known])])
    return cols, st, n_merged


def detect_with(cols: Mapping[str, Any] | Any, settings: CrossingSettings, *,
                merge_window_s: float | None = None, max_gap_s: float | None = None,
                merge_repeats: bool = False) -> list[CrossingAlert]:
    """The alerts of `cols` with `settings` (``--merge-window-s``, ``--max-gap-s``,
    ``--merge-repeats`` of the command)."""
    return detect_crossings(cols, merge_window_s=merge_window_s, max_gap_s=max_gap_s,
                            split_repeats=not merge_repeats, **settings.detector_options())


def find_crossings(table: Mapping[str, Any] | Any, *, strict: bool = False,
                   merge_window_s: float | None = None, max_gap_s: float | None = None,
                   merge_repeats: bool = False, **options: Any) -> CrossingsResult:
    """Predict and detect the crossings of a bearing table as ``fusion crossings`` does.

    Parameters
    ----------
    table : Table or mapping
        Columns ``track_id`` (-1 rows are ignored), ``time`` (s), ``bearing_deg`` (deg).
    strict, **options
        See :func:`crossing_setup`.
    merge_window_s, max_gap_s, merge_repeats
        See :func:`detect_with`.

    Returns
    -------
    CrossingsResult
    """
    cols, st, n_merged = crossing_setup(table, strict=strict, **options)
    alerts = detect_with(cols, st, merge_window_s=merge_window_s, max_gap_s=max_gap_s,
                         merge_repeats=merge_repeats)
    return CrossingsResult(alerts=alerts, settings=st, n_merged=n_merged)


def alert_columns(alerts: list[CrossingAlert]) -> dict[str, NDArray[Any]]:
    """Columns of the alerts file (formats.md section 4, with the optional interval columns)."""
    return {
        "time": np.array([a.time for a in alerts], dtype=float),
        "track_a": np.array([a.track_a for a in alerts], dtype=np.int64),
        "track_b": np.array([a.track_b for a in alerts], dtype=np.int64),
        "t_cross": np.array([a.t_cross for a in alerts], dtype=float),
        "kind": np.array([a.kind.value for a in alerts], dtype=str),
        "t_cross_low": np.array([a.t_cross_low for a in alerts], dtype=float),
        "t_cross_high": np.array([a.t_cross_high for a in alerts], dtype=float),
    }
