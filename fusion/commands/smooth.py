"""``fusion smooth --bearings B.csv --out S.csv``: bearing-rate smoothing on factor graphs.

Rows with ``track_id >= 0`` are smoothed track by track (batch Levenberg-Marquardt); rows with
``track_id`` -1 are detections of unknown origin, formed into tracks and smoothed jointly through
crossings (:class:`fusion.passive.smoothing.MultiTrackSmoother`). Rows out of time order are
sorted (one warning); two rows of one labelled track at the same time are an error. Output
(``docs/formats.md``, section 7):
``track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg``, bearings in [0, 360)
when every input bearing is >= 0, else in [-180, 180).

Settings not given are fitted to the input (:func:`fusion.pipelines.bearing_smoothing.
fit_smoothing`, as the library's :func:`fusion.smooth_bearings` does): scan period, bearing
noise, clutter density, detection probability, bearing acceleration PSD and the track rules
that follow from them. One line says what was
chosen; the same goes to ``S.settings.json`` beside ``S.csv`` (not with ``--out -``).

With ``--output-times grid`` each track is written on the regular grid of the period
(:func:`fusion.passive.smoothing.grid.on_grid`), through gaps up to ``--max-gap-scans`` periods.
The default stays at the smoother's own times: on the Autoferry camera bearings the grid gave
``fusion crossings`` the same detected crossings with more false alarms (RESULTS.md, issue 18).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from fusion._progress import progress
from fusion.cli import MAX_SCANS_OPTION, emit, number
from fusion.io import read_bearings, write_settings, write_table
from fusion.passive.smoothing.multitrack import ASSOCIATIONS, END_DETECTIONS
from fusion.pipelines.bearing_smoothing import (
    LINK_PATH_ALPHA,
    SHORT_LINK_Q_DEG2_PER_S3,
    check_track_lengths,
    fit_smoothing,
    smooth_bearings,
)

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
    p.add_argument("--bearing-sigma-deg", dest="sigma_bearing_deg", type=number(float, gt=0), default=None,
                   help="bearing measurement standard deviation, deg (default: estimated from "
                        "the scatter of the detections)")
    p.add_argument("--period-s", "-K", dest="period_s", type=number(float, gt=0), default=None,
                   help="sample period of the output grid and of the scan model, s (default: "
                        "the median step between distinct times, labelled tracks and "
                        "unknown-origin rows pooled)")
    p.add_argument("--association", choices=ASSOCIATIONS, default="weighted",
                   help="weights of the bearing factors shared around crossings: posterior "
                        "association probabilities (weighted, default) or a gated nearest "
                        "assignment per scan (nearest, the baseline)")
    p.add_argument("--end-extension", dest="extend_ends",
                   action=argparse.BooleanOptionalAction, default=False,
                   help="unknown-origin rows: extend a track over the ambiguous detections "
                        "before its first and after its last segment (where it starts or ends "
                        "beside another track), weighted like the detections of its gaps "
                        "(default: off; on real camera bearings it added false crossing alerts)")
    p.add_argument("--start-extension", dest="extend_starts",
                   action=argparse.BooleanOptionalAction, default=False,
                   help="unknown-origin rows: extend a track over the ambiguous detections "
                        "before its first segment only, as --end-extension does (default: off)")
    p.add_argument("--short-link-accel-psd-deg2-per-s3", dest="short_link_q_deg2_per_s3",
                   type=number(float, ge=0), default=SHORT_LINK_Q_DEG2_PER_S3,
                   help="unknown-origin rows: a chain of segments too short to be kept is "
                        "offered a link to a later track start with this bearing acceleration "
                        f"PSD, deg^2/s^3 (default {SHORT_LINK_Q_DEG2_PER_S3:g}; 0: off)")
    p.add_argument("--link-path-alpha", type=number(float, ge=0, le=0.5), default=LINK_PATH_ALPHA,
                   help="unknown-origin rows: refuse a segment link whose gap has scans with "
                        "no detection near the link's path that a target detected with the "
                        "fitted P_D would miss with probability below this (default "
                        f"{LINK_PATH_ALPHA:g}; 0: off)")
    p.add_argument("--end-detections", choices=END_DETECTIONS, default="own",
                   help="with --end-extension: extend a track's ends only over the detections "
                        "the initial tracker gave the track its end segment came from or left "
                        "shared with it (own, default), or over any it took (tracked)")
    p.add_argument("--link-gate", type=number(float, gt=0), default=30.0,
                   help="unknown-origin rows: gate on the squared Mahalanobis distance (2 "
                        "degrees of freedom) of a link between two segments of one track "
                        "(default 30)")
    p.add_argument("--relink-gate", type=number(float, gt=0), default=100.0,
                   help="unknown-origin rows: the wider gate of a second link assignment "
                        "among the segment ends and starts the first left unlinked (default "
                        "100; not above --link-gate: no second assignment)")
    p.add_argument("--crossing-gap-scans", type=number(int, ge=1, le=MAX_SCANS_OPTION),
                   default=60,
                   help="unknown-origin rows: longest gap, in scans, a link may bridge across "
                        "a crossing (an ambiguous scan in the gap; slow crossings keep two "
                        "tracks ambiguous for long); default 60, not above --max-gap-scans: "
                        "off")
    p.add_argument("--link-curvature", action=argparse.BooleanOptionalAction, default=True,
                   help="unknown-origin rows: a link between two segments propagates the "
                        "bearing with their mean bearing acceleration (default: on; "
                        "--no-link-curvature: constant rate)")
    p.add_argument("--output-times", choices=("grid", "states"), default="states",
                   help="states (default): the smoother's own state times; grid: every track "
                        "on the regular grid of --period-s through gaps up to --max-gap-scans "
                        "periods, with its sigma")
    p.add_argument("--accel-psd-deg2-per-s3", dest="q_deg2_per_s3", type=number(float, gt=0), default=None,
                   help="bearing acceleration PSD, deg^2/s^3 (default: estimated from the "
                        "changes of the bearing rate along tracks, checked against the "
                        "growth of second differences with the lag)")
    p.add_argument("--robust", choices=("none", "huber", "cauchy"), default="huber",
                   help="loss on the bearing factors of labelled tracks (default huber)")
    p.add_argument("--clutter-density", type=number(float, gt=0), default=None,
                   help="false detections per scan per radian (default: estimated)")
    p.add_argument("--detection-probability", dest="p_detect", type=number(float, gt=0, le=1), default=None,
                   help="probability that a track is detected in a scan, (0, 1] (default: "
                        "estimated)")
    p.add_argument("--init-rate-sigma-deg-per-s", dest="init_sigma_rate_deg_per_s",
                   type=number(float, gt=0), default=None,
                   help="bearing-rate standard deviation of a new track, deg/s (default: "
                        "estimated)")
    p.add_argument("--max-misses", type=number(int, ge=1, le=MAX_SCANS_OPTION), default=None,
                   help="scans in a row without a detection that end a track (default: from "
                        "the detection probability)")
    p.add_argument("--max-miss-s", type=number(float, gt=0), default=4.0,
                   help="a track survives misses for at least this long, s (default 4; "
                        "ignored with --max-misses)")
    p.add_argument("--merge-deg", type=number(float, ge=0), default=1.0,
                   help="unknown-origin bearings of one scan closer than this are one "
                        "detection, deg (default 1.0: a camera detector may box one boat "
                        "several times; 0: no merging)")
    p.add_argument("--twin-deg", type=number(float, ge=0), default=4.0,
                   help="tracks from unknown-origin rows whose median distance over their "
                        "common time is below this are one source, deg (default 4.0: a boat "
                        "10 m long at 150 m; 0: keep them apart)")
    p.add_argument("--max-gap-scans", type=number(int, ge=1, le=MAX_SCANS_OPTION), default=None,
                   help="longest gap, in scans, that a track may bridge (default: from "
                        "--max-misses)")
    p.add_argument("--min-length", type=number(int, ge=2, le=MAX_SCANS_OPTION), default=None,
                   help="fewest detections of a track formed from unknown-origin rows, >= 2 "
                        "(default: from the detection probability)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (none either when standard error is not a terminal)")
    p.set_defaults(handler=run, inputs=("bearings",))


def run(args: argparse.Namespace) -> int:
    """Read, smooth, write (:func:`fusion.pipelines.bearing_smoothing.smooth_bearings`)."""
    table = read_bearings(args.bearings)
    try:
        check_track_lengths(table)
    except ValueError as e:
        raise ValueError(f"{args.bearings}: {e}") from None
    # work in rows, twice: once when the settings are fitted to them, once when smoothed (a
    # file of one long track is not 0 % until the end, the fit is half the work)
    n_rows = len(table["track_id"])
    bar = progress(2 * n_rows, quiet=args.quiet, desc="smooth", unit="row")
    try:
        st = fit_smoothing(
            table, merge_deg=args.merge_deg, max_miss_s=args.max_miss_s,
            sigma_bearing_deg=args.sigma_bearing_deg, period_s=args.period_s,
            q_deg2_per_s3=args.q_deg2_per_s3, clutter_density=args.clutter_density,
            p_detect=args.p_detect, init_sigma_rate_deg_per_s=args.init_sigma_rate_deg_per_s,
            max_misses=args.max_misses, max_gap_scans=args.max_gap_scans,
            min_length=args.min_length)
    except BaseException:
        bar.close()
        raise
    bar.update(n_rows)
    try:
        result = smooth_bearings(table, settings=st, robust=args.robust,
                                 association=args.association,
                                 clutter_density=args.clutter_density, merge_deg=args.merge_deg,
                                 twin_deg=args.twin_deg, output_times=args.output_times,
                                 extend_ends=args.extend_ends,
                                 extend_starts=args.extend_starts,
                                 short_link_q_deg2_per_s3=args.short_link_q_deg2_per_s3,
                                 link_path_alpha=args.link_path_alpha,
                                 end_detections=args.end_detections,
                                 link_gate=args.link_gate, relink_gate=args.relink_gate,
                                 crossing_gap_scans=args.crossing_gap_scans,
                                 link_curvature=args.link_curvature,
                                 on_rows=bar.update)
    except RuntimeError as e:  # gtsam: an ill-posed graph
        bar.close()
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ValueError(f"{args.bearings}: the smoothing graph is ill-conditioned ({first}); "
                         "a larger --accel-psd-deg2-per-s3 or --bearing-sigma-deg may help") from None
    bar.close()
    tracks = result.tracks
    write_table(args.out, result.columns())
    counted = result.association_clutter_density
    assoc = {"association": args.association, "output_times": args.output_times,
             "end_extension": args.extend_ends, "end_detections": args.end_detections,
             "link_gate": args.link_gate, "relink_gate": args.relink_gate,
             "crossing_gap_scans": args.crossing_gap_scans,
             "link_curvature": args.link_curvature, "start_extension": args.extend_starts,
             "short_link_accel_psd_deg2_per_s3": args.short_link_q_deg2_per_s3,
             "link_path_alpha": args.link_path_alpha}
    if counted is not None:
        assoc["association_clutter_density"] = float(counted)
    write_settings(args.out, {"command": "smooth", "tracks": len(tracks), "settings": st.as_dict(),
                              **assoc},
                   inputs=(args.bearings,))
    note = "" if counted is None or args.clutter_density is not None else (
        f"; association {args.association}, clutter {counted:.3g} /scan/rad counted")
    emit(f"fusion smooth: {st.describe()}{note}: {len(tracks)} track(s) -> {args.out}")
    logger.info("wrote %d tracks to %s", len(tracks), args.out)
    return 0
