"""``fusion track --detections D.csv --out T.csv``: multistatic active tracking.

Reads position detections (``event,time,x,y`` plus optional clue columns ``snr_db, score,
aspect_deg, src_x, src_y, rcv_x, rcv_y`` and the sensor platform's position ``own_x, own_y``)
and writes one row per track per event:
``track_id,event,time,x,y,vx,vy,status``. Clue columns absent from the file leave the rules that
read them out of the rank; the command says so once on stderr. With ``src_x, src_y, rcv_x, rcv_y``
each detection's position error is the bistatic error ellipse propagated from the range-sum and
bearing accuracies, learnt per receiver from the data starting from ``--range-sum-sigma-m`` and
``--bearing-sigma-deg`` (``--noise fixed``: those values for every receiver); without them (e.g.
radar), or with ``--position-errors isotropic``, it is ``--position-sigma-m`` per axis. The
equivalent aspect angle comes from each track's heading and the source/receiver positions; an
``aspect_deg`` column is used only with ``--aspect-column measured`` (nothing in a file says how
it was obtained). With ``--smooth`` each confirmed track is refined with all of its detections on
a factor graph (:mod:`fusion.active.smoothing`) and every row gets ``sigma_x, sigma_y`` (m).
A tentative track whose detections stand still relative to the sensor (``rcv_x, rcv_y``, else
``own_x, own_y``) while the sensor moved significantly is platform-fixed clutter and is not
confirmed (:mod:`fusion.active.platform`; ``--keep-platform-fixed`` turns this off).

Scales not given are read from the first ``--fit-pings`` pings
(:func:`fusion.active.settings.track_settings`, through
:func:`fusion.pipelines.active_tracking.build_tracker`, as the library's
:func:`fusion.track_detections` does): scan period, position scatter, speed prior,
process noise, clutter density, start exclusion and the hotspot lengths. One line on stderr says
what was chosen; the same goes to ``T.settings.json`` beside ``T.csv`` (not with ``--out -``),
with a line saying why when no track was confirmed. The file is read and written in chunks,
ping after ping (the tracker is online), unless ``--smooth`` or ``--confirmed-only`` need the
whole run or the rows are not in event order (then the whole-file reader sorts them).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import logging
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from fusion._progress import track_progress
from fusion.cli import MAX_SCANS_OPTION, emit, number
from fusion.io import (
    RowOrderError,
    iter_detections,
    read_detections,
    write_settings,
    write_table,
    write_table_chunks,
)
from fusion.pipelines.active_tracking import (
    FIT_PINGS,
    MAP_MEMORY_PINGS,
    TrackOptions,
    build_tracker,
    track_pings,
)

if TYPE_CHECKING:
    from fusion.active.settings import TrackSettings
    from fusion.active.tracker import Tracker
    from fusion.active.types import Ping, PingResult

logger = logging.getLogger(__name__)

_POSITIONS = ("src_x", "src_y", "rcv_x", "rcv_y")
_HEADER = ("track_id", "event", "time", "x", "y", "vx", "vy", "status")
#: Pings per written chunk when streaming.
_PINGS_PER_CHUNK = 256


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``track`` subcommand."""
    p = sub.add_parser(
        "track",
        help="track targets in active-sonar (or any position) detections",
        description="Kalman prediction + fuzzy-logic association (or Kalman nearest neighbour), "
                    "clutter map, M-of-N confirmation and track score. Scales not given (position "
                    "sigma, speed prior, process noise, start exclusion, hotspot lengths) are "
                    "read from the detections; one line on stderr and T.settings.json say what "
                    "was chosen.",
    )
    p.add_argument("--detections", type=Path, required=True, help="detections CSV")
    p.add_argument("--out", type=Path, required=True, help="output tracks CSV")
    p.add_argument("--mode", choices=("fuzzy", "kalman"), default="fuzzy",
                   help="association: fuzzy rank (default) or Kalman likelihood alone")
    p.add_argument("--rules", type=Path, default=None,
                   help="fuzzy system JSON file (default: the built-in rule base, its hotspot "
                        "'near' from --hotspot-near-m)")
    g = p.add_argument_group("scales (default: read from the detections)")
    g.add_argument("--position-sigma-m", dest="position_sigma",
                   type=number(float, gt=0), default=None, metavar="M",
                   help="position error of a detection per axis, m, for detections without "
                        "source/receiver positions (default: the scatter of straight-line "
                        "triplets of detections)")
    g.add_argument("--speed-sigma-mps", type=number(float, gt=0), default=None, metavar="V",
                   help="standard deviation of each velocity component of a new track, m/s "
                        "(default: half the 90th percentile speed of objects seen moving; 3 "
                        "when too few are)")
    g.add_argument("--accel-psd-m2-per-s3", dest="accel_psd",
                   type=number(float, ge=0), default=None, metavar="Q",
                   help="white-acceleration spectral density, m^2/s^3 (default: "
                        "speed_sigma^2 / (2.5 scan periods))")
    g.add_argument("--init-exclusion-m", type=number(float, ge=0), default=None, metavar="M",
                   help="detections this close to a hotspot region start no track, m (default: "
                        "the position sigma)")
    g.add_argument("--hotspot-near-m", dest="hotspot_near", type=number(float, ge=0), nargs=2, default=None,
                   metavar=("FULL", "NONE"),
                   help="distances to a hotspot where the rule 'near' is 1 and 0, m (default: "
                        "1 and 5 position sigmas)")
    g.add_argument("--feature-sigma-m", dest="feature_sigma",
                   type=number(float, ge=0), default=None, metavar="M",
                   help="spread of a clutter feature's echoes per axis, m, for the density "
                        "clutter map (default: 0.3 position sigma)")
    g.add_argument("--intensity-bandwidth-m", dest="intensity_bandwidth",
                   type=number(float, gt=0), default=None, metavar="M",
                   help="kernel of the clutter intensity of the track score, m (default: 10 "
                        "position sigmas)")
    g.add_argument("--max-speed-mps", dest="max_speed", type=number(float, gt=0), default=30.0, metavar="V",
                   help="fastest plausible object, m/s: how far the settings look for the "
                        "next detection of an object (default 30)")
    g.add_argument("--fit-pings", type=number(int, ge=3, le=MAX_SCANS_OPTION), default=FIT_PINGS, metavar="N",
                   help=f"pings the scales are read from (default {FIT_PINGS})")
    p.add_argument("--position-errors", choices=("geometry", "isotropic"), default="geometry",
                   help="position error of detections with src_x,src_y,rcv_x,rcv_y: bistatic "
                        "error ellipse from range-sum and bearing accuracies (default) or "
                        "--position-sigma-m per axis")
    p.add_argument("--range-sum-sigma-m", dest="range_sum_sigma", type=number(float, gt=0), default=100.0,
                   help="bistatic range-sum accuracy (standard deviation), m: the start of the "
                        "per-receiver estimate, or the value itself with --noise fixed "
                        "(default 100)")
    p.add_argument("--bearing-sigma-deg", dest="bearing_sigma", type=number(float, gt=0), default=1.5,
                   help="receiver bearing accuracy (standard deviation), deg; as "
                        "--range-sum-sigma-m (default 1.5)")
    p.add_argument("--noise", choices=("estimate", "fixed"), default="estimate",
                   help="range-sum and bearing accuracies: learnt per receiver from echoes that "
                        "recur (default) or --range-sum-sigma-m/--bearing-sigma-deg for all")
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
    p.add_argument("--delete-llr", type=number(float), default=-4.0,
                   help="a tentative track whose score falls below this is deleted (default -4)")
    p.add_argument("--no-track-score", action="store_true",
                   help="confirm on M-of-N hits alone (the paper), no track score")
    p.add_argument("--no-score-evidence", action="store_true",
                   help="the track score ignores the classifier score of each hit")
    p.add_argument("--detection-probability", type=number(float, gt=0, le=0.999), default=None,
                   help="probability that a receiver detects a track on a ping, for the track "
                        "score (default: estimated from confirmed tracks)")
    p.add_argument("--clutter-density", type=number(float, gt=0), default=None,
                   help="clutter detections per m^2 per ping and receiver, for the track score "
                        "(default: estimated over the field from the detections)")
    p.add_argument("--intensity-leave-one-out", action="store_true",
                   help="the estimated clutter intensity at a detection leaves out the "
                        "detection's own kernel (leave-one-out estimate; measured with "
                        "--confirm-llr 5, see docs/tracking.md; default: off)")
    p.add_argument("--intensity-leave-track-out", action="store_true",
                   help="the estimated clutter intensity at a track's detection leaves out the "
                        "detection's own kernel and those of the track's earlier detections "
                        "(see docs/tracking.md; default: off)")
    p.add_argument("--hits-per-detection", action="store_true",
                   help="each detection a tentative track takes counts towards the M of M-of-N "
                        "(default: each ping with a detection counts once)")
    p.add_argument("--coast-gate-births", action="store_true",
                   help="a detection that only coasting confirmed tracks gate (they took no "
                        "detection of its receiver on the ping) may start a track (default: any "
                        "track's gate keeps it from starting one; docs/tracking.md)")
    p.add_argument("--successor-llr", type=number(float), default=None, metavar="LLR",
                   help="with --coast-gate-births: a track born in a coasting confirmed track's "
                        "gate starts with this track score and is confirmed with one hit fewer "
                        "(default: off)")
    p.add_argument("--snr-evidence", action="store_true",
                   help="the track score adds each hit's SNR likelihood ratio, target against "
                        "clutter, learnt from the detections (column snr_db; default: off)")
    p.add_argument("--birth-evidence", action="store_true",
                   help="a new track starts at its detection's classifier-score likelihood ratio "
                        "(and SNR ratio with --snr-evidence) instead of 0 (default: off)")
    p.add_argument("--track-pd-prior-pings", type=number(float, gt=0), default=None, metavar="PINGS",
                   help="score each track with its own detection probability per receiver: a "
                        "Beta prior of the receiver's P_D worth PINGS pings updated by the "
                        "track's hits and misses (docs/tracking.md; default: off, the receiver's P_D)")
    p.add_argument("--no-pilot-speed", dest="pilot_speed", action="store_false",
                   help="the speed prior (when --speed-sigma-mps is not given) stays the one of "
                        "straight-line triplets of detections (default: the median speed of the "
                        "consistent moving tracks a pilot run over the --fit-pings confirms)")
    p.add_argument("--pd-from-confirmed", action="store_true",
                   help="estimate each receiver's detection probability from confirmed tracks "
                        "alone (default: also from tentative tracks whose score has reached "
                        "--confirm-llr)")
    p.add_argument("--coast-probability", type=number(float, ge=0, le=0.5), default=0.01,
                   metavar="P",
                   help="a confirmed track coasts until that many missed pings of a real "
                        "target would have probability below P under the estimated detection "
                        "probabilities, at least --max-misses (default 0.01; 0: --max-misses "
                        "alone)")
    p.add_argument("--no-shadow-test", dest="shadow_test", action="store_false",
                   help="fuzzy mode: confirm tracks behind a nearer confirmed track too (default: "
                        "with own_x,own_y and no rcv_x,rcv_y, a tentative track whose latest "
                        "detection lies behind a nearer confirmed track, within that track's "
                        "angular extent, is held: multipath ghosts behind a large vessel)")
    p.add_argument("--shadow-extent-sigmas", type=number(float, gt=0), default=8.0, metavar="K",
                   help="half-extent of a confirmed track across the line of sight, in RMS "
                        "cross-range residuals of its own detections (default 8)")
    p.add_argument("--motion-recent-half", action="store_true",
                   help="fuzzy mode: the motion test also fits a straight line to the later "
                        "half of a tentative track's detections, so that a target that turned "
                        "back is seen to move (default: one line through all of them)")
    p.add_argument("--min-speed-mps", dest="min_speed", type=number(float, ge=0), default=None,
                   help="speeds up to this count as standing still in the motion test, m/s "
                        "(default: the position sigma / --still-wander-s, e.g. 0.5 at 125-m "
                        "sonar errors, 0.01 at 3-m radar errors)")
    p.add_argument("--still-wander-s", type=number(float, gt=0), default=250.0,
                   help="time over which a still object's apparent position wanders by its "
                        "position sigma, s; sets the default --min-speed-mps (default 250)")
    p.add_argument("--motion-probability", type=number(float, gt=0, le=0.999999), default=0.999,
                   help="confidence of the motion test (default 0.999)")
    p.add_argument("--gate-probability", type=number(float, gt=0, le=0.999999), default=0.99,
                   help="chi-square gate probability (default 0.99)")
    p.add_argument("--min-rank", type=number(float, ge=0, le=1), default=None,
                   help="lowest fuzzy rank associated, one value for all pairs (default: derived "
                        "from the rule base for the clues present, at likelihood ratio "
                        "--edge-likelihood)")
    p.add_argument("--edge-likelihood", type=number(float, gt=0, le=0.999999), default=0.25,
                   help="likelihood ratio at the edge of the acceptance region of the derived "
                        "rank threshold (default 0.25)")
    p.add_argument("--confirmed-edge-likelihood", type=number(float, gt=0, le=0.999999), default=0.1,
                   help="the same for confirmed tracks (default 0.1)")
    p.add_argument("--confirm", type=number(int, ge=1, le=MAX_SCANS_OPTION), nargs=2, default=(3, 4),
                   metavar=("M", "N"),
                   help="confirm after M hits in the first N pings (default 3 4)")
    p.add_argument("--max-misses", type=number(int, ge=1, le=MAX_SCANS_OPTION), default=5,
                   help="consecutive misses deleting a confirmed track (default 5)")
    p.add_argument("--confirm-stationary", action="store_true",
                   help="fuzzy mode: confirm a track on its hits alone, even when its own "
                        "detections do not move (default: such a track is held tentative until "
                        "it moves or the clutter map flags it)")
    p.add_argument("--keep-platform-fixed", action="store_true",
                   help="fuzzy mode: confirm a track even when its detections stand still "
                        "relative to a sensor that moved (default: held tentative; the sensor "
                        "position is rcv_x,rcv_y or own_x,own_y)")
    p.add_argument("--hotspot-drop", action="store_true",
                   help="fuzzy mode: delete a tentative track within --init-exclusion-m of a "
                        "hotspot region unless its own detections move")
    p.add_argument("--clutter-map", choices=("density", "grid"), default="density",
                   help="clutter map: recurrence judged with each detection's own error "
                        "ellipse (default) or counted in fixed grid cells")
    p.add_argument("--hotspot-cell-m", dest="hotspot_cell", type=number(float, gt=0), default=150.0,
                   help="--clutter-map grid: cell size, m (default 150)")
    p.add_argument("--map-memory-pings", type=number(int, ge=2, le=MAX_SCANS_OPTION),
                   default=MAP_MEMORY_PINGS,
                   metavar="N",
                   help="the density clutter map remembers the last N pings (default "
                        f"{MAP_MEMORY_PINGS}: memory and time per ping stay bounded on long runs)")
    p.add_argument("--confirmed-only", action="store_true",
                   help="write only rows of tracks that were confirmed at some point")
    p.add_argument("--smooth", action="store_true",
                   help="refine each confirmed track with all of its detections on a factor graph "
                        "(fixed-interval smoother) and append sigma_x, sigma_y (m) to every row")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (none either when standard error is not a terminal)")
    p.set_defaults(handler=run, inputs=("detections", "rules"))


