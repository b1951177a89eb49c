"""``fusion track --detections D.csv --out T.csv``: multistatic active tracking.

Reads position detections (``event,time,x,y`` plus optional clue columns ``snr_db, score,
aspect_deg, src_x, src_y, rcv_x, rcv_y``) and writes one row per track per event:
``track_id,event,time,x,y,vx,vy,status``. Clue columns absent from the file leave the rules that
read them out of the rank; the command says so once on stderr. With ``src_x, src_y, rcv_x, rcv_y``
each detection's position error is the bistatic error ellipse propagated from the range-sum and
bearing accuracies, learnt per receiver from the data starting from ``--range-sum-sigma`` and
``--bearing-sigma`` (``--noise fixed``: those values for every receiver); without them (e.g.
radar), or with ``--position-errors isotropic``, it is ``--position-sigma`` per axis. The
equivalent aspect angle comes from each track's heading and the source/receiver positions; an
``aspect_deg`` column is used only with ``--aspect-column measured`` (nothing in a file says how
it was obtained). With ``--smooth`` each confirmed track is refined with all of its detections on
a factor graph (:mod:`fusion.active.smoothing`) and every row gets ``sigma_x, sigma_y`` (m).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from fusion.cli import emit, number
from fusion.io import read_detections, write_table

_POSITIONS = ("src_x", "src_y", "rcv_x", "rcv_y")


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``track`` subcommand."""
    p = sub.add_parser(
        "track",
        help="track targets in active-sonar (or any position) detections",
        description="Kalman prediction + fuzzy-logic association (or Kalman nearest neighbour), "
                    "clutter map, M-of-N confirmation.",
    )
    p.add_argument("--detections", type=Path, required=True, help="detections CSV")
    p.add_argument("--out", type=Path, required=True, help="output tracks CSV")
    p.add_argument("--mode", choices=("fuzzy", "kalman"), default="fuzzy",
                   help="association: fuzzy rank (default) or Kalman likelihood alone")
    p.add_argument("--rules", type=Path, default=None,
                   help="fuzzy system JSON file (default: the built-in rule base)")
    p.add_argument("--position-sigma", type=number(float, gt=0), default=100.0,
                   help="position error of a detection per axis, m, for detections without "
                        "source/receiver positions (default 100)")
    p.add_argument("--position-errors", choices=("geometry", "isotropic"), default="geometry",
                   help="position error of detections with src_x,src_y,rcv_x,rcv_y: bistatic "
                        "error ellipse from range-sum and bearing accuracies (default) or "
                        "--position-sigma per axis")
    p.add_argument("--range-sum-sigma", type=number(float, gt=0), default=100.0,
                   help="bistatic range-sum accuracy (standard deviation), m: the start of the "
                        "per-receiver estimate, or the value itself with --noise fixed "
                        "(default 100)")
    p.add_argument("--bearing-sigma", type=number(float, gt=0), default=1.5,
                   help="receiver bearing accuracy (standard deviation), deg; as "
                        "--range-sum-sigma (default 1.5)")
    p.add_argument("--noise", choices=("estimate", "fixed"), default="estimate",
                   help="range-sum and bearing accuracies: learnt per receiver from echoes that "
                        "recur (default) or --range-sum-sigma/--bearing-sigma for all")
    p.add_argument("--aspect-column", choices=("ignored", "measured"), default="ignored",
                   help="an aspect_deg column is ignored (default: the aspect comes from the "
                        "track heading and the source/receiver positions) or used as a "
                        "measurement")
    p.add_argument("--score-threshold", type=number(float, ge=0, le=1), default=None,
                   help="classifier-score gate: detections with a lower score join no track "
                        "(default: no gate)")
    p.add_argument("--confirm-llr", type=number(float), default=3.0,
                   help="track score (log-likelihood ratio, target against clutter) a tentative "
                        "track needs besides its M-of-N hits (default 3)")
    p.add_argument("--no-track-score", action="store_true",
                   help="confirm on M-of-N hits alone (the paper), no track score")
    p.add_argument("--detection-probability", type=number(float, gt=0, le=0.999), default=None,
                   help="probability that a receiver detects a track on a ping, for the track "
                        "score (default: estimated from confirmed tracks)")
    p.add_argument("--clutter-density", type=number(float, gt=0), default=None,
                   help="clutter detections per m^2 per ping and receiver, for the track score "
                        "(default: estimated over the field from the detections)")
    p.add_argument("--min-speed", type=number(float, ge=0), default=0.5,
                   help="speeds up to this count as standing still in the motion test, m/s "
                        "(default 0.5)")
    p.add_argument("--accel-psd", type=number(float, ge=0), default=0.04,
                   help="white-acceleration spectral density, m^2/s^3 (default 0.04)")
    p.add_argument("--min-rank", type=number(float, ge=0, le=1), default=None,
                   help="lowest fuzzy rank associated, one value for all pairs (default: derived "
                        "from the rule base for the clues present, at likelihood ratio 0.25)")
    p.add_argument("--confirm", type=number(int, ge=1), nargs=2, default=(3, 4), metavar=("M", "N"),
                   help="confirm after M hits in the first N pings (default 3 4)")
    p.add_argument("--max-misses", type=number(int, ge=1), default=5,
                   help="consecutive misses deleting a confirmed track (default 5)")
    p.add_argument("--confirm-stationary", action="store_true",
                   help="fuzzy mode: confirm a track on its hits alone, even when its own "
                        "detections do not move (default: such a track is held tentative until "
                        "it moves or the clutter map flags it)")
    p.add_argument("--clutter-map", choices=("density", "grid"), default="density",
                   help="clutter map: recurrence judged with each detection's own error "
                        "ellipse (default) or counted in fixed grid cells")
    p.add_argument("--hotspot-cell", type=number(float, gt=0), default=150.0,
                   help="--clutter-map grid: cell size, m (default 150)")
    p.add_argument("--confirmed-only", action="store_true",
                   help="write only rows of tracks that were confirmed at some point")
    p.add_argument("--smooth", action="store_true",
                   help="refine each confirmed track with all of its detections on a factor graph "
                        "(fixed-interval smoother) and append sigma_x, sigma_y (m) to every row")
    p.set_defaults(handler=run, inputs=("detections", "rules"))


