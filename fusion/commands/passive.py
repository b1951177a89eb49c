"""``fusion passive --cube C.npz [--cube C2.npz ...] (--click B,F | --clicks K.csv | --auto) --out DIR``.

Runs the passive pipeline (:class:`fusion.pipelines.passive.PassivePipeline`) over one cube or
consecutive cubes of one recording and writes into DIR:

- ``tracks.csv``: ``track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg,tqi``,
  one row per track per scan, fixed-lag smoothed; ``tqi`` is empty at a track's first state
  (the acquisition's prior, before any update);
- ``alerts.csv``: ``time,track_a,track_b,t_cross,kind``, the crossing alerts.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from fusion._output import atomic_outputs
from fusion.cli import DB_RANGE, MAX_SCANS_OPTION, emit, number, summary
from fusion.io import read_cube, read_table, write_settings, write_table

logger = logging.getLogger(__name__)


def _click(text: str):
    """``BEAM,FREQ`` or ``BEAM,FREQ,TIME`` (an argparse type)."""
    from fusion.pipelines.passive.types import Click

    parts = text.split(",")
    try:
        if len(parts) not in (2, 3):
            raise ValueError
        beam, freq = int(parts[0]), float(parts[1])
        time = float(parts[2]) if len(parts) == 3 else None
        return Click(beam, freq, time)
    except ValueError as e:
        detail = f": {e}" if str(e) else ""
        raise argparse.ArgumentTypeError(
            f"{text!r} is not BEAM,FREQ or BEAM,FREQ,TIME{detail}") from None


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``passive`` subcommand."""
    p = sub.add_parser(
        "passive",
        help="track narrowband lines through beam/frequency/time cubes",
        description=(
            "Passive narrowband tracking: clicked (or automatically found) lines are acquired, "
            "each track's bearing and bearing rate is held in a GTSAM fixed-lag graph, the track "
            "quality indicator ends lost tracks, and predicted crossings are resolved through "
            "the association-weighted multi-track graph. Several --cube files are consecutive "
            "parts of one recording. Writes tracks.csv and alerts.csv into --out."
        ),
    )
    p.add_argument("--cube", type=Path, action="append", required=True,
                   help="cube .npz (repeat for consecutive cubes of one recording)")
    starts = p.add_mutually_exclusive_group(required=True)
    starts.add_argument("--click", type=_click, action="append", metavar="BEAM,FREQ[,TIME]",
                        help="an operator click (repeatable); without TIME as soon as the "
                             "acquisition window is full")
    starts.add_argument("--clicks", type=Path, help="CSV of clicks: beam,freq[,time]")
    starts.add_argument("--auto", action="store_true",
                        help="start tracks automatically on the strongest lines")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    g = p.add_argument_group("pipeline")
    g.add_argument("--acq-scans", type=number(int, ge=3, le=MAX_SCANS_OPTION), default=60,
                   help="scans the acquisition looks back over, scans (default 60)")
    g.add_argument("--graph-lag-s", dest="lag", type=number(float, gt=0), default=200.0,
                   help="fixed lag of the tracks' graphs, s (default 200)")
    g.add_argument("--accel-sigma-deg-per-min2", dest="accel_sigma", type=number(float, gt=0), default=2.0,
                   help="bearing-acceleration standard deviation, deg/min^2 (default 2)")
    g.add_argument("--beam-sigma-beams", dest="beam_sigma", type=number(float, gt=0), default=0.5,
                   help="standard deviation of a measured peak, beams (default 0.5)")
    g.add_argument("-J", "--window-samples", dest="window",
                   type=number(int, ge=3, le=MAX_SCANS_OPTION), default=12, metavar="J",
                   help="crossing detector: samples per least-squares window, samples (default 12)")
    g.add_argument("-K", "--period-s", dest="period", type=number(float, gt=0), default=None, metavar="K",
                   help="crossing detector: sample period, s (default 5 scan periods)")
    g.add_argument("--snr0-db", type=number(float, ge=DB_RANGE[0], le=DB_RANGE[1]), default=3.0,
                   help="TQI design SNR of the tracker threshold, dB (default 3)")
    g.add_argument("--snr1-db", type=number(float, ge=DB_RANGE[0], le=DB_RANGE[1]), default=10.0,
                   help="TQI design SNR of a strong track, dB (default 10)")
    norm = g.add_mutually_exclusive_group()
    norm.add_argument("--normalize", dest="normalize", action="store_const", const=True,
                      default=None,
                      help="normalise the cubes to unit noise mean first (split-window median "
                           "over frequency, pooled over 60 scans); default: when a cube's median "
                           "noise level (first 60 scans) is outside 0.8-1.25, as printed")
    norm.add_argument("--no-normalize", dest="normalize", action="store_const", const=False,
                      help="the cubes are already normalised to unit noise mean: use them as read")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (none either when standard error is not a terminal)")
    p.set_defaults(handler=run, inputs=("cube", "clicks"), out_is_dir=True,
                   out_files=("tracks.csv", "alerts.csv"))