class _Summary:
    """What a run did, for the closing line and the reason when nothing was confirmed."""

    def __init__(self) -> None:
        self.pings = self.detections = 0
        self.hits: dict[int, int] = {}
        self.confirmed: set[int] = set()

    def add(self, ping_n: int, result: PingResult) -> None:
        self.pings += 1
        self.detections += ping_n
        for tid, det, st in zip(result.track_id.tolist(), result.detection.tolist(),
                                result.status.tolist(), strict=True):
            self.hits[tid] = self.hits.get(tid, 0) + (det >= 0)
            if st == "confirmed":
                self.confirmed.add(tid)

    def why_none(self, args: argparse.Namespace, st: TrackSettings) -> str | None:
        """One line saying why no track was confirmed (None when some was)."""
        if self.confirmed:
            return None
        m, n = args.confirm
        if self.detections == 0:
            return f"no track confirmed: {args.detections} holds no detections"
        most = max(self.hits.values(), default=0)
        if most < m:
            return (f"no track confirmed: no detection sequence got {m} hits within {n} pings "
                    f"(at most {most} of {self.pings} pings; {len(self.hits)} tracks started): "
                    f"the detections do not recur along a path inside the gates (position "
                    f"sigma {st.position_sigma_m:.3g} m, speed sigma "
                    f"{st.speed_sigma_mps:.3g} m/s; see --position-sigma-m, --speed-sigma-mps)")
        held = sum(h >= m for h in self.hits.values())
        why = []
        if not args.confirm_stationary and args.mode == "fuzzy":
            from fusion.active.motion import still_speed_mps

            floor = (args.min_speed if args.min_speed is not None
                     else still_speed_mps(st.position_sigma_m, args.still_wander_s))
            why.append(f"their detections did not move faster than --min-speed-mps "
                       f"{floor:.3g} m/s significantly (stationary hold; "
                       "--confirm-stationary)")
            if not args.keep_platform_fixed:
                why.append("they stood still relative to the moving sensor (platform-fixed; "
                           "--keep-platform-fixed)")
        if not args.no_track_score and args.mode == "fuzzy":
            why.append(f"their track score stayed below --confirm-llr {args.confirm_llr:g}")
        return (f"no track confirmed: {held} track(s) reached {m} hits but were held "
                f"tentative: {' or '.join(why) or 'deleted before confirmation'}")


