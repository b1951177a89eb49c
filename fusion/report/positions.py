"""Plan-view figures of position tracks: multistatic tracks over the clutter map, TMA solutions.

Positions are x east, y north in metres. The clutter map drawn behind ``fusion track`` output is
computed from the detections the tracker read: the fraction of pings with a detection in each
cell (the recurrence the clutter map of "Target tracking using fuzzy logic association",
Section 2.4, thresholds), and the hotspots of :class:`fusion.active.clutter.density.
DensityClutterMap` with the scales ``fusion track`` chose (its ``T.settings.json``), fed
ping by ping.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.report.figures import covariance_ellipse, new_figure, sigma_band
from fusion.types import Table

__all__ = ["clutter_recurrence", "track_sigma_figure", "tracks_figure", "tma_figure"]

#: Cell of the recurrence map, m (the grid clutter map's default cell).
CELL_M = 150.0
#: Most cells per axis of the recurrence map (the cell grows for wide areas).
MAX_CELLS = 300
#: Points of a TMA track marked with 2-sigma bars and bearing lines.
TMA_MARKS = 8


def _tracks(table: Table) -> Iterator[tuple[int, NDArray[np.intp]]]:
    ids = table["track_id"]
    for tid in np.unique(ids):
        rows = np.flatnonzero(ids == tid)
        yield int(tid), rows[np.argsort(table["time"][rows], kind="stable")]


def clutter_recurrence(detections: Table, *, cell_m: float = CELL_M
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Fraction of pings with at least one detection in each cell.

    Parameters
    ----------
    detections : Table
        ``event,time,x,y`` (m).
    cell_m : float, keyword-only
        Cell size, m; grown so that no axis has more than :data:`MAX_CELLS` cells.

    Returns
    -------
    x_edges : ndarray, shape (nx + 1,)
        Cell edges east, m.
    y_edges : ndarray, shape (ny + 1,)
        Cell edges north, m.
    fraction : ndarray, shape (ny, nx)
        Pings with a detection in the cell over all pings (empty events between the first and
        the last count as pings), in [0, 1].
    """
    x, y, ev = detections["x"], detections["y"], detections["event"]
    lo = np.array([x.min(), y.min()])
    span = np.array([x.max(), y.max()]) - lo
    cell = max(float(cell_m), float(span.max()) / MAX_CELLS, 1e-9)
    n = np.maximum(np.ceil(span / cell).astype(int), 1) + 1
    ix = np.minimum(((x - lo[0]) / cell).astype(int), n[0] - 1)
    iy = np.minimum(((y - lo[1]) / cell).astype(int), n[1] - 1)
    cells = np.unique(np.c_[ev, iy, ix], axis=0)  # one count per ping and cell
    counts = np.zeros((n[1], n[0]))
    np.add.at(counts, (cells[:, 1], cells[:, 2]), 1.0)
    n_pings = int(ev.max() - ev.min() + 1)
    return (lo[0] + cell * np.arange(n[0] + 1), lo[1] + cell * np.arange(n[1] + 1),
            counts / n_pings)


#: Settings of ``fusion track`` (``T.settings.json``) that shape its density clutter map.
MAP_SETTINGS = ("position_sigma_m", "feature_sigma_m")


def track_map_settings(tracks_path: Path) -> dict[str, float]:
    """The clutter-map scales ``fusion track`` chose for `tracks_path` (from ``T.settings.json``).

    Empty when the file is absent or does not hold them (the map's defaults are then used).
    """
    from fusion.io import read_json, settings_path

    try:
        settings = read_json(settings_path(tracks_path))["settings"]
        found = {k: float(settings[k]) for k in MAP_SETTINGS if k in settings}
    except (OSError, ValueError, KeyError, TypeError):
        return {}
    return {k: v for k, v in found.items() if np.isfinite(v) and v > 0}


def _hotspots(detections: Table, map_settings: dict[str, float] | None = None) -> Any:
    """Hotspots of the density clutter map fed with the detections ping by ping."""
    from fusion.active.clutter.density import DensityClutterMap

    cmap = DensityClutterMap(**(map_settings or {}))
    ev = detections["event"]
    for e in np.unique(ev):
        r = ev == e
        cmap.update(np.c_[detections["x"][r], detections["y"][r]], float(detections["time"][r][0]))
    return cmap.hotspots()