def run(args: argparse.Namespace) -> int:
    """Track the detections and write the tracks."""
    from fusion.active.clutter import ClutterMap, DensityClutterMap
    from fusion.active.tracker import Tracker

    if args.confirm[0] > args.confirm[1]:
        raise ValueError(f"--confirm: M must not exceed N, got {args.confirm[0]} {args.confirm[1]}")
    if args.smooth and args.accel_psd <= 0:
        raise ValueError("--smooth needs --accel-psd > 0")
    table = read_detections(args.detections)
    system = None
    if args.mode == "fuzzy" and args.rules is not None:
        from fusion.active.fuzzy import load_system

        system = load_system(args.rules)
    try:
        tracker = Tracker(
            mode=args.mode,
            system=system,
            position_sigma_m=args.position_sigma,
            position_errors=args.position_errors,
            range_sum_sigma_m=args.range_sum_sigma,
            bearing_sigma_deg=args.bearing_sigma,
            noise=args.noise,
            aspect="measured" if args.aspect_column == "measured" else "geometry",
            score_threshold=args.score_threshold,
            confirm_llr=None if args.no_track_score else args.confirm_llr,
            detection_probability=args.detection_probability,
            clutter_intensity=args.clutter_density,
            min_speed_mps=args.min_speed,
            accel_psd=args.accel_psd,
            min_rank=args.min_rank,
            confirm_hits=args.confirm[0],
            confirm_window=args.confirm[1],
            max_misses=args.max_misses,
            hold_stationary=not args.confirm_stationary,
            clutter_map=(ClutterMap(cell_m=args.hotspot_cell, position_sigma_m=args.position_sigma)
                         if args.clutter_map == "grid"
                         else DensityClutterMap(position_sigma_m=args.position_sigma)),
        )
    except ValueError as e:
        raise ValueError(f"bad option: {e}") from None
    if args.mode == "fuzzy":
        absent = [c for c in ("score", "snr_db") if c not in table]
        measured = args.aspect_column == "measured" and "aspect_deg" in table
        if not measured and not all(c in table for c in _POSITIONS):
            absent.append("src_x, src_y, rcv_x, rcv_y (aspect_deg from the track heading)"
                          if args.aspect_column == "ignored" else
                          "aspect_deg (or src_x, src_y, rcv_x, rcv_y)")
        if absent:
            emit(f"fusion track: note: {args.detections} has no {', '.join(absent)}; "
                 "the rules reading them are left out of the rank", err=True)
        # The note above replaces the fuzzy engine's own warning.
        logging.getLogger("fusion.active.fuzzy").setLevel(logging.ERROR)
    from fusion.active.types import pings_from_columns

    result = tracker.run(pings_from_columns(table))
    cols = result.columns()
    if args.smooth:
        from fusion.active.smoothing import TrackSmoother, smooth_tracks

        smoother = TrackSmoother(accel_psd=tracker.accel_psd,
                                 speed_sigma_mps=tracker.speed_sigma_mps)
        cols = smooth_tracks(result, smoother).columns
    if args.confirmed_only:
        import numpy as np

        keep = np.isin(cols["track_id"], result.confirmed_ids())
        cols = {k: v[keep] for k, v in cols.items()}
    write_table(args.out, cols)
    logging.getLogger(__name__).info("%d tracks confirmed", result.confirmed_ids().size)
    return 0