#: Options of the command whose dest differs from the :class:`TrackOptions` field: dest ->
#: field (a ``no_*`` dest is the field negated).
_FIELDS = {"position_sigma": "position_sigma_m", "accel_psd": "accel_psd_m2_per_s3",
           "hotspot_near": "hotspot_near_m", "feature_sigma": "feature_sigma_m",
           "intensity_bandwidth": "intensity_bandwidth_m", "max_speed": "max_speed_mps",
           "range_sum_sigma": "range_sum_sigma_m", "bearing_sigma": "bearing_sigma_deg",
           "no_track_score": "track_score", "no_score_evidence": "score_evidence",
           "min_speed": "min_speed_mps", "hotspot_cell": "hotspot_cell_m"}


def track_options(args: argparse.Namespace) -> TrackOptions:
    """The library's options (:class:`~fusion.pipelines.active_tracking.TrackOptions`) of the
    command line."""
    fields = {f.name for f in dataclasses.fields(TrackOptions)}
    values = {}
    for dest, value in vars(args).items():
        name = _FIELDS.get(dest, dest)
        if name not in fields:
            continue
        if dest.startswith("no_"):
            value = not value
        elif isinstance(value, list):
            value = tuple(value)
        values[name] = value
    return TrackOptions(**values)


def _build(args: argparse.Namespace, opts: TrackOptions, prefix: list[Ping],
           system: object | None) -> tuple[TrackSettings, Tracker]:
    """The settings read from the first pings and the tracker they configure."""
    st, tracker = build_tracker(prefix, opts, system)
    _note(args, prefix)
    return st, tracker


