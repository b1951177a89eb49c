"""``fusion smooth --bearings B.csv --out S.csv``: bearing-rate smoothing on factor graphs.

Rows with ``track_id >= 0`` are smoothed track by track (batch Levenberg-Marquardt); rows with
``track_id`` -1 are detections of unknown origin, formed into tracks and smoothed jointly through
crossings (:class:`fusion.passive.smoothing.MultiTrackSmoother`). Rows out of time order are
sorted (one warning); two rows of one labelled track at the same time are an error. Output
(``docs/formats.md``, section 7):
``track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg``, bearings in [0, 360)
when every input bearing is >= 0, else in [-180, 180).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from fusion.cli import number
from fusion.io import read_bearings, write_table
from fusion.passive.smoothing import BearingSmoother, MultiTrackSmoother, smooth_bearings

logger = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``smooth`` subcommand."""
    p = sub.add_parser(
        "smooth",
        help="smooth bearing tracks (labelled, or detections of unknown origin)",
        description="Bearing-rate smoothing on factor graphs; track_id -1 rows are detections "
        "of unknown origin, tracked and smoothed jointly through crossings.",
    )
    p.add_argument("--bearings", type=Path, required=True, help="input CSV track_id,time,bearing_deg")
    p.add_argument("--out", type=Path, required=True, help="output CSV")
    p.add_argument("--sigma-bearing-deg", type=number(float, gt=0), default=0.5,
                   help="bearing measurement standard deviation, deg (default 0.5)")
    p.add_argument("--q-deg2-per-s3", type=number(float, gt=0), default=3e-6,
                   help="bearing acceleration PSD, deg^2/s^3 (default 3e-6)")
    p.add_argument("--robust", choices=("none", "huber", "cauchy"), default="huber",
                   help="loss on the bearing factors of labelled tracks (default huber)")
    p.add_argument("--clutter-density", type=number(float, gt=0), default=0.1,
                   help="false detections per scan per radian (default 0.1)")
    p.add_argument("--p-detect", type=number(float, gt=0, le=1), default=0.9,
                   help="probability that a track is detected in a scan, (0, 1] (default 0.9)")
    p.add_argument("--min-length", type=number(int, ge=2), default=5,
                   help="fewest detections of a track formed from unknown-origin rows, >= 2 "
                        "(default 5)")
    p.set_defaults(handler=run, inputs=("bearings",))


def run(args: argparse.Namespace) -> int:
    """Read, smooth, write."""
    table = read_bearings(args.bearings)
    ids, times = table["track_id"], table["time"]
    short = [int(k) for k in np.unique(ids[ids >= 0]) if np.unique(times[ids == k]).size < 2]
    if short:
        listed = ", ".join(map(str, short[:5])) + (", ..." if len(short) > 5 else "")
        raise ValueError(f"{args.bearings}: track(s) {listed} have fewer than 2 distinct times; "
                         "a bearing rate needs at least 2 samples per track")
    sigma = np.radians(args.sigma_bearing_deg)
    q = args.q_deg2_per_s3 * np.radians(1.0) ** 2
    single = BearingSmoother(sigma_bearing=sigma, q=q, robust=args.robust)
    multi = MultiTrackSmoother(sigma_bearing=sigma, q=q, clutter_density=args.clutter_density,
                               p_detect=args.p_detect, min_length=args.min_length)
    bearing_deg = table["bearing_deg"]
    tracks = smooth_bearings(table["track_id"], table["time"], np.radians(bearing_deg),
                             single=single, multi=multi)
    to_360 = bool(np.all(bearing_deg >= 0))
    cols: dict[str, list[np.ndarray]] = {k: [] for k in (
        "track_id", "time", "bearing_deg", "bearing_rate_deg_per_min", "sigma_bearing_deg")}
    for tr in tracks:
        b = np.degrees(tr.bearing)
        cols["track_id"].append(np.full(len(tr), tr.track_id, np.int64))
        cols["time"].append(tr.times)
        cols["bearing_deg"].append(np.mod(b, 360.0) if to_360 else b)
        cols["bearing_rate_deg_per_min"].append(np.degrees(tr.rate) * 60.0)
        cols["sigma_bearing_deg"].append(np.degrees(tr.sigma_bearing))
    out = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in cols.items()}
    write_table(args.out, out)
    logger.info("wrote %d tracks to %s", len(tracks), args.out)
    return 0
