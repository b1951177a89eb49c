"""``fusion crossings --bearings B.csv --out C.csv``: predict and detect bearing-track crossings.

The bearings are read in chunks, twice (:func:`fusion.io.iter_bearings`): a first pass collects
what the data-fitted settings need of the whole file (the median time step within tracks and the
median track span, exactly: :class:`~fusion.passive.crossing.summary.BearingStats`); the second
puts the tracks on the grid and runs the detector as the rows arrive
(:func:`~fusion.passive.crossing.stream.detect_crossings_streamed`), so memory holds a chunk and a
few cells per track, not the file. The alerts are those of the whole-file path bit for bit. A
track that resumes after the streaming path took it as ended costs one more pass
(:func:`~fusion.passive.crossing.stream.scan_long_gaps`) and a fresh start that assumes nothing.
Rows out of time order (overall, not only within a track) or repeated times send the command to
the whole-file path, which sorts (with its warning) or refuses with its usual message.
"""

from __future__ import annotations

import argparse
import logging
from collections.abc import Iterator

import numpy as np

from fusion._progress import track_progress
from fusion.cli import MAX_SCANS_OPTION, emit, number, summary
from fusion.io import RowOrderError, iter_bearings, read_bearings, write_table
from fusion.passive.crossing import CrossingAlert
from fusion.passive.crossing.settings import (
    DEFAULT_ALLOWANCE_GATE_LEVEL,
    DEFAULT_CONFIRM,
    DEFAULT_CONFIRM_LEAD,
    DEFAULT_CURVE_ALPHA,
    DEFAULT_CURVE_MANOEUVRE,
    DEFAULT_EXTRAPOLATION,
    DEFAULT_FAR_SIDE,
    DEFAULT_HORIZON_S,
    DEFAULT_LADDER_ALPHA,
    DEFAULT_LEAD_WINDOWS,
    DEFAULT_LEVEL,
    DEFAULT_MANOEUVRE_MEMORY_WINDOWS,
    DEFAULT_MANOEUVRE_SCALE,
    DEFAULT_N_WINDOWS,
    DEFAULT_WINDOW_FILL,
    DEFAULT_WINDOW_S,
    MAX_SAMPLES_PER_WINDOW,
    MIN_SAMPLES_PER_WINDOW,
    CrossingSettings,
    crossing_settings_from_steps,
)
from fusion.passive.crossing.stream import (
    GridAssumptionBroken,
    detect_crossings_streamed,
    scan_long_gaps,
)
from fusion.passive.crossing.summary import BearingStats, BearingSummary
from fusion.pipelines.bearing_crossings import (  # alert_columns: imported from here before
    alert_columns,
    check_spans,
    crossing_setup,
    detect_with,
)

#: Most windows in the ladder: each doubles the last, and the memory with it (16: the longest
#: window is 32,768 times the first, about 170 MB on a small file; 100,000 asked for 40 GiB).
MAX_N_WINDOWS = 16