def _note(args: argparse.Namespace, prefix: list[Ping]) -> None:
    """Say which clue columns the file lacks (fuzzy mode), once."""
    if args.mode == "fuzzy":
        present = set(prefix[0].clues) if prefix else set()
        absent = [c for c in ("score", "snr_db") if c not in present]
        measured = args.aspect_column == "measured" and "aspect_deg" in present
        if not measured and not all(c in present for c in _POSITIONS):
            absent.append("src_x, src_y, rcv_x, rcv_y (aspect_deg from the track heading)"
                          if args.aspect_column == "ignored" else
                          "aspect_deg (or src_x, src_y, rcv_x, rcv_y)")
        if absent and prefix:  # printed by run() once the tracks are written: a failing run
            # prints its error line only (and a run read twice, streamed then whole, one note)
            args.track_note = (f"fusion track: note: {args.detections} has no "
                               f"{', '.join(absent)}; the rules reading them are left out of "
                               "the rank")
        # The note above replaces the fuzzy engine's own warning.
        logging.getLogger("fusion.active.fuzzy").setLevel(logging.ERROR)


def _streamed(args: argparse.Namespace, opts: TrackOptions, system: object | None,
              summary: _Summary) -> TrackSettings:
    """Read, track and write ping by ping (bounded memory); returns the settings."""
    from fusion.active.types import TrackingResult, iter_pings

    pings = iter_pings(chunk.table for chunk in iter_detections(args.detections))
    prefix = list(itertools.islice(pings, args.fit_pings))
    st, tracker = _build(args, opts, prefix, system)

    def chunks() -> Iterator[dict]:
        results = []
        for p in track_progress(itertools.chain(prefix, pings), quiet=args.quiet,
                                desc="track", unit="ping"):
            r = tracker.step(p)
            summary.add(p.n, r)
            results.append(r)
            if len(results) >= _PINGS_PER_CHUNK:
                yield TrackingResult(tuple(results)).columns()
                results = []
        yield TrackingResult(tuple(results)).columns()

    write_table_chunks(args.out, chunks(), header=_HEADER)
    return st


