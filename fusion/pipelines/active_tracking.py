"""Multistatic tracking of a detection table: ``fusion track`` as a library call.

:func:`track_detections` takes the rows of a detections file (a :class:`fusion.types.Table`
from :func:`fusion.io.read_detections`, or a mapping of arrays ``event``, ``time``, ``x``, ``y``
and optional clue columns), reads the scales not given from the first ``fit_pings`` pings
(:func:`fusion.active.settings.track_settings`, and the pilot run's speed prior,
:func:`fusion.active.pilot.pilot_speed_prior`) exactly as the command does, tracks every ping and
returns the command's output rows with the settings. The options are :class:`TrackOptions`, one
field per option of ``fusion track`` with its unit in the name and the command's default;
``fusion track`` builds its tracker with the same :func:`build_tracker`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from fusion.active.settings import TrackSettings
    from fusion.active.tracker import Tracker
    from fusion.active.types import Ping, PingResult, TrackingResult

__all__ = [
    "FIT_PINGS",
    "MAP_MEMORY_PINGS",
    "TrackOptions",
    "TrackingRun",
    "build_tracker",
    "track_detections",
    "track_pings",
    "tracker_from",
]

#: Pings whose detections the settings are read from, by default.
FIT_PINGS = 500
#: Pings the density clutter map remembers by default (bounded memory on long runs).
MAP_MEMORY_PINGS = 200


@dataclass(frozen=True)
class TrackOptions:
    """Options of ``fusion track``; ``None``: estimated from the first `fit_pings` pings.

    Each field is the command's option of the same name (``position_sigma_m`` is
    ``--position-sigma-m``, ``track_score=False`` is ``--no-track-score``, ...) with its default;
    see ``fusion track --help`` and ``docs/tracking.md``.
    """

    mode: str = "fuzzy"
    position_sigma_m: float | None = None
    speed_sigma_mps: float | None = None
    accel_psd_m2_per_s3: float | None = None
    init_exclusion_m: float | None = None
    hotspot_near_m: tuple[float, float] | None = None
    feature_sigma_m: float | None = None
    intensity_bandwidth_m: float | None = None
    max_speed_mps: float = 30.0
    fit_pings: int = FIT_PINGS
    position_errors: str = "geometry"
    range_sum_sigma_m: float = 100.0
    bearing_sigma_deg: float = 1.5
    noise: str = "estimate"
    aspect_column: str = "ignored"
    score_threshold: float | None = None
    confirm_llr: float = 3.0
    delete_llr: float = -4.0
    track_score: bool = True
    score_evidence: bool = True
    detection_probability: float | None = None
    clutter_density: float | None = None
    pilot_speed: bool = True
    pd_from_confirmed: bool = False
    coast_probability: float = 0.01
    intensity_leave_one_out: bool = False
    intensity_leave_track_out: bool = False
    hits_per_detection: bool = False
    coast_gate_births: bool = False
    successor_llr: float | None = None
    snr_evidence: bool = False
    birth_evidence: bool = False
    track_pd_prior_pings: float | None = None
    shadow_test: bool = True
    shadow_extent_sigmas: float = 8.0
    motion_recent_half: bool = False
    min_speed_mps: float | None = None
    still_wander_s: float = 250.0
    motion_probability: float = 0.999
    gate_probability: float = 0.99
    min_rank: float | None = None
    edge_likelihood: float = 0.25
    confirmed_edge_likelihood: float = 0.1
    confirm: tuple[int, int] = (3, 4)
    max_misses: int = 5
    confirm_stationary: bool = False
    keep_platform_fixed: bool = False
    hotspot_drop: bool = False
    clutter_map: str = "density"
    hotspot_cell_m: float = 150.0
    map_memory_pings: int = MAP_MEMORY_PINGS
    smooth: bool = False
    confirmed_only: bool = False

    def __post_init__(self) -> None:
        if self.confirm[0] > self.confirm[1]:
            raise ValueError(f"--confirm: M must not exceed N, got {self.confirm[0]} {self.confirm[1]}")
        if self.smooth and self.accel_psd_m2_per_s3 is not None and self.accel_psd_m2_per_s3 <= 0:
            raise ValueError("--smooth needs --accel-psd-m2-per-s3 > 0")


def tracker_from(opts: TrackOptions, st: TrackSettings, system: object | None) -> Tracker:
    """The tracker these options and settings configure."""
    from fusion.active.clutter import ClutterMap, DensityClutterMap
    from fusion.active.tracker import Tracker

    sigma = st.position_sigma_m
    return Tracker(
        mode=opts.mode, system=system, position_sigma_m=sigma,
        position_errors=opts.position_errors, range_sum_sigma_m=opts.range_sum_sigma_m,
        bearing_sigma_deg=opts.bearing_sigma_deg, noise=opts.noise,
        aspect="measured" if opts.aspect_column == "measured" else "geometry",
        score_threshold=opts.score_threshold,
        confirm_llr=opts.confirm_llr if opts.track_score else None,
        delete_llr=opts.delete_llr, score_evidence=opts.score_evidence,
        detection_probability=opts.detection_probability,
        clutter_intensity=opts.clutter_density, min_speed_mps=opts.min_speed_mps,
        still_wander_s=opts.still_wander_s,
        motion_probability=opts.motion_probability, gate_probability=opts.gate_probability,
        accel_psd=st.accel_psd, speed_sigma_mps=st.speed_sigma_mps,
        init_exclusion_m=st.init_exclusion_m, hotspot_drop=opts.hotspot_drop,
        intensity_bandwidth_m=st.intensity_bandwidth_m, min_rank=opts.min_rank,
        edge_likelihood=opts.edge_likelihood,
        confirmed_edge_likelihood=opts.confirmed_edge_likelihood,
        confirm_hits=opts.confirm[0], confirm_window=opts.confirm[1],
        max_misses=opts.max_misses, hold_stationary=not opts.confirm_stationary,
        pd_from_tentative=not opts.pd_from_confirmed,
        coast_probability=opts.coast_probability or None,
        intensity_leave_one_out=opts.intensity_leave_one_out,
        intensity_leave_track_out=opts.intensity_leave_track_out,
        hits_per_detection=opts.hits_per_detection,
        coast_gate_births=opts.coast_gate_births, successor_llr=opts.successor_llr,
        snr_evidence=opts.snr_evidence, birth_evidence=opts.birth_evidence,
        track_pd_prior_pings=opts.track_pd_prior_pings,
        motion_recent=opts.motion_recent_half, shadow=opts.shadow_test,
        shadow_extent_sigmas=opts.shadow_extent_sigmas,
        reject_platform_fixed=not opts.keep_platform_fixed,
        clutter_map=(ClutterMap(cell_m=opts.hotspot_cell_m, position_sigma_m=sigma)
                     if opts.clutter_map == "grid"
                     else DensityClutterMap(position_sigma_m=sigma,
                                            feature_sigma_m=st.feature_sigma_m,
                                            memory_pings=opts.map_memory_pings)),
    )


def build_tracker(prefix: Sequence[Ping], opts: TrackOptions,
                  system: object | None = None) -> tuple[TrackSettings, Tracker]:
    """The settings read from the first pings and the tracker they configure.

    `system`: the fuzzy association system (default: the paper's rule base,
    :func:`fusion.active.rulebase.default_association_system`). Raises ValueError
    ``"bad option: ..."`` when an option does not fit.
    """
    from fusion.active.rulebase import default_association_system
    from fusion.active.settings import track_settings

    try:
        st = track_settings(list(prefix), position_sigma_m=opts.position_sigma_m,
                            speed_sigma_mps=opts.speed_sigma_mps,
                            accel_psd=opts.accel_psd_m2_per_s3,
                            init_exclusion_m=opts.init_exclusion_m,
                            feature_sigma_m=opts.feature_sigma_m,
                            hotspot_near_m=(None if opts.hotspot_near_m is None
                                            else tuple(opts.hotspot_near_m)),
                            intensity_bandwidth_m=opts.intensity_bandwidth_m,
                            max_speed_mps=opts.max_speed_mps)
        if opts.mode == "fuzzy" and system is None:
            system = default_association_system(hotspot_near_m=st.hotspot_near_m)
        tracker = tracker_from(opts, st, system)
        if (opts.speed_sigma_mps is None and opts.pilot_speed and prefix
                and opts.mode == "fuzzy"):
            from fusion.active.pilot import pilot_speed_prior

            logging.getLogger("fusion.active.fuzzy").setLevel(logging.ERROR)

            pilot = pilot_speed_prior(
                list(prefix), tracker,
                **({} if opts.min_speed_mps is None else {"min_speed_mps": opts.min_speed_mps}))
            if pilot.speed_sigma_mps is not None:
                st = st.with_track_speed(pilot.speed_sigma_mps, len(pilot.speeds_mps))
                tracker = tracker_from(opts, st, system)
    except ValueError as e:
        raise ValueError(f"bad option: {e}") from None
    return st, tracker


@dataclass(frozen=True)
class TrackingRun:
    """Tracks of a detection table.

    Attributes
    ----------
    columns : dict of str to ndarray
        The rows of ``fusion track``'s output (``track_id,event,time,x,y,vx,vy,status``, and
        ``sigma_x, sigma_y`` with ``smooth``).
    settings : TrackSettings
        Scales given or read from the first pings (``settings.describe()``).
    result : TrackingResult
        Per-ping results of the tracker (``result.confirmed_ids()``, ...).
    """

    columns: dict[str, NDArray[Any]]
    settings: TrackSettings
    result: TrackingResult


def track_pings(pings: Sequence[Ping], opts: TrackOptions, *, system: object | None = None,
                on_built: Callable[[TrackSettings], None] | None = None,
                on_ping: Callable[[Ping, PingResult], None] | None = None,
                each: Callable[[Sequence[Ping]], Iterable[Ping]] | None = None) -> TrackingRun:
    """Track pings (:func:`fusion.active.types.pings_from_columns`) with `opts`.

    `on_built(settings)` once the settings are read from the first pings, `on_ping(ping,
    result)` after each ping, `each(pings)` wraps the loop over the pings (a progress bar).
    """
    from fusion.active.types import TrackingResult

    st, tracker = build_tracker(pings[:opts.fit_pings], opts, system)
    if on_built is not None:
        on_built(st)
    tracker.reset()
    results = []
    for p in (each(pings) if each is not None else pings):
        results.append(tracker.step(p))
        if on_ping is not None:
            on_ping(p, results[-1])
    result = TrackingResult(tuple(results))
    cols = result.columns()
    if opts.smooth:
        from fusion.active.smoothing import TrackSmoother, smooth_tracks

        smoother = TrackSmoother(accel_psd=tracker.accel_psd,
                                 speed_sigma_mps=tracker.speed_sigma_mps)
        cols = smooth_tracks(result, smoother).columns
    if opts.confirmed_only:
        keep = np.isin(cols["track_id"], result.confirmed_ids())
        cols = {k: v[keep] for k, v in cols.items()}
    return TrackingRun(columns=cols, settings=st, result=result)


def track_detections(table: Mapping[str, Any] | Any, *, system: object | None = None,
                     **options: Any) -> TrackingRun:
    """Track a detection table as ``fusion track`` does, its scales read from the data.

    Parameters
    ----------
    table : Table or mapping
        Columns ``event``, ``time`` (s), ``x``, ``y`` (m) and any clue columns.
    system : keyword-only
        Fuzzy association system (default: the paper's rule base).
    **options
        Fields of :class:`TrackOptions` (``position_sigma_m=20.0``, ``smooth=True``, ...).

    Returns
    -------
    TrackingRun
    """
    from fusion.active.types import pings_from_columns

    return track_pings(pings_from_columns(table), TrackOptions(**options), system=system)
