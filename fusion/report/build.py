"""``fusion report``: the figures of one result, chosen by its kind.

:func:`make_report` tells the result's kind (:func:`fusion.report.kinds.detect_result`), reads
it and the optional extra inputs with the validating readers of :mod:`fusion.io`, draws the
kind's figures and writes them as PNG files into the output folder.

==========================  =================================================  ===============
kind (command)              figures                                            extra inputs
==========================  =================================================  ===============
acquisition (``acquire``)   ``btr.png``                                        cube (required),
                                                                               freq, lag
passive (``passive``)       ``passive_tracks.png`` (TQI, alerts, sigma)        --
smoothed (``smooth``)       ``smoothed.png``; ``crossings.png`` with alerts    bearings, alerts
tqi (``tqi``)               ``tqi.png``; ``tqi_bearing_time.png``              bearings
alerts (``crossings``)      ``crossings.png``; ``crossings_bearing_time.png``  bearings
tracks (``track``)          ``tracks.png``; ``tracks_sigma.png`` (--smooth)    detections
tma (``tma``)               ``tma.png``                                        ownship
localization (``localize``) ``localize.png``; ``localize_surface.png``         array
==========================  =================================================  ===============
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from fusion._output import outputs_together
from fusion.report.figures import FigureWriter
from fusion.report.index import write_summary
from fusion.report.kinds import KINDS, DetectedResult, detect_result

__all__ = ["ReportInputs", "make_report"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReportInputs:
    """Optional inputs some figures need, as given on the command line.

    Attributes
    ----------
    cube : pathlib.Path, optional
        Beam/frequency/time cube of an acquisition (``.npz``).
    freq_hz : float, optional
        Clicked frequency of an acquisition, Hz.
    lag_s : float
        ``--display-lag-s`` of the acquisition, s.
    bearings : pathlib.Path, optional
        ``track_id,time,bearing_deg`` CSV (input of crossings/smooth, bearings of tqi tracks).
    alerts : pathlib.Path, optional
        Crossing alerts CSV to draw on smoothed tracks.
    detections : pathlib.Path, optional
        Detections CSV of ``fusion track`` (the clutter map).
    ownship : pathlib.Path, optional
        Own-ship ``time,x,y`` CSV of ``fusion tma``.
    array : pathlib.Path, optional
        Array JSON of ``fusion localize`` (sensors, intensity surface).
    """

    cube: Path | None = None
    freq_hz: float | None = None
    lag_s: float = 0.0
    bearings: Path | None = None
    alerts: Path | None = None
    detections: Path | None = None
    ownship: Path | None = None
    array: Path | None = None

    def given(self) -> set[str]:
        """Names of the inputs given (``lag_s`` when not 0)."""
        return {f.name for f in fields(self) if getattr(self, f.name) not in (None, 0.0)}

    def paths(self) -> list[Path]:
        """The input files given."""
        return [v for f in fields(self) if isinstance(v := getattr(self, f.name), Path)]


#: Extra inputs each kind uses.
USES: dict[str, frozenset[str]] = {
    "acquisition": frozenset({"cube", "freq_hz", "lag_s"}),
    "passive": frozenset(),
    "passive_tracks": frozenset({"alerts"}),
    "smoothed": frozenset({"bearings", "alerts"}),
    "tqi": frozenset({"bearings"}),
    "alerts": frozenset({"bearings"}),
    "tracks": frozenset({"detections"}),
    "tma": frozenset({"ownship"}),
    "localization": frozenset({"array"}),
    "events": frozenset({"array"}),
    "localization_folder": frozenset({"array"}),
}

#: Option name of each extra input (for messages).
OPTION = {"cube": "--cube", "freq_hz": "--freq-hz", "lag_s": "--display-lag-s",
          "bearings": "--bearings",
          "alerts": "--alerts", "detections": "--detections", "ownship": "--ownship",
          "array": "--array"}


def _n_tracks(table: Any) -> int:
    return int(np.unique(np.asarray(table["track_id"])).size)


def _alert_counts(alerts: Any) -> str:
    if alerts is None:
        return "no alerts given"
    kinds = np.asarray(alerts["kind"]).astype(str)
    return (f"{len(kinds)} alerts ({int((kinds == 'predicted').sum())} predicted, "
            f"{int((kinds == 'detected').sum())} detected)")


def _state_counts(states: Any) -> str:
    s = np.asarray(states).astype(str)
    order = ("strong", "low_snr", "uncertain", "lost")
    return ", ".join(f"{name} {int((s == name).sum())}" for name in order)


def _track_counts(tracks: Any) -> str:
    """Confirmed tracks drawn, and tracks never confirmed (left out of the figure)."""
    ids = np.asarray(tracks["track_id"])
    status = np.asarray(tracks["status"]).astype(str)
    confirmed = np.unique(ids[status == "confirmed"])
    never = np.setdiff1d(np.unique(ids), confirmed)
    return f"{confirmed.size} confirmed tracks, {never.size} never confirmed (not drawn)"


def _tma_reading(result: Any) -> str:
    cols = result.columns
    obs = bool(np.all(np.asarray(cols["observable"]) != 0)) if "observable" in cols else True
    text = f"final range {float(np.asarray(cols['range'])[-1]):.0f} m"
    if "range_low" in cols:
        hi = float(np.asarray(cols["range_high"])[-1])
        text += (f" (95 % interval {float(np.asarray(cols['range_low'])[-1]):.0f}-"
                 + ("unbounded" if hi >= 1e12 else f"{hi:.0f}") + " m)")
    return text + ("; range observable" if obs else "; FLAGGED: range unobservable")


def _read_bearings(path: Path) -> Any:
    from fusion.io import read_bearings

    return read_bearings(path)


def _header_only(path: Path) -> bool:
    """Whether a CSV file holds a header line and no row (a run without alerts writes that)."""
    with path.open("rb") as fh:
        lines = [line for line in (fh.readline() for _ in range(3)) if line.strip()]
    return len(lines) == 1


def _read_alerts(path: Path) -> Any:
    from fusion.io import read_alerts, read_table
    from fusion.report.kinds import file_kind
    from fusion.types import Table

    if _header_only(path) and file_kind(path) == "alerts":
        return Table({c: np.zeros(0) for c in ("time", "track_a", "track_b", "t_cross")}
                     | {"kind": np.zeros(0, dtype=str)}, source=str(path))
    alerts = read_alerts(path)
    try:  # the interval columns, when the file has them
        extra = read_table(path, required=("t_cross_low", "t_cross_high"), max_abs=None)
    except ValueError:
        return alerts
    return Table({**alerts.columns, "t_cross_low": extra["t_cross_low"],
                  "t_cross_high": extra["t_cross_high"]}, source=alerts.source)


def _smoothed_table(path: Path, *, with_tqi: bool) -> tuple[Any, Any]:
    """A smoothed-tracks table and its TQI column (empty cells: no state yet)."""
    from fusion.io import read_smoothed, read_table

    table = read_smoothed(path)
    if not with_tqi:
        return table, None
    tqi = read_table(path, required=("track_id", "tqi"), text=("tqi",), integer=("track_id",))
    return table, np.asarray(tqi["tqi"]).astype(str)


def _passive(res: DetectedResult, extra: ReportInputs, out: FigureWriter) -> None:
    from fusion.report.bearing_time import smoothed_figure

    tracks_path = res.files[0]
    alerts = (_read_alerts(res.files[1]) if res.kind == "passive"
              else _read_alerts(extra.alerts) if extra.alerts else None)
    table, tqi = _smoothed_table(tracks_path, with_tqi=True)
    out.save(smoothed_figure(table, tqi=tqi, alerts=alerts,
                             title=f"fusion passive: {res.path}"), "passive_tracks.png",
             "bearing-time tracks with 1-sigma bands and TQI states, crossing alerts; bearing "
             f"rate; bearing sigma — {_n_tracks(table)} tracks, {_alert_counts(alerts)}")


def _smoothed(res: DetectedResult, extra: ReportInputs, out: FigureWriter) -> None:
    from fusion.report.bearing_time import alerts_figure, smoothed_figure

    table, _ = _smoothed_table(res.path, with_tqi=False)
    alerts = _read_alerts(extra.alerts) if extra.alerts else None
    raw = _read_bearings(extra.bearings) if extra.bearings else None
    out.save(smoothed_figure(table, alerts=alerts, detections=raw,
                             title=f"fusion smooth: {res.path.name}"), "smoothed.png",
             "smoothed bearing tracks with 1-sigma bands"
             + (" over the raw bearings (grey)" if raw is not None else "")
             + f", bearing rate and sigma over time — {_n_tracks(table)} tracks"
             + (f", {_alert_counts(alerts)}" if alerts is not None else ""))
    if alerts is not None and len(alerts):
        out.save(alerts_figure(alerts, title=f"crossing alerts: {extra.alerts.name}"),
                 "crossings.png", "crossing time and interval of every alert, per track pair "
                 f"— {_alert_counts(alerts)}")


def _tqi(res: DetectedResult, extra: ReportInputs, out: FigureWriter) -> None:
    from fusion.io import read_tqi
    from fusion.report.bearing_time import tqi_bearing_figure, tqi_figure

    table = read_tqi(res.path)
    bearings = _read_bearings(extra.bearings) if extra.bearings else None
    states = _state_counts(table["tqi"])
    out.save(tqi_figure(table, title=f"fusion tqi: {res.path.name}"), "tqi.png",
             "amplitude (dB), bearing residual (deg) and TQI state of every track over time "
             f"— {_n_tracks(table)} tracks, updates {states}")
    if bearings is not None:
        out.save(tqi_bearing_figure(table, bearings,
                                    title=f"TQI on the tracks of {extra.bearings.name}"),
                 "tqi_bearing_time.png", f"TQI states on the bearing tracks — updates {states}")


def _alerts(res: DetectedResult, extra: ReportInputs, out: FigureWriter) -> None:
    from fusion.report.bearing_time import alerts_figure, alerts_on_tracks_figure

    alerts = _read_alerts(res.path)
    if len(alerts) == 0 and not extra.bearings:
        raise ValueError(f"{res.path}: no alerts to draw (give --bearings to draw the tracks)")
    bearings = _read_bearings(extra.bearings) if extra.bearings else None
    if len(alerts):
        out.save(alerts_figure(alerts, title=f"fusion crossings: {res.path.name}"),
                 "crossings.png", "crossing time and interval of every alert, per track pair "
                 f"— {_alert_counts(alerts)}")
    if bearings is not None:
        out.save(alerts_on_tracks_figure(alerts, bearings,
                                         title=f"crossing alerts on {extra.bearings.name}"),
                 "crossings_bearing_time.png",
                 f"the alerts on the bearing tracks — {_n_tracks(bearings)} tracks, "
                 f"{_alert_counts(alerts)}")


def _tracks(res: DetectedResult, extra: ReportInputs, out: FigureWriter) -> None:
    from fusion.io import read_detections, read_table, read_tracks
    from fusion.report.positions import track_map_settings, track_sigma_figure, tracks_figure

    tracks = read_tracks(res.path)
    det = read_detections(extra.detections) if extra.detections else None
    try:
        sig = read_table(res.path, required=("sigma_x", "sigma_y"), max_abs=None)
    except ValueError:
        sig = None  # not a --smooth output
    counts = _track_counts(tracks)
    out.save(tracks_figure(tracks, detections=det, title=f"fusion track: {res.path.name}",
                           map_settings=track_map_settings(res.path)),
             "tracks.png", "tracks in plan view (x east, y north)"
             + (" over the clutter map of the detections" if det is not None else "")
             + f" — {counts}")
    if sig is None:
        return
    out.save(track_sigma_figure(tracks, sig["sigma_x"], sig["sigma_y"],
                                title=f"fusion track --smooth: {res.path.name}"),
             "tracks_sigma.png", f"x and y of the confirmed tracks with 1-sigma bands — {counts}")


def _tma(res: DetectedResult, extra: ReportInputs, out: FigureWriter) -> None:
    from fusion.io import read_ownship, read_table, read_tma_result
    from fusion.report.positions import tma_figure
    from fusion.types import Table

    own = read_ownship(extra.ownship) if extra.ownship else None
    result = read_tma_result(res.path)
    try:  # the range interval, when the output has it
        interval = read_table(res.path, required=("range_low", "range_high"), max_abs=None)
    except ValueError:
        interval = None
    if interval is not None:
        result = Table({**result.columns, "range_low": interval["range_low"],
                        "range_high": interval["range_high"]}, source=result.source)
    try:  # the observability flag, when the output has it
        flag = read_table(res.path, required=("observable",), max_abs=None)
    except ValueError:
        flag = None
    if flag is not None:
        result = Table({**result.columns, "observable": flag["observable"]}, source=result.source)
    out.save(tma_figure(result, ownship=own, title=f"fusion tma: {res.path.name}"), "tma.png",
             "plan view with 2-sigma bars, range with its 95 % interval and speed over time — "
             + _tma_reading(result))


def _acquisition(res: DetectedResult, extra: ReportInputs, out: FigureWriter) -> None:
    from fusion.io import read_cube, read_json
    from fusion.report.acquisition import acquisition_figure, read_acquisition

    if extra.cube is None:
        raise ValueError(f"{res.path}: an acquisition result needs --cube C.npz (the cube given "
                         "to fusion acquire) to draw its BTR")
    result = read_acquisition(read_json(res.path), source=str(res.path))
    out.save(acquisition_figure(read_cube(extra.cube), result, freq_hz=extra.freq_hz,
                                lag_s=extra.lag_s, title=f"fusion acquire: {res.path.name}"),
             "btr.png", "bearing-time record of the clicked bin with the acquired line — "
             f"bearing {result['bearing_deg']:.2f} deg, rate "
             f"{result['bearing_rate_deg_per_min']:.2f} deg/min, SNR {result['snr_db']:.1f} dB"
             + (", defaults used (no line above the noise)" if result["default_used"] else ""))


def _localization(res: DetectedResult, extra: ReportInputs, out: FigureWriter) -> None:
    from fusion.io import read_array
    from fusion.report.kinds import file_kind
    from fusion.report.localization import (
        fix_counts,
        fixes_figure,
        read_fixes,
        surface_figure,
        surface_reading,
    )

    array = read_array(extra.array) if extra.array else None
    folder = res.kind == "localization_folder"
    kinds = [file_kind(path) if folder else res.kind for path in res.files]
    read = [read_fixes(path, kind) for path, kind in zip(res.files, kinds, strict=True)]
    for path, kind, fixes in zip(res.files, kinds, read, strict=True):  # all read first
        prefix = f"{path.stem}_" if folder else ""
        out.save(fixes_figure(fixes, array=array, title=f"fusion localize: {path.name}"),
                 f"{prefix}localize.png", "sources in plan view with 2-sigma ellipses, depth "
                 f"(or height in the array's frame) over time — {fix_counts(fixes, kind)}")
        if array is not None and kind == "localization":
            fig = surface_figure(fixes, array, title=f"intensity surface: {path.name}")
            if fig is None:
                logger.warning("%s: no valid TDOA in any window; no intensity surface", path)
            else:
                out.save(fig, f"{prefix}localize_surface.png",
                         "eq. 17 intensity of the window with the most valid TDOAs, plan view "
                         f"and depth section, with its sources — {surface_reading(fixes)}")


DRAW: dict[str, Callable[[DetectedResult, ReportInputs, FigureWriter], None]] = {
    "acquisition": _acquisition,
    "passive": _passive,
    "passive_tracks": _passive,
    "smoothed": _smoothed,
    "tqi": _tqi,
    "alerts": _alerts,
    "tracks": _tracks,
    "tma": _tma,
    "localization": _localization,
    "events": _localization,
    "localization_folder": _localization,
}


def make_report(result: str | Path, out_dir: str | Path, *,
                inputs: ReportInputs | None = None) -> tuple[str, list[Path]]:
    """Draw the figures of a ``fusion`` result into `out_dir`.

    Parameters
    ----------
    result : path-like
        A result file or output folder of a ``fusion`` command (see :mod:`fusion.report.kinds`).
    out_dir : path-like
        Folder for the PNG files (created if missing).
    inputs : ReportInputs, optional, keyword-only
        Extra inputs; each must be one the result's kind uses.

    Returns
    -------
    kind : str
        The result's kind.
    written : list of pathlib.Path
        The PNG files written, then ``summary.md`` (each figure with its one-line reading;
        :mod:`fusion.report.index`).

    Raises
    ------
    ValueError
        An unknown result, an extra input the kind does not use, a missing required input, or
        bad content in any input (one line naming the file). Every input is read before any
        figure is drawn, and the figures are committed together: a failure writes none.
    """
    extra = inputs or ReportInputs()
    found = detect_result(result)
    unused = sorted(extra.given() - USES[found.kind])
    if unused:
        names = ", ".join(OPTION[u] for u in unused)
        raise ValueError(f"{names}: not used for a result of {KINDS[found.kind]} ({result})")
    out = FigureWriter(out_dir, inputs=[*found.files, *extra.paths()])
    with outputs_together(out_dir):  # every figure and the index, or none (an input found bad late)
        DRAW[found.kind](found, extra, out)
        index = write_summary(Path(out_dir), f"{found.path} ({KINDS[found.kind]})", out.readings)
    return found.kind, [*out.written, index]
