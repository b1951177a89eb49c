"""``fusion localize --events E.csv``: localize events found by any detector.

``E.csv`` lists events, one a row: ``t_start,t_end`` (s from the start of the audio) and,
optionally, ``f_low,f_high`` (Hz; a zero ``f_low`` means from the band floor). Without the band
columns each event's band is estimated from its spectrum against the background before it.
The audio is one multichannel file (channel i = sensor i) or one mono file per sensor in array
order (trimmed to the shortest with a warning; a sample-rate mismatch is an error).

Per event (:class:`fusion.localization.events.EventLocalizer`): band-passed cross-correlation TDOAs of
every pair with sub-sample precision and data sigmas, triangle-closure screening, the
factor-graph solve with covariance and the eq. (17) intensity surface as a check. The result
JSON::

    {"events": [{"t_start", "t_end", "f_low", "f_high", "band_source",
                 "x", "y", "z", "cov", "interval_95": {"x": [lo, hi], "y": .., "z": ..},
                 "tdoas": [{"pair", "tau", "sigma", "used"}], "tdoas_used",
                 "residual_rms_s", "closure_rms_s", "variance_factor",
                 "observable", "in_region", "surface_agrees", "surface_peak"}],
     "sound_speed": c, "sample_rate": fs}

Numbers that do not exist (the covariance of an unobservable position) are ``null``, and so is
``surface_agrees`` when the surface check is off. The
``localize`` command adds ``--events`` and calls :func:`run_events`; :func:`add_event_options`
adds this mode's options.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from fusion.cli import number, summary

__all__ = ["add_event_options", "event_document", "read_events", "run_events"]


def add_event_options(parser: argparse.ArgumentParser) -> None:
    """Add the options of the event mode (all optional, each with the library's default)."""
    g = parser.add_argument_group("events (--events)")
    g.add_argument("--event-band-floor-hz", dest="event_band_floor",
                   type=number(float, gt=0), default=10.0, metavar="HZ",
                   help="lowest band edge of an event, Hz; a zero f_low is raised to it "
                        "(default 10)")
    g.add_argument("--event-default-band-hz", dest="event_default_band",
                   type=number(float, gt=0), nargs=2, default=None,
                   metavar=("LOW", "HIGH"),
                   help="band of an event without f_low/f_high whose band cannot be estimated "
                        "(default: the band floor to 0.45 of the sample rate)")
    g.add_argument("--event-region-apertures", dest="event_region", type=number(float, gt=0),
                   default=3.0, metavar="APERTURES",
                   help="half-width of the search box in array apertures (default 3)")
    g.add_argument("--event-no-surface", action="store_true",
                   help="skip the intensity-surface check")


def read_events(path: Path) -> list:
    """Events of an events CSV (``t_start,t_end[,f_low,f_high]``), checked row by row."""
    from fusion.io import read_table
    from fusion.localization.events import Event

    table = read_table(path, required=("t_start", "t_end"), optional=("f_low", "f_high"))
    cols = table.columns
    n = len(cols["t_start"])
    lows = cols.get("f_low", [None] * n)
    highs = cols.get("f_high", [None] * n)
    events = []
    for k in range(n):
        lo = None if lows[k] is None else float(lows[k])
        hi = None if highs[k] is None else float(highs[k])
        try:
            events.append(Event(float(cols["t_start"][k]), float(cols["t_end"][k]), lo, hi))
        except ValueError as e:
            raise ValueError(f"{path}: data row {k + 1}: {e}") from None
    return events


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def event_document(fixes: list, *, sound_speed: float, fs: float) -> dict[str, Any]:
    """The result JSON of a list of :class:`fusion.localization.events.EventFix` (NaN -> null)."""
    rows = []
    for f in fixes:
        cov = [[_num(v) for v in row] for row in np.asarray(f.covariance)]
        iv = {a: [_num(f.interval_95[k, 0]), _num(f.interval_95[k, 1])]
              for k, a in enumerate("xyz")}
        t = f.tdoas
        rows.append({
            "t_start": f.event.t_start, "t_end": f.event.t_end,
            "f_low": f.band_hz[0], "f_high": f.band_hz[1], "band_source": f.band_source,
            "x": _num(f.position[0]), "y": _num(f.position[1]), "z": _num(f.position[2]),
            "cov": cov, "interval_95": iv,
            "tdoas": [{"pair": [int(i), int(j)], "tau": float(tau),
                       "sigma": _num(float(sig)), "used": bool(u)}
                      for (i, j), tau, sig, u in zip(t.pairs, t.taus, t.sigmas, f.used,
                                                      strict=True)],
            "tdoas_used": f.n_used,
            "residual_rms_s": _num(f.residual_rms_s),
            "closure_rms_s": _num(f.closure_rms_s),
            "variance_factor": _num(f.variance_factor),
            "observable": f.observable, "in_region": f.in_region,
            "surface_agrees": f.surface_agrees,
            "surface_peak": {a: _num(f.surface_peak[k]) for k, a in enumerate("xyz")},
        })
    return {"events": rows, "sound_speed": sound_speed, "sample_rate": fs}


def run_events(args: argparse.Namespace) -> int:
    """Localize the events of ``args.events`` in ``args.audio``; write ``args.out`` (JSON).

    Reads ``args.audio`` (list of paths), ``args.array``, ``args.events``, ``args.out`` and the
    options of :func:`add_event_options` (their defaults when absent).
    """
    from fusion.io import read_array, read_audio_files, write_json
    from fusion.localization.events import EventLocalizer

    array = read_array(args.array)
    events = read_events(Path(args.events))
    audio, fs = read_audio_files([Path(p) for p in args.audio], array.n_sensors)
    floor = float(getattr(args, "event_band_floor", 10.0))
    default_band = getattr(args, "event_default_band", None)
    if default_band is not None and not default_band[0] < default_band[1]:
        raise ValueError(f"--event-default-band-hz: low edge {default_band[0]:g} must be below the "
                         f"high edge {default_band[1]:g}")
    if floor >= 0.45 * fs:
        raise ValueError(f"--event-band-floor-hz {floor:g} Hz is above 0.45 of the sample rate "
                         f"{fs:g} Hz")
    localizer = EventLocalizer(
        band_floor_hz=floor,
        default_band_hz=None if default_band is None else tuple(default_band),
        region_apertures=float(getattr(args, "event_region", 3.0)),
        surface=not bool(getattr(args, "event_no_surface", False)))
    fixes = localizer.localize(audio, fs, array, events)
    write_json(args.out, event_document(fixes, sound_speed=array.sound_speed, fs=fs))
    n_obs = sum(f.observable for f in fixes)
    summary("localize", f"{len(fixes)} events, {n_obs} localized (observable) -> {args.out}",
            err=True)
    return 0
