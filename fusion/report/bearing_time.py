"""Bearing-time figures: smoothed and passive tracks, TQI states, crossing alerts.

Bearing across, time down (the waterfall of a sonar display), one colour per track. Inputs are
the validated tables of :mod:`fusion.io` (:class:`fusion.types.Table`); each function returns the
figure, :mod:`fusion.report.build` saves it.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.report.figures import (
    TQI_MARKERS,
    bearing_band,
    new_figure,
    no_wrap_line,
    state_legend,
    tqi_markers,
)
from fusion.types import Table

__all__ = ["MAX_ALERT_PAIRS", "alerts_figure", "alerts_on_tracks_figure", "smoothed_figure",
           "tqi_bearing_figure", "tqi_figure"]

#: Marker and colour of each alert kind: black, so that colour stays the tracks' identity, and
#: shapes no TQI state uses (:data:`fusion.report.figures.TQI_MARKERS`).
ALERT_STYLE = {"predicted": ("v", "k"), "detected": ("D", "k")}

#: Tracks named in a legend at most (more tracks: no legend entry per track).
MAX_LEGEND_TRACKS = 12


def _tracks(table: Table) -> Iterator[tuple[int, NDArray[np.intp]]]:
    """(track id, row indices in time order) of every track of `table`."""
    ids = table["track_id"]
    for tid in np.unique(ids):
        rows = np.flatnonzero(ids == tid)
        yield int(tid), rows[np.argsort(table["time"][rows], kind="stable")]


def _bearing_at(table: Table, track: int, time: float) -> float:
    """Bearing of `track` at the sample nearest `time`, deg (NaN outside the track's times)."""
    rows = np.flatnonzero(table["track_id"] == track)
    if rows.size == 0 or not table["time"][rows].min() <= time <= table["time"][rows].max():
        return float("nan")
    k = rows[int(np.argmin(np.abs(table["time"][rows] - time)))]
    return float(table["bearing_deg"][k])


def _draw_alerts(ax: Any, alerts: Table, bearings: Table) -> None:
    """Alert markers on track a at the alert time, and the crossing time between both tracks."""
    for i in range(len(alerts)):
        kind = str(alerts["kind"][i])
        marker, colour = ALERT_STYLE.get(kind, ("o", "k"))
        a, b, t = int(alerts["track_a"][i]), int(alerts["track_b"][i]), float(alerts["time"][i])
        ax.plot(_bearing_at(bearings, a, t), t, marker, color=colour, mfc="none", ms=8)
        tc = float(alerts["t_cross"][i])
        ba, bb = _bearing_at(bearings, a, tc), _bearing_at(bearings, b, tc)
        if np.isfinite(ba) and np.isfinite(bb) and abs(ba - bb) < 180.0:
            ax.plot([ba, bb], [tc, tc], "-", color=colour, lw=1.0, alpha=0.7)
    for kind, (marker, colour) in ALERT_STYLE.items():
        ax.plot([], [], marker, color=colour, mfc="none", label=f"crossing {kind} (alert time)")
    ax.plot([], [], "-", color="0.3", lw=1.0, label="predicted/detected crossing time")


def _bearing_axes(ax: Any, bearing: NDArray[np.float64]) -> None:
    finite = bearing[np.isfinite(bearing)]
    if finite.size:
        ax.set_xlim(finite.min() - 3.0, finite.max() + 3.0)
    ax.set_xlabel("bearing, deg")
    ax.set_ylabel("time, s")
    if not ax.yaxis_inverted():
        ax.invert_yaxis()


def smoothed_figure(tracks: Table, *, tqi: NDArray[Any] | None = None,
                    alerts: Table | None = None, detections: Table | None = None,
                    title: str) -> Any:
    """Smoothed bearing tracks with 1-sigma bands, their bearing rate and sigma over time.

    Parameters
    ----------
    tracks : Table
        ``track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg`` (deg, deg/min,
        deg), one row per track and time (``fusion smooth``, ``tracks.csv`` of ``fusion
        passive``).
    tqi : ndarray of str, shape (rows,), optional, keyword-only
        TQI state of each row (``passive``); drawn as coloured dots on the tracks.
    alerts : Table, optional, keyword-only
        Crossing alerts ``time,track_a,track_b,t_cross,kind`` drawn on the tracks.
    detections : Table, optional, keyword-only
        Raw bearings ``track_id,time,bearing_deg`` drawn as grey dots behind the tracks.
    title : str, keyword-only
        Figure title.

    Returns
    -------
    matplotlib Figure
        Three panels sharing the time axis (down): bearing, bearing rate (deg/min) and bearing
        sigma (deg).
    """
    fig, (ax, ax_rate, ax_sig) = new_figure(1, 3, size=(13.0, 7.0), sharey=True,
                                            gridspec_kw={"width_ratios": [2.2, 1, 1]})
    if detections is not None:
        ax.plot(detections["bearing_deg"], detections["time"], ".", color="0.7", ms=2,
                label="input bearings")
    n_tracks = len(np.unique(tracks["track_id"]))
    for tid, rows in _tracks(tracks):
        label = f"track {tid}" if n_tracks <= MAX_LEGEND_TRACKS else None
        t = tracks["time"][rows]
        line = bearing_band(ax, t, tracks["bearing_deg"][rows],
                            tracks["sigma_bearing_deg"][rows], lw=1.0, label=label)
        ax_rate.plot(tracks["bearing_rate_deg_per_min"][rows], t, color=line.get_color(), lw=1.0)
        ax_sig.plot(tracks["sigma_bearing_deg"][rows], t, color=line.get_color(), lw=1.0)
        if tqi is not None:  # colour: the track; marker: its state
            tqi_markers(ax, tracks["bearing_deg"][rows], t, tqi[rows], color=line.get_color(),
                        ms=2.5)
        ax.annotate(str(tid), (tracks["bearing_deg"][rows][-1], t[-1]), fontsize=8,
                    color=line.get_color(), xytext=(2, 2), textcoords="offset points")
    if tqi is not None:
        state_legend(ax)
    if alerts is not None and len(alerts):
        _draw_alerts(ax, alerts, tracks)
    _bearing_axes(ax, tracks["bearing_deg"])
    ax.set_title("bearing tracks (band: 1 sigma)")
    ax.legend(fontsize=7, loc="best", ncol=2)
    ax_rate.set_xlabel("bearing rate, deg/min")
    ax_rate.set_title("bearing rate")
    ax_sig.set_xlabel("bearing sigma, deg")
    ax_sig.set_title("bearing standard deviation")
    for a in (ax_rate, ax_sig):
        a.grid(alpha=0.3)
    fig.suptitle(title)
    return fig


def tqi_figure(table: Table, *, title: str) -> Any:
    """Amplitude, residual and TQI state of every track over time (``fusion tqi`` output).

    Parameters
    ----------
    table : Table
        ``track_id,time,amplitude,residual,tqi`` (amplitude linear on the normalised scale,
        residual deg).
    title : str, keyword-only

    Returns
    -------
    matplotlib Figure
        Amplitude (dB) and residual (deg), marker by state, and the state, against time (s);
        colour is the track in every panel.
    """
    fig, (ax_a, ax_r, ax_s) = new_figure(3, 1, size=(10.0, 8.0), sharex=True)
    states = list(TQI_MARKERS)
    amp_db = 10.0 * np.log10(np.maximum(table["amplitude"], 1e-3))
    tqi = table["tqi"]
    ids = np.unique(table["track_id"])
    offsets = np.linspace(-0.25, 0.25, ids.size) if ids.size > 1 else np.zeros(1)
    for k, (off, (tid, rows)) in enumerate(zip(offsets, _tracks(table), strict=True)):
        colour = f"C{k % 10}"
        tqi_markers(ax_a, table["time"][rows], amp_db[rows], tqi[rows], color=colour)
        tqi_markers(ax_r, table["time"][rows], table["residual"][rows], tqi[rows], color=colour)
        level = np.array([states.index(s) if s in states else np.nan for s in tqi[rows]])
        label = f"track {tid}" if ids.size <= MAX_LEGEND_TRACKS else None
        ax_s.step(table["time"][rows], level + off, where="post", lw=1.0, color=colour,
                  label=label)
    state_legend(ax_a)
    ax_a.set_ylabel("amplitude, dB (noise mean 0 dB)")
    ax_a.legend(fontsize=7, loc="best", ncol=4)
    ax_r.set_ylabel("residual, deg")
    ax_s.set_yticks(range(len(states)), states)
    ax_s.set_ylabel("TQI state")
    ax_s.set_xlabel("time, s")
    if ids.size <= MAX_LEGEND_TRACKS:
        ax_s.legend(fontsize=7, loc="best", ncol=4)
    for a in (ax_a, ax_r, ax_s):
        a.grid(alpha=0.3)
    fig.suptitle(title)
    return fig


def tqi_bearing_figure(table: Table, bearings: Table, *, title: str) -> Any:
    """Bearing tracks (colour) marked with the TQI state (marker) at the same track and time.

    Parameters
    ----------
    table : Table
        ``fusion tqi`` output (``track_id,time,...,tqi``).
    bearings : Table
        ``track_id,time,bearing_deg`` of the same tracks; rows without a TQI row at the same
        track and time are grey.
    title : str, keyword-only

    Returns
    -------
    matplotlib Figure
    """
    fig, ax = new_figure(size=(8.0, 7.0))
    key = {(int(k), float(t)): str(s) for k, t, s in
           zip(table["track_id"], table["time"], table["tqi"], strict=True)}
    state = np.array([key.get((int(k), float(t)), "") for k, t in
                      zip(bearings["track_id"], bearings["time"], strict=True)])
    m = state == ""
    ax.plot(bearings["bearing_deg"][m], bearings["time"][m], ".", color="0.75", ms=2,
            label="no TQI at this time")
    for k, (tid, rows) in enumerate(_tracks(bearings)):  # colour: the track; marker: its state
        colour = f"C{k % 10}"
        ax.plot(no_wrap_line(bearings["bearing_deg"][rows]), bearings["time"][rows], "-",
                color=colour, lw=0.8, alpha=0.6, label=f"track {tid}" if k < MAX_LEGEND_TRACKS
                else None)
        tqi_markers(ax, bearings["bearing_deg"][rows], bearings["time"][rows], state[rows],
                    color=colour)
    state_legend(ax)
    _bearing_axes(ax, bearings["bearing_deg"])
    ax.legend(fontsize=7, loc="best")
    ax.set_title(title)
    return fig


#: Most track pairs (rows) in :func:`alerts_figure`.
MAX_ALERT_PAIRS = 40


def alerts_figure(alerts: Table, *, title: str) -> Any:
    """Crossing alerts per track pair: alert time, crossing time and its interval.

    Parameters
    ----------
    alerts : Table
        ``time,track_a,track_b,t_cross,kind`` and, when present, ``t_cross_low,t_cross_high``
        (s).
    title : str, keyword-only

    Returns
    -------
    matplotlib Figure
        One row per alerting pair: a marker at each alert's time, a dot at its crossing time
        with the interval as a bar, a thin line from one to the other. At most
        :data:`MAX_ALERT_PAIRS` rows (the pairs with the most alerts; the title says how many
        were left out), so the figure keeps a readable size for any number of pairs.
    """
    count: dict[tuple[int, int], int] = {}
    for a, b in zip(alerts["track_a"], alerts["track_b"], strict=True):
        count[(int(a), int(b))] = count.get((int(a), int(b)), 0) + 1
    shown = sorted(count, key=lambda p: (-count[p], p))[:MAX_ALERT_PAIRS]
    if len(shown) < len(count):
        title = f"{title} ({len(shown)} of {len(count)} alerting pairs: those with most alerts)"
        keep = [(int(a), int(b)) in set(shown) for a, b in zip(alerts["track_a"],
                                                                 alerts["track_b"], strict=True)]
        alerts = alerts.select(np.flatnonzero(keep))
    pairs = sorted(shown)
    fig, ax = new_figure(size=(9.0, max(3.0, 1.2 + 0.3 * len(pairs))))
    row = {p: i for i, p in enumerate(pairs)}
    interval = "t_cross_low" in alerts and "t_cross_high" in alerts
    for i in range(len(alerts)):
        y = row[(int(alerts["track_a"][i]), int(alerts["track_b"][i]))]
        marker, colour = ALERT_STYLE.get(str(alerts["kind"][i]), ("o", "k"))
        t, tc = float(alerts["time"][i]), float(alerts["t_cross"][i])
        ax.plot([t, tc], [y, y], "-", color=colour, lw=0.6, alpha=0.6)
        ax.plot(t, y, marker, color=colour, mfc="none", ms=8)
        if interval:
            lo, hi = float(alerts["t_cross_low"][i]), float(alerts["t_cross_high"][i])
            ax.errorbar(tc, y, xerr=[[tc - lo], [hi - tc]], fmt="o", color=colour, ms=4,
                        capsize=3)
        else:
            ax.plot(tc, y, "o", color=colour, ms=4)
    for kind, (marker, colour) in ALERT_STYLE.items():
        ax.plot([], [], marker, color=colour, mfc="none", label=f"{kind}: alert time")
    ax.plot([], [], "o", color="0.3", ms=4,
            label="crossing time" + (" and interval" if interval else ""))
    ax.set_yticks(range(len(pairs)), [f"{a} x {b}" for a, b in pairs])
    ax.set_ylabel("track pair")
    ax.set_xlabel("time, s")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    ax.set_title(title)
    return fig


def alerts_on_tracks_figure(alerts: Table, bearings: Table, *, title: str) -> Any:
    """Bearing tracks with the crossing alerts raised on them.

    Parameters
    ----------
    alerts : Table
        ``fusion crossings`` output.
    bearings : Table
        The ``track_id,time,bearing_deg`` input of the crossings run (track -1 drawn grey).
    title : str, keyword-only

    Returns
    -------
    matplotlib Figure
    """
    fig, ax = new_figure(size=(8.0, 7.0))
    labelled = bearings.select(bearings["track_id"] >= 0)
    clutter = bearings.select(bearings["track_id"] < 0)
    if len(clutter):
        ax.plot(clutter["bearing_deg"], clutter["time"], ".", color="0.8", ms=2,
                label="unknown origin")
    n_tracks = len(np.unique(labelled["track_id"]))
    for tid, rows in _tracks(labelled):
        ax.plot(no_wrap_line(labelled["bearing_deg"][rows]), labelled["time"][rows], ".-",
                ms=2, lw=0.6, label=f"track {tid}" if n_tracks <= MAX_LEGEND_TRACKS else None)
    if len(alerts):
        _draw_alerts(ax, alerts, labelled)
    _bearing_axes(ax, bearings["bearing_deg"])
    ax.legend(fontsize=7, loc="best", ncol=2)
    ax.set_title(title)
    return fig