def tracks_figure(tracks: Table, *, detections: Table | None = None, title: str,
                  map_settings: dict[str, float] | None = None, tentative: bool = False) -> Any:
    """Multistatic tracks in plan view, over the clutter map of the detections when given.

    Parameters
    ----------
    tracks : Table
        ``track_id,event,time,x,y,vx,vy,status`` (``fusion track``).
    detections : Table, optional, keyword-only
        The detections the tracker read (``event,time,x,y`` [+ ``src_x,src_y,rcv_x,rcv_y``]):
        drawn as grey dots over the recurrence map, with the hotspot regions and the source
        and receivers.
    title : str, keyword-only
    map_settings : dict, optional, keyword-only
        Scales of the density clutter map whose hotspots are drawn (``position_sigma_m``,
        ``feature_sigma_m``: those ``fusion track`` chose, :func:`track_map_settings`); the
        map's defaults when None.
    tentative : bool, optional, keyword-only
        Also draw the tracks that were never confirmed, faint (default False: a run in clutter
        starts hundreds, which bury the map; the title counts them).

    Returns
    -------
    matplotlib Figure
        Confirmed stretches solid, the tentative stretches of confirmed tracks faint and
        dotted, a cross where a confirmed track was deleted; the sensor platform's path
        (``own_x, own_y`` of the detections) as a black line.
    """
    fig, ax = new_figure(size=(9.0, 8.0))
    if detections is not None and len(detections):
        xe, ye, frac = clutter_recurrence(detections)
        im = ax.pcolormesh(xe, ye, np.ma.masked_equal(frac, 0.0), cmap="Greys", vmin=0.0,
                           vmax=1.0, shading="flat", alpha=0.8)
        fig.colorbar(im, ax=ax, label="fraction of pings with a detection in the cell",
                     shrink=0.7)
        ax.plot(detections["x"], detections["y"], ".", color="0.7", ms=1.0, label="detections")
        hot = _hotspots(detections, map_settings)
        for k in range(len(hot)):
            covariance_ellipse(ax, hot.positions[k], hot.covariances[k], n_sigma=hot.gate,
                               color="tab:red", lw=1.0, ls="--")
        if len(hot):
            ax.plot([], [], "--", color="tab:red", label="clutter-map hotspot regions")
        if "src_x" in detections and "rcv_x" in detections:
            src = np.unique(np.c_[detections["src_x"], detections["src_y"]], axis=0)
            rcv = np.unique(np.c_[detections["rcv_x"], detections["rcv_y"]], axis=0)
            ax.plot(src[:, 0], src[:, 1], "*", color="k", ms=12, label="source")
            ax.plot(rcv[:, 0], rcv[:, 1], "^", color="k", mfc="w", ms=8, label="receivers")
        if "own_x" in detections and "own_y" in detections:
            ax.plot(detections["own_x"], detections["own_y"], "-", color="k", lw=1.5,
                    label="sensor platform")
            ax.plot(detections["own_x"][-1], detections["own_y"][-1], ">", color="k", ms=7)
    n_confirmed = 0
    for tid, rows in _tracks(tracks):
        x, y, status = tracks["x"][rows], tracks["y"][rows], tracks["status"][rows]
        conf = status == "confirmed"
        n_confirmed += bool(conf.any())
        if not (conf.any() or tentative):
            continue
        line, = ax.plot(x, y, ":", lw=0.6, alpha=0.35 if conf.any() else 0.2)
        if conf.any():
            ax.plot(np.where(conf, x, np.nan), np.where(conf, y, np.nan), "-", lw=2.0,
                    color=line.get_color())
            k = int(np.flatnonzero(conf)[-1])
            ax.annotate(str(tid), (x[k], y[k]), fontsize=8, xytext=(3, 3),
                        textcoords="offset points")
        if status[-1] == "deleted" and conf.any():
            ax.plot(x[-1], y[-1], "x", color=line.get_color(), ms=6)
    ax.plot([], [], "-", color="0.2", lw=2.0, label="confirmed track")
    ax.plot([], [], ":", color="0.2", lw=0.6, alpha=0.35, label="tentative stretch")
    ax.plot([], [], "x", color="0.2", label="deleted")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x east, m")
    ax.set_ylabel("y north, m")
    ax.legend(fontsize=7, loc="best")
    n_all = len(np.unique(tracks["track_id"]))
    ax.set_title(f"{title}\n{n_confirmed} confirmed of {n_all} tracks"
                 + ("" if tentative else f" ({n_all - n_confirmed} never confirmed, not drawn)"))
    return fig