def _whole(args: argparse.Namespace, opts: TrackOptions, system: object | None,
           summary: _Summary) -> TrackSettings:
    """Read the whole file (sorted by event), track, write; returns the settings
    (:func:`fusion.pipelines.active_tracking.track_pings`, as the library's
    :func:`fusion.track_detections`)."""
    from fusion.active.types import pings_from_columns

    pings = pings_from_columns(read_detections(args.detections))
    run = track_pings(
        pings, opts, system=system, on_built=lambda _: _note(args, pings[:opts.fit_pings]),
        on_ping=lambda p, r: summary.add(p.n, r),
        each=lambda ps: track_progress(ps, quiet=args.quiet, desc="track", unit="ping",
                                       total=len(ps)))
    write_table(args.out, run.columns)
    return run.settings


def run(args: argparse.Namespace) -> int:
    """Track the detections and write the tracks, the settings and one line of summary."""
    opts = track_options(args)  # checks --confirm and --smooth
    system = None
    if args.mode == "fuzzy" and args.rules is not None:
        from fusion.active.fuzzy import load_system

        system = load_system(args.rules)
    summary = _Summary()
    streamed = not (args.smooth or args.confirmed_only)
    if streamed:
        try:
            st = _streamed(args, opts, system, summary)
        except RowOrderError as e:  # rows out of event order: the whole-file reader sorts them
            logger.debug("%s; reading the whole file", e)
            summary, streamed = _Summary(), False
    if not streamed:
        st = _whole(args, opts, system, summary)
    why = summary.why_none(args, st)
    write_settings(args.out, {"command": "track", "settings": st.metadata(),
                              "pings": summary.pings, "detections": summary.detections,
                              "tracks": len(summary.hits),
                              "confirmed_tracks": len(summary.confirmed), "no_track_reason": why},
                   inputs=(args.detections, args.rules))
    if getattr(args, "track_note", None):
        emit(args.track_note, err=True)
    emit(f"fusion track: {st.describe()}: {len(summary.confirmed)} confirmed track(s) of "
         f"{len(summary.hits)} -> {args.out}", err=True)
    if why is not None:
        emit(f"fusion track: {why}", err=True)
    logger.info("%d tracks confirmed", len(summary.confirmed))
    return 0
