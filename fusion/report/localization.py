"""Figures of ``fusion localize`` results: sources and whale tracks, intensity surfaces.

Plan view (x east, y north) and depth against time of every localized source and track, with
2-sigma ellipses and bars from each fix's covariance; sources flagged unobservable or
mirror-ambiguous are hollow. With the array, the eq. (17) intensity of the window with the most
valid TDOAs (*Localization of Short Duration Periodic Signals*, eq. 16-17, steps 56-60;
:func:`fusion.localization.surfaces.intensity_volume`) is drawn as its largest value over depth (plan
view) and over y (depth section), with that window's sources on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import SensorArray
from fusion.report.figures import covariance_ellipse, new_figure

__all__ = ["Fixes", "fix_counts", "read_fixes", "fixes_figure", "surface_figure", "surface_reading"]

#: Sources drawn with a covariance ellipse at most (the rest as points).
MAX_ELLIPSES = 200
#: Delay sigma used when a TDOA carries none, s (the grid's cell span widens it anyway).
DEFAULT_SIGMA_S = 1e-5


@dataclass(frozen=True)
class Fixes:
    """Localized sources and tracks of one result file.

    Attributes
    ----------
    time : ndarray, shape (n,)
        Mid-time of each fix's window (or event), s.
    xyz : ndarray, shape (n, 3)
        Positions, m (z up).
    cov : ndarray, shape (n, 3, 3)
        Covariances, m^2 (NaN when unknown).
    good : ndarray of bool, shape (n,)
        Observable and not mirror-ambiguous.
    tracks : tuple of (int, ndarray (k, 4))
        Track id and points ``(t, x, y, z)``.
    windows : list of dict
        The raw windows of a localization result (empty for events).
    """

    time: NDArray[np.float64]
    xyz: NDArray[np.float64]
    cov: NDArray[np.float64]
    good: NDArray[np.bool_]
    tracks: tuple[tuple[int, NDArray[np.float64]], ...]
    windows: list[dict[str, Any]]


def _cov(v: Any) -> NDArray[np.float64]:
    try:
        c = np.array(v, dtype=float)
    except (TypeError, ValueError):
        return np.full((3, 3), np.nan)
    return c if c.shape == (3, 3) else np.full((3, 3), np.nan)


def _finite(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def read_fixes(path: Path, kind: str) -> Fixes:
    """Read a ``fusion localize`` result (``kind`` ``localization``) or its ``--events`` result.

    Raises
    ------
    ValueError
        The file does not hold a valid result (the readers of :mod:`fusion.io` name the
        problem).
    """
    from fusion.io import read_json, read_localization

    rows: list[tuple[float, float, float, float, NDArray[np.float64], bool]] = []
    tracks: tuple[tuple[int, NDArray[np.float64]], ...] = ()
    windows: list[dict[str, Any]] = []
    if kind == "localization":
        result = read_localization(path)  # validates every field the figures use
        doc = read_json(path)
        windows = doc["windows"]
        for w, raw in zip(result.windows, windows, strict=True):
            for s, rs in zip(w.sources, raw["sources"], strict=True):
                good = rs.get("observable", True) is not False and not rs.get("mirror_ambiguous")
                rows.append((0.5 * (w.t_start + w.t_end), s.x, s.y, s.z, np.array(s.cov), good))
        tracks = tuple((tid, np.array(points, dtype=float).reshape(-1, 4))
                       for tid, points in result.tracks)
    else:
        doc = read_json(path)
        events = doc.get("events") if isinstance(doc, dict) else None
        if not isinstance(events, list):
            raise ValueError(f"{path}: expected an object with an 'events' list")
        for k, e in enumerate(events):
            if not isinstance(e, dict) or not all(_finite(e.get(c)) for c in
                                                  ("t_start", "t_end", "x", "y", "z")):
                raise ValueError(f"{path}: event {k} needs numbers t_start, t_end, x, y, z")
            rows.append((0.5 * (e["t_start"] + e["t_end"]), e["x"], e["y"], e["z"],
                         _cov(e.get("cov")), e.get("observable", True) is not False))
    if rows:
        t, x, y, z, cov, good = zip(*rows, strict=True)
        xyz = np.c_[x, y, z]
        return Fixes(np.array(t), xyz, np.array(cov), np.array(good, dtype=bool), tracks, windows)
    return Fixes(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0, dtype=bool),
                 tracks, windows)


def fix_counts(fixes: Fixes, kind: str) -> str:
    """The counts a reader needs before any error figure: fixes, flagged, tracks.

    Examples
    --------
    >>> f = Fixes(np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3, 3)),
    ...           np.array([True, True, False]), (), [])
    >>> fix_counts(f, "events")
    '3 events localized, 2 fixed, 1 flagged (unobservable)'
    >>> fix_counts(f, "localization")
    '3 sources, 2 fixed, 1 flagged (unobservable or mirror-ambiguous), 0 tracks'
    """
    n, good = int(fixes.good.size), int(fixes.good.sum())
    if kind == "events":
        return f"{n} events localized, {good} fixed, {n - good} flagged (unobservable)"
    return (f"{n} sources, {good} fixed, {n - good} flagged (unobservable or mirror-ambiguous), "
            f"{len(fixes.tracks)} tracks")


def fixes_figure(fixes: Fixes, *, array: SensorArray | None = None, title: str) -> Any:
    """Sources and tracks in plan view and depth against time.

    Parameters
    ----------
    fixes : Fixes
    array : SensorArray, optional, keyword-only
        Sensors drawn in plan view and at their depth.
    title : str, keyword-only

    Returns
    -------
    matplotlib Figure
        Left: plan view, sources coloured by time, 2-sigma ellipses, tracks as lines. Right:
        depth (m, down) against time (s) with 2-sigma bars.
    """
    fig, (ax, ax_d) = new_figure(1, 2, size=(13.0, 6.0), gridspec_kw={"width_ratios": [1.2, 1]})
    if array is not None:
        s = array.positions
        ax.plot(s[:, 0], s[:, 1], "^", color="k", mfc="w", ms=8, label="sensors")
    t, p, good = fixes.time, fixes.xyz, fixes.good
    vmin, vmax = (float(t.min()), float(t.max())) if t.size else (0.0, 1.0)
    if good.any():
        sc = ax.scatter(p[good, 0], p[good, 1], c=t[good], cmap="viridis", vmin=vmin, vmax=vmax,
                        s=14, label="sources", zorder=3)
        fig.colorbar(sc, ax=ax, label="time, s", shrink=0.8)
        for k in np.flatnonzero(good)[:MAX_ELLIPSES]:
            if np.all(np.isfinite(fixes.cov[k, :2, :2])):
                covariance_ellipse(ax, p[k, :2], fixes.cov[k, :2, :2], n_sigma=2.0,
                                   color="tab:blue", lw=0.6, alpha=0.6)
    if (~good).any():
        ax.plot(p[~good, 0], p[~good, 1], "o", mfc="none", color="0.5", ms=5,
                label="unobservable or mirror-ambiguous")
    for tid, pts in fixes.tracks:
        line, = ax.plot(pts[:, 1], pts[:, 2], "-", lw=1.5)
        ax.annotate(f"track {tid}", (pts[-1, 1], pts[-1, 2]), fontsize=8, xytext=(3, 3),
                    textcoords="offset points")
        ax_d.plot(pts[:, 0], -pts[:, 3], "-", lw=1.5, color=line.get_color(),
                  label=f"track {tid}")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x east, m")
    ax.set_ylabel("y north, m")
    ax.set_title("plan view (ellipses: 2 sigma)")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="best")
    # depth (m, down) when everything is under the sea surface z = 0 (a range); otherwise the
    # array's own frame, height z up (a tank, a frame of hydrophones around z = 0)
    zs = np.concatenate([p[:, 2], array.positions[:, 2] if array is not None else []])
    as_depth = bool(zs.size == 0 or np.all(zs <= 0))
    sign = -1.0 if as_depth else 1.0
    if good.any():
        sz = 2.0 * np.sqrt(np.where(np.isfinite(fixes.cov[good, 2, 2]), fixes.cov[good, 2, 2],
                                    0.0))
        ax_d.errorbar(t[good], sign * p[good, 2], yerr=sz, fmt="o", ms=3, color="tab:blue",
                      capsize=2, label="sources (2 sigma)")
    if (~good).any():
        ax_d.plot(t[~good], sign * p[~good, 2], "o", mfc="none", color="0.5", ms=5)
    if array is not None:
        for z in np.unique(array.positions[:, 2]):
            ax_d.axhline(sign * z, color="k", lw=0.5, ls=":")
        ax_d.plot([], [], ":", color="k", lw=0.5,
                  label="sensor depths" if as_depth else "sensor heights")
    if as_depth:
        ax_d.invert_yaxis()
    ax_d.set_xlabel("time, s")
    ax_d.set_ylabel("depth, m" if as_depth else "height z, m (z up, array frame)")
    ax_d.set_title("depth" if as_depth else "height")
    ax_d.grid(alpha=0.3)
    if ax_d.get_legend_handles_labels()[0]:
        ax_d.legend(fontsize=7, loc="best")
    fig.suptitle(f"{title}: {int(good.sum())} sources ({int((~good).sum())} not fixed), "
                 f"{len(fixes.tracks)} tracks")
    return fig


def _best_window(windows: list[dict[str, Any]]) -> int | None:
    """Index of the window with the most valid TDOAs (None: no valid TDOA anywhere)."""
    counts = [sum(bool(d.get("valid")) for d in w.get("tdoas", [])) for w in windows]
    if not counts or max(counts) == 0:
        return None
    return int(np.argmax(counts))


def surface_reading(fixes: Fixes) -> str:
    """The counts of the window :func:`surface_figure` draws (its time, valid TDOAs, sources)."""
    k = _best_window(fixes.windows)
    if k is None:
        return "no valid TDOA in any window"
    w = fixes.windows[k]
    n_valid = sum(bool(d.get("valid")) for d in w.get("tdoas", []))
    return (f"window {w['t_start']:g}-{w['t_end']:g} s, {n_valid} valid TDOAs, "
            f"{len(w.get('sources', []))} sources")


def surface_figure(fixes: Fixes, array: SensorArray, *, title: str) -> Any | None:
    """The eq. (17) intensity of the window with the most valid TDOAs (None: no valid TDOA).

    Parameters
    ----------
    fixes : Fixes
        A localization result (events carry no windows: None).
    array : SensorArray
        The array of the recording.
    title : str, keyword-only

    Returns
    -------
    matplotlib Figure or None
        Plan view (largest intensity over depth) and depth section (largest over y), with the
        window's sources and the sensors.
    """
    from fusion.localization.surfaces import SearchRegion, WindowTdoas, intensity_volume

    k = _best_window(fixes.windows)
    if k is None:
        return None
    w = fixes.windows[k]
    valid = [d for d in w["tdoas"] if d.get("valid")]
    n = array.positions.shape[0]
    valid = [d for d in valid if all(0 <= int(i) < n for i in d["pair"])]
    if not valid:
        raise ValueError("the result's TDOA pairs name sensors the --array does not have")
    sig = [d["sigma"] if _finite(d.get("sigma")) and d["sigma"] > 0 else DEFAULT_SIGMA_S
           for d in valid]
    tdoas = WindowTdoas(array.positions, np.array([d["pair"] for d in valid], dtype=int),
                        np.array([d["tau"] for d in valid], dtype=float), np.array(sig),
                        c=array.sound_speed)
    zs = array.positions[:, 2]
    column = (float(zs.min()), 0.0) if zs.max() < 0 else None
    grid = SearchRegion(extent_factor=1.0, water_column=column, max_points=40_000).volume(
        array.positions)
    vol = intensity_volume(tdoas, grid, equation=17).values  # (nx, ny, nz)
    fig, (ax, ax_d) = new_figure(1, 2, size=(13.0, 6.0))
    im = ax.pcolormesh(grid.x, grid.y, vol.max(axis=2).T, cmap="magma", shading="nearest")
    fig.colorbar(im, ax=ax, label="eq. 17 intensity (TDOAs agreeing)", shrink=0.8)
    im_d = ax_d.pcolormesh(grid.x, -grid.z, vol.max(axis=1).T, cmap="magma", shading="nearest")
    fig.colorbar(im_d, ax=ax_d, label="eq. 17 intensity (TDOAs agreeing)", shrink=0.8)
    s = array.positions
    for a, v in ((ax, s[:, 1]), (ax_d, -s[:, 2])):
        a.plot(s[:, 0], v, "^", color="w", mec="k", ms=8, label="sensors")
    mid = 0.5 * (float(w["t_start"]) + float(w["t_end"]))
    here = np.isclose(fixes.time, mid)
    if here.any():
        p = fixes.xyz[here]
        ax.plot(p[:, 0], p[:, 1], "o", mfc="none", mec="c", ms=10, mew=2, label="sources")
        ax_d.plot(p[:, 0], -p[:, 2], "o", mfc="none", mec="c", ms=10, mew=2, label="sources")
    ax.set_xlabel("x east, m")
    ax.set_ylabel("y north, m")
    ax.set_title("plan view (largest over depth)")
    ax_d.invert_yaxis()
    ax_d.set_xlabel("x east, m")
    ax_d.set_ylabel("depth, m")
    ax_d.set_title("depth section (largest over y)")
    for a in (ax, ax_d):
        a.legend(fontsize=7, loc="best")
    fig.suptitle(f"{title}: window {w['t_start']:g}-{w['t_end']:g} s, {len(valid)} valid TDOAs")
    return fig