def track_sigma_figure(tracks: Table, sigma_x: NDArray[np.float64], sigma_y: NDArray[np.float64],
                       *, title: str) -> Any:
    """x and y of the confirmed tracks over time with their 1-sigma bands (``track --smooth``).

    Parameters
    ----------
    tracks : Table
        ``fusion track --smooth`` output.
    sigma_x, sigma_y : ndarray, shape (rows,)
        Its ``sigma_x, sigma_y`` columns, m.
    title : str, keyword-only

    Returns
    -------
    matplotlib Figure
    """
    fig, (ax_x, ax_y) = new_figure(2, 1, size=(10.0, 7.0), sharex=True)
    for tid, rows in _tracks(tracks):
        rows = rows[tracks["status"][rows] == "confirmed"]
        if rows.size == 0:
            continue
        t = tracks["time"][rows]
        for ax, col, sig in ((ax_x, "x", sigma_x), (ax_y, "y", sigma_y)):
            v = tracks[col][rows]
            line, = ax.plot(t, v, lw=1.0, label=f"track {tid}" if ax is ax_x else None)
            sigma_band(ax, t, v, sig[rows], color=line.get_color())
    ax_x.set_ylabel("x east, m")
    ax_y.set_ylabel("y north, m")
    ax_y.set_xlabel("time, s")
    for ax in (ax_x, ax_y):
        ax.grid(alpha=0.3)
    if ax_x.get_legend_handles_labels()[0]:
        ax_x.legend(fontsize=7, loc="best", ncol=3)
    fig.suptitle(f"{title} (confirmed tracks, band: 1 sigma)")
    return fig


def tma_figure(result: Table, *, ownship: Table | None = None, title: str) -> Any:
    """TMA solution: plan view with 2-sigma bars, range and speed over time.

    Parameters
    ----------
    result : Table
        ``time,x,y,vx,vy,sigma_x,sigma_y,range`` (``fusion tma``; m, m/s, s), with
        ``range_low,range_high`` (95 % interval, m) and ``observable`` (1/0) when the output has
        them; a range flagged unobservable is written on the figure and in its title.
    ownship : Table, optional, keyword-only
        Own-ship ``time,x,y``: drawn with bearing lines to the estimate at a few times.
    title : str, keyword-only

    Returns
    -------
    matplotlib Figure
    """
    fig, axes = new_figure(size=(12.0, 6.5), mosaic=[["plan", "range"], ["plan", "speed"]],
                           width_ratios=[1.4, 1.0])
    ax = axes["plan"]
    t, x, y = result["time"], result["x"], result["y"]
    if ownship is not None:
        ax.plot(ownship["x"], ownship["y"], "k-", lw=1.2, label="own-ship")
    ax.plot(x, y, "b-", lw=1.5, label="target estimate")
    marks = np.unique(np.linspace(0, t.size - 1, min(TMA_MARKS, t.size)).astype(int))
    ax.errorbar(x[marks], y[marks], xerr=2 * result["sigma_x"][marks],
                yerr=2 * result["sigma_y"][marks], fmt="o", color="b", ms=3, capsize=3,
                label="2 sigma in x and y")
    if ownship is not None:
        ox = np.interp(t[marks], ownship["time"], ownship["x"])
        oy = np.interp(t[marks], ownship["time"], ownship["y"])
        for k, m in enumerate(marks):
            ax.plot([ox[k], x[m]], [oy[k], y[m]], ":", color="0.5", lw=0.8)
        ax.plot([], [], ":", color="0.5", label="bearing (own-ship to estimate)")
    ax.plot(x[-1], y[-1], "bs", ms=6)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x east, m")
    ax.set_ylabel("y north, m")
    ax.legend(fontsize=7, loc="best")
    ax.set_title("plan view")
    axes["range"].plot(t, result["range"] / 1000.0, "b-", label="range")
    if "range_low" in result and "range_high" in result:
        axes["range"].fill_between(t, result["range_low"] / 1000.0, result["range_high"] / 1000.0,
                                   color="b", alpha=0.2, lw=0, label="95 % interval")
        axes["range"].legend(fontsize=7, loc="best")
    axes["range"].set_ylabel("range, km")
    speed = np.hypot(result["vx"], result["vy"])
    axes["speed"].plot(t, speed, "b-")
    axes["speed"].set_ylabel("speed, m/s")
    axes["speed"].set_xlabel("time, s")
    axes["range"].sharex(axes["speed"])
    for a in (axes["range"], axes["speed"]):
        a.grid(alpha=0.3)
    course = float(np.degrees(np.arctan2(result["vx"][-1], result["vy"][-1])) % 360.0)
    flagged = "observable" in result and bool(np.any(np.asarray(result["observable"]) == 0))
    if flagged:  # the estimate is drawn, but the reader must not take its range at face value
        for a in (ax, axes["range"]):
            a.text(0.5, 0.97, "RANGE UNOBSERVABLE (flagged)", transform=a.transAxes, ha="center",
                   va="top", color="tab:red", fontsize=10, fontweight="bold",
                   bbox={"facecolor": "w", "edgecolor": "tab:red", "alpha": 0.9})
    fig.suptitle(("RANGE UNOBSERVABLE -- " if flagged else "")
                 + f"{title}: final range {result['range'][-1] / 1000:.2f} km, "
                 f"speed {speed[-1]:.1f} m/s, course {course:.0f} deg"
                 + ("" if "observable" not in result or flagged else " (range observable)"))
    return fig