logger = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``crossings`` subcommand."""
    p = sub.add_parser(
        "crossings",
        help="predict and detect crossings of bearing tracks",
        description=(
            "Predict and detect crossings of bearing tracks (Target Track Crossing "
            "Prediction/Detection): least-squares bearing and rate over a window of each "
            "track, crossing time of every pair with an interval from the fits' covariance "
            "(Fieller), prediction/detection inequalities. A pair whose rate difference the "
            "window cannot resolve is tried on windows 2, 4, ... times longer; no alert carries "
            "an interval wider than the horizon. Windows and horizon are in seconds; the "
            "sample period K comes from the data (dense data are averaged onto a coarser "
            "grid, irregular data interpolated; gaps longer than --max-gap-s split a track). "
            "One line says what was chosen. Rows with track_id -1 are ignored. Defaults "
            "chosen on varied simulated scenarios (benchmarks/RESULTS.md)."
        ),
    )
    p.add_argument("--bearings", required=True, help="input CSV: track_id,time,bearing_deg")
    p.add_argument("--out", required=True,
                   help="output CSV: time,track_a,track_b,t_cross,kind,t_cross_low,t_cross_high")
    p.add_argument("--window-s", type=number(float, gt=0), default=None, metavar="S",
                   help=f"shortest least-squares window, s (default {DEFAULT_WINDOW_S:g} s or "
                        "an eighth of the median track span if shorter, at least "
                        f"{MIN_SAMPLES_PER_WINDOW} samples)")
    p.add_argument("--horizon-s", dest="horizon", type=number(float, gt=0), default=None, metavar="S",
                   help="prediction horizon and widest interval of an alert, s "
                        f"(default {DEFAULT_HORIZON_S:g} s)")
    p.add_argument("--windows", type=number(int, ge=1, le=MAX_N_WINDOWS),
                   default=DEFAULT_N_WINDOWS, metavar="N",
                   help="windows in the ladder, each twice the previous "
                        f"(default {DEFAULT_N_WINDOWS}; 1: the method's single window)")
    p.add_argument("--lead", type=number(float, gt=0), default=DEFAULT_LEAD_WINDOWS, metavar="F",
                   help="predictions reach F spans of the window used ahead "
                        f"(default {DEFAULT_LEAD_WINDOWS:g}; the method: 1)")
    p.add_argument("--confirm", type=number(int, ge=1, le=MAX_SCANS_OPTION), default=DEFAULT_CONFIRM,
                   metavar="N",
                   help="samples in a row a pair must satisfy an inequality before it alerts "
                        f"(default {DEFAULT_CONFIRM}; the method: 1)")
    p.add_argument("--confirm-lead", type=number(float, gt=0), default=DEFAULT_CONFIRM_LEAD,
                   metavar="F",
                   help="confirming samples may predict up to F window spans ahead (default: "
                        "--lead); alerts still only within --lead, so a pair watched from "
                        "further out alerts as soon as its crossing comes within reach")
    p.add_argument("--level", type=number(float, gt=0, le=0.99999), default=DEFAULT_LEVEL,
                   metavar="P", help="nominal level of the fits' t_cross intervals (default "
                   f"{DEFAULT_LEVEL:g}: on varied scenarios about 95 %% of such intervals hold "
                   "the crossing, the fits' own 95 %% too few because tracks curve)")
    p.add_argument("--period-s", "-K", dest="period", type=number(float, gt=0), default=None, metavar="K",
                   help="grid period K, s (default: the median time step within tracks, "
                        "coarser if the window would hold more than "
                        f"{MAX_SAMPLES_PER_WINDOW} samples)")
    p.add_argument("--window-samples", "-J", dest="window",
                   type=number(int, ge=3, le=MAX_SCANS_OPTION), default=None, metavar="J",
                   help="samples in the shortest window, > 2 (default: from --window-s; replaces it)")
    p.add_argument("--merge-window-s", dest="merge_window",
                   type=number(float, gt=0), default=None, metavar="S",
                   help="alerts of a pair whose t_cross differ by <= S s, or whose intervals "
                        "overlap, are one event (default: the window)")
    p.add_argument("--max-gap-s", dest="max_gap", type=number(float, gt=0), default=None, metavar="S",
                   help="a gap longer than S s splits a track (default 3*K)")
    p.add_argument("--bearing-model", choices=("curve", "line"), default="curve",
                   help="curve (default): a shortest window whose bearings curve (F-test at "
                        "--curve-alpha) gets the bearing curve of a constant-velocity contact, "
                        "the crossing's interval from that curve's covariance; line: straight "
                        "lines only (the method's regression)")
    p.add_argument("--curve-alpha", type=number(float, gt=0, le=0.5), default=DEFAULT_CURVE_ALPHA,
                   metavar="P", help="level of the F-test that keeps a curve instead of the "
                   f"line (default {DEFAULT_CURVE_ALPHA:g}; smaller keeps fewer curves)")
    p.add_argument("--ladder-alpha", type=number(float, ge=0, le=0.5),
                   default=DEFAULT_LADDER_ALPHA, metavar="P",
                   help="a track enters a longer window of the ladder only if its residual "
                        "variance there passes the variance-ratio test against the shortest "
                        f"window at level P (default {DEFAULT_LADDER_ALPHA:g}; 0: every track, "
                        "the ladder before)")
    p.add_argument("--extrapolation", choices=("calibrated", "curvature", "model"),
                   default=DEFAULT_EXTRAPOLATION,
                   help="variance of a fit extrapolated ahead (predictions): calibrated (grown "
                        "by the factor that makes each track's earlier window predict the samples "
                        "since as often as --level says, pooled over tracks), curvature (the "
                        "fits' covariance plus the window's quadratic term the line leaves out, "
                        "at the predicted crossing) or model (the fits' own covariance); default "
                        f"{DEFAULT_EXTRAPOLATION}")
    p.add_argument("--manoeuvre-scale", type=number(float, ge=0),
                   default=DEFAULT_MANOEUVRE_SCALE, metavar="F",
                   help="predictions also carry the miss of the windows' lines under a bearing "
                        "rate that wanders as much as the tracks' own rate changes show "
                        "(intensity estimated from the data as it arrives), times F (default "
                        f"{DEFAULT_MANOEUVRE_SCALE:g}; 0: off, the intervals before)")
    p.add_argument("--ahead-variance-at", choices=("far-end", "crossing"),
                   default="far-end" if DEFAULT_FAR_SIDE else "crossing",
                   help="where the variances that grow with the lead (curvature, "
                        "--manoeuvre-scale) are evaluated: far-end (default: again at the upper "
                        "end of the interval, which is recomputed) or crossing (at the predicted "
                        "crossing only, before)")
    p.add_argument("--allowance-gates-from", type=number(int, ge=0),
                   default=DEFAULT_ALLOWANCE_GATE_LEVEL + 1,
                   metavar="N",
                   help="on windows of the ladder from the N-th on (1: the shortest), the "
                        "intervals widened by --manoeuvre-scale and --ahead-variance-at far-end "
                        "also decide which pairs alert (default "
                        f"{DEFAULT_ALLOWANCE_GATE_LEVEL + 1}; 0: on none, they only widen the "
                        "alerts' intervals)")
    p.add_argument("--manoeuvre-memory-windows", type=number(float, gt=0),
                   default=DEFAULT_MANOEUVRE_MEMORY_WINDOWS, metavar="F",
                   help="a track's rate changes are forgotten over F spans of the shortest "
                        f"window in its rate-wander intensity (default "
                        f"{DEFAULT_MANOEUVRE_MEMORY_WINDOWS:g})")
    p.add_argument("--no-curve-manoeuvre", dest="curve_manoeuvre", action="store_false",
                   default=DEFAULT_CURVE_MANOEUVRE,
                   help="pairs judged on curves get no --manoeuvre-scale allowance (before; by "
                        "default it widens their predictions' intervals, the curves' own "
                        "interval still deciding and confirming)")
    p.add_argument("--window-fill", type=number(float, gt=0, le=1), default=DEFAULT_WINDOW_FILL,
                   metavar="F",
                   help="a longer window of the ladder takes part once it holds more than F of "
                        "its samples (a track younger than the window, or restarted by a gap; "
                        f"default {DEFAULT_WINDOW_FILL:g}; 1: only full windows, before)")
    p.add_argument("--confirm-rule", choices=("overlap", "count"), default="overlap",
                   help="overlap (default): each of the --confirm samples in a row must hit with "
                        "a t_cross interval that overlaps the one before (a prediction that "
                        "jumps is not confirmed); count: any hits in a row (before)")
    p.add_argument("--predictions", choices=("revised", "once"), default="revised",
                   help="revised (default): a pair's crossing is predicted again when its new "
                        "interval no longer overlaps that of the prediction raised; once: one "
                        "prediction per crossing (before)")
    p.add_argument("--merge-repeats", action="store_true",
                   help="merge a pair's crossings by time and interval overlap only (before: a "
                        "crossing in the other direction is always the pair's next crossing)")
    p.add_argument("--strict", action="store_true",
                   help="refuse two rows of one track at one time (default: merge them, "
                        "weighted by sigma_bearing_deg if the file has it, and say how many)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (none either when standard error is not a terminal)")
    p.set_defaults(handler=run, inputs=("bearings",))


def run(args: argparse.Namespace) -> int:
    """Read the bearings, detect crossings, write the alerts; print a one-line summary."""
    try:
        alerts, st = _streamed(args)
    except (RowOrderError, _NotInTimeOrder) as e:
        logger.debug("%s; reading the whole file", e)
        alerts, st = _whole_file(args)
    write_table(args.out, alert_columns(alerts))
    n_pred = sum(a.kind == "predicted" for a in alerts)
    summary("crossings", f"{st.describe()}: {len(alerts)} alert(s) ({n_pred} predicted, "
            f"{len(alerts) - n_pred} detected) -> {args.out}")
    return 0


class _NotInTimeOrder(Exception):
    """Rows of different tracks are not in time order overall (fine for the whole-file path)."""


def _two_tracks(args: argparse.Namespace, n_tracks: int) -> None:
    if n_tracks < 2:
        raise ValueError(f"{args.bearings}: needs at least two tracks (track_id >= 0)")


def _options(args: argparse.Namespace) -> dict:
    """The settings options of the command line."""
    return {"window_s": args.window_s, "horizon_s": args.horizon, "period_s": args.period,
            "J": args.window, "n_windows": args.windows, "lead_windows": args.lead,
            "confirm": args.confirm, "level": args.level,
            "curve_alpha": args.curve_alpha if args.bearing_model == "curve" else None,
            "ladder_alpha": args.ladder_alpha or None,
            "revise": args.predictions == "revised",
            "confirm_overlap": args.confirm_rule == "overlap",
            "calibrate": args.extrapolation == "calibrated",
            "curvature": args.extrapolation == "curvature",
            "confirm_lead_windows": args.confirm_lead,
            "manoeuvre_scale": args.manoeuvre_scale,
            "far_side": args.ahead_variance_at == "far-end",
            # the ladder's level of the N-th window (1-based); 0: the gate on no window
            "allowance_gate_level": (None if args.allowance_gates_from == 0
                                     else args.allowance_gates_from - 1),
            "manoeuvre_memory_windows": args.manoeuvre_memory_windows,
            "curve_manoeuvre": args.curve_manoeuvre, "window_fill": args.window_fill}


def _check_spans(args: argparse.Namespace, st: CrossingSettings, spans_s: np.ndarray) -> None:
    try:
        check_spans(st, spans_s)
    except ValueError as e:
        raise ValueError(f"{args.bearings}: {e}") from None


def _streamed(args: argparse.Namespace) -> tuple[list[CrossingAlert], CrossingSettings]:
    """Two passes over the file in chunks: the settings, then the detector as rows arrive."""
    stats = BearingStats()
    n_rows = 0
    for c in iter_bearings(args.bearings):
        stats.add(c.table["track_id"], c.table["time"])
        n_rows += len(c.table["time"])
    summary: BearingSummary = stats.summary()
    if not summary.time_ordered:
        raise _NotInTimeOrder(f"{args.bearings}: tracks are not interleaved in time order")
    _two_tracks(args, summary.track_ids.size)
    try:
        if summary.step_s is None:  # the message of estimate_period
            raise ValueError("cannot infer the sample period: no track has two distinct times")
        st = crossing_settings_from_steps(summary.step_s, float(np.median(summary.spans_s)),
                                          **_options(args))
    except ValueError as e:
        raise ValueError(f"{args.bearings}: {e}") from None
    _check_spans(args, st, summary.spans_s)
    if summary.n_unknown:
        logger.info("ignoring %d detection(s) of unknown origin (track_id -1)", summary.n_unknown)
    def rows() -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        for c in track_progress(iter_bearings(args.bearings), quiet=args.quiet,
                                desc="crossings", unit="row", total=n_rows,
                                weight=lambda c: len(c.table["time"])):
            yield c.table["track_id"], c.table["time"], c.table["bearing_deg"]

    options = {"origin_s": summary.t_min_s, "merge_window_s": args.merge_window,
               "max_gap_s": args.max_gap, "split_repeats": not args.merge_repeats,
               **st.detector_options()}
    try:
        alerts = detect_crossings_streamed(rows(), **options)
    except GridAssumptionBroken as e:  # one more pass: the knots after long gaps, then exact
        logger.debug("%s; passing over the file for the gaps", e)
        gaps = scan_long_gaps(rows(), period_s=st.period_s, origin_s=summary.t_min_s,
                              max_gap_s=args.max_gap)
        alerts = detect_crossings_streamed(rows(), next_knots=gaps, **options)
    return alerts, st


def _whole_file(args: argparse.Namespace) -> tuple[list[CrossingAlert], CrossingSettings]:
    """The whole table at once (rows sorted by the reader if they were out of order), as
    :func:`fusion.pipelines.bearing_crossings.find_crossings` does."""
    table = read_bearings(args.bearings, distinct=args.strict, sigma=not args.strict)

    def said(cols: dict, n_merged: int) -> None:
        if n_merged:
            emit(f"merged {n_merged} simultaneous bearing row(s) of one track "
                 f"({'weighted by sigma_bearing_deg' if 'sigma_bearing_deg' in cols else 'equal weights'}"
                 "; --strict refuses them)")

    try:
        cols, st, _ = crossing_setup(table, strict=args.strict, on_merged=said, **_options(args))
    except ValueError as e:
        raise ValueError(f"{args.bearings}: {e}") from None
    alerts = detect_with(cols, st, merge_window_s=args.merge_window, max_gap_s=args.max_gap,
                         merge_repeats=args.merge_repeats)
    return alerts, st