def _read_clicks(path: Path) -> list:
    from fusion.pipelines.passive.types import Click

    table = read_table(path, required=("beam", "freq"), optional=("time",), integer=("beam",))
    times = table["time"] if "time" in table else [None] * len(table)
    try:
        return [Click(int(b), float(f), None if t is None else float(t))
                for b, f, t in zip(table["beam"], table["freq"], times, strict=True)]
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None


def run(args: argparse.Namespace) -> int:
    """Read the cubes and clicks, run the pipeline, write the tracks and alerts."""
    from fusion._progress import progress
    from fusion.passive.acquisition import Acquisition, LineStarter
    from fusion.passive.crossing import CrossingDetector
    from fusion.passive.quality import TrackQualityIndicator
    from fusion.pipelines.passive import PassivePipeline, SmootherSettings
    from fusion.pipelines.passive.noise import unit_noise_cubes

    if not args.snr1_db > args.snr0_db:
        raise ValueError(f"--snr1-db ({args.snr1_db:g}) must exceed --snr0-db ({args.snr0_db:g})")
    cubes = [read_cube(c) for c in args.cube]
    cubes, normalised, notes = unit_noise_cubes(cubes, args.normalize,
                                                [str(c) for c in args.cube])
    n_scans = sum(c.n_scans for c in cubes)
    if n_scans < args.acq_scans:
        raise ValueError(f"the cubes hold {n_scans} scans, fewer than --acq-scans "
                         f"{args.acq_scans}: no track can start")
    clicks = list(args.click or []) + (_read_clicks(args.clicks) if args.clicks else [])
    period = 5.0 * cubes[0].scan_period if args.period is None else args.period
    pipe = PassivePipeline(
        acquisition=Acquisition(),
        tqi=TrackQualityIndicator(snr0_db=args.snr0_db, snr1_db=args.snr1_db),
        crossing=CrossingDetector(J=args.window, K=period),
        smoother=SmootherSettings(lag_s=args.lag, accel_sigma_deg_per_min2=args.accel_sigma,
                                  beam_sigma=args.beam_sigma),
        starter=LineStarter() if args.auto else None,
        acquisition_scans=args.acq_scans,
    )
    bar = progress(n_scans, quiet=args.quiet, desc="passive", unit="scan")
    try:
        res = pipe.run(cubes, clicks, on_scan=bar.update)
    finally:
        bar.close()
    out = Path(args.out)
    with atomic_outputs(out / "tracks.csv", out / "alerts.csv") as (tracks, alerts):
        write_table(tracks, res.track_columns())  # both renamed into place together
        write_table(alerts, res.alert_columns())
    write_settings(out / "passive", {"command": "passive", "normalize": normalised,
                                     "crossing_period_s": period},
                   inputs=[*args.cube, args.clicks])
    for note in notes:
        emit(note, err=True)
    n_lost = sum(t.end is not None for t in res.tracks)
    n_pred = int(np.sum(res.alert_columns()["kind"] == "predicted"))
    near = [r.fallback for r in res.resolutions if r.method == "nearest"]
    why = "" if not near else (f" ({len(near)} by nearest assignment: " + ", ".join(
        f"{near.count(w)} {w}" for w in sorted(set(near))) + ")")
    summary("passive", f"{len(res.tracks)} track(s) ({n_lost} ended lost) over {res.n_scans} "
            f"scans, {len(res.alerts)} alert(s) ({n_pred} predicted), {len(res.resolutions)} "
            f"crossing(s) resolved{why} -> {out}/tracks.csv, {out}/alerts.csv")
    return 0
