"""A bearing table smoothed with settings fitted to it: ``fusion smooth`` as a library call.

:func:`smooth_bearings` takes the rows of a bearings file (a :class:`fusion.types.Table` from
:func:`fusion.io.read_bearings`, or any mapping of equal-length arrays ``track_id``, ``time``,
``bearing_deg``), estimates every scale not given exactly as the command does
(:func:`fit_smoothing`: same-scan unknown-origin detections merged first, then
:func:`fusion.passive.smoothing.settings.fit_smooth_settings`) and returns the smoothed tracks
with the settings used (:class:`SmoothingResult`). ``fusion smooth`` calls the same functions,
so a script and the command give the same numbers. Units are in the names: the table and the
options are in degrees, the returned :class:`~fusion.passive.smoothing.types.SmoothedTrack`
in radians, :meth:`SmoothingResult.columns` in degrees again (the command's output file).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import wrap_angle
from fusion.passive.smoothing import BearingSmoother, MultiTrackSmoother, SmoothedTrack
from fusion.passive.smoothing import smooth_bearings as smooth_rows
from fusion.passive.smoothing.grid import on_grid
from fusion.passive.smoothing.merge import merge_scan_detections
from fusion.passive.smoothing.settings import SmoothSettings, fit_smooth_settings

__all__ = [
    "OUTPUT_TIMES",
    "LINK_PATH_ALPHA",
    "SHORT_LINK_Q_DEG2_PER_S3",
    "SmoothingResult",
    "check_track_lengths",
    "fit_smoothing",
    "smooth_bearings",
    "smoothed_columns",
]

#: Acceleration PSD of the links of short chains to later track starts in ``fusion smooth``,
#: deg^2/s^3 (:mod:`fusion.passive.smoothing.rescue`; tuning seeds 9200-9259 and diagnosis
#: seeds, docs/smoothing.md "Late starts": 1e-4 too narrow, 3e-3 links wrongly, 3e-4 - 1e-3
#: the same outcomes).
SHORT_LINK_Q_DEG2_PER_S3 = 5e-4

#: Significance level of the link-path test of ``fusion smooth`` (a link refused when the
#: scans of its gap without a detection near its path are less probable than this for a
#: target detected with ``P_D``; :mod:`fusion.passive.smoothing.linkpath`; tuning seeds
#: 9200-9259, docs/smoothing.md "Links through empty scans": 1e-3 - 1e-6 refused true links
#: across runs of misses, 1e-8 none).
LINK_PATH_ALPHA = 1e-8

#: Where the tracks are returned: the smoother's own state times, or a regular grid.
OUTPUT_TIMES = ("states", "grid")


@dataclass(frozen=True)
class SmoothingResult:
    """Smoothed tracks of a bearing table and the settings that made them.

    Attributes
    ----------
    tracks : tuple of SmoothedTrack
        One per track, bearings and rates in radians.
    settings : SmoothSettings
        Scales given or estimated (``settings.estimated`` names the estimated ones).
    association_clutter_density : float or None
        Clutter density the multi-track association used, /scan/rad (counted from the data
        when not given; None when the table has no unknown-origin rows).
    to_360 : bool
        Whether every input bearing was >= 0 (then :meth:`columns` writes [0, 360)).
    """

    tracks: tuple[SmoothedTrack, ...]
    settings: SmoothSettings
    association_clutter_density: float | None
    to_360: bool

    def columns(self) -> dict[str, NDArray[Any]]:
        """The rows of ``fusion smooth``'s output file (:func:`smoothed_columns`)."""
        return smoothed_columns(self.tracks, to_360=self.to_360)


def _radians(bearing_deg: Any) -> NDArray[np.float64]:
    """Bearings in radians; those beyond one turn (|deg| > 360) wrapped into [-pi, pi) first,
    the rest converted as they are (the smoothers take any branch within one turn)."""
    deg = np.asarray(bearing_deg, dtype=float)
    z = np.radians(deg)
    beyond = np.abs(deg) > 360.0
    if beyond.any():
        z[beyond] = wrap_angle(z[beyond])
    return z


def check_track_lengths(table: Mapping[str, Any] | Any) -> None:
    """Refuse labelled tracks with fewer than 2 distinct times (no rate can be estimated).

    Raises
    ------
    ValueError
        ``"track(s) 3, 7 have fewer than 2 distinct times; ..."``.
    """
    ids, times = np.asarray(table["track_id"]), np.asarray(table["time"], dtype=float)
    short = [int(k) for k in np.unique(ids[ids >= 0]) if np.unique(times[ids == k]).size < 2]
    if short:
        listed = ", ".join(map(str, short[:5])) + (", ..." if len(short) > 5 else "")
        raise ValueError(f"track(s) {listed} have fewer than 2 distinct times; "
                         "a bearing rate needs at least 2 samples per track")


def fit_smoothing(table: Mapping[str, Any] | Any, *, merge_deg: float = 1.0,
                  max_miss_s: float = 4.0, **given: Any) -> SmoothSettings:
    """The settings of :func:`smooth_bearings`: those in `given`, the others from the rows.

    Parameters
    ----------
    table : Table or mapping
        Columns ``track_id`` (-1: unknown origin), ``time`` (s), ``bearing_deg``.
    merge_deg : float, keyword-only
        Unknown-origin bearings of one scan closer than this are one detection before the fit,
        deg (the detections the tracker will see; 0: none).
    max_miss_s : float, keyword-only
        See :func:`~fusion.passive.smoothing.settings.fit_smooth_settings`.
    **given
        Any of ``sigma_bearing_deg, period_s, q_deg2_per_s3, clutter_density, p_detect,
        init_sigma_rate_deg_per_s, max_misses, max_gap_scans, min_length`` (None: estimate).
    """
    ids = np.asarray(table["track_id"])
    times = np.asarray(table["time"], dtype=float)
    z = _radians(table["bearing_deg"])
    merge = float(np.radians(merge_deg))
    unk = ids < 0
    if unk.any() and merge > 0:  # settings from the detections the tracker will see
        order = np.argsort(times[unk], kind="stable")
        tm, zm, _ = merge_scan_detections(times[unk][order], z[unk][order], within=merge)
        ids, times, z = (np.r_[ids[~unk], np.full(tm.size, -1)], np.r_[times[~unk], tm],
                         np.r_[z[~unk], zm])
    return fit_smooth_settings(ids, times, z, max_miss_s=max_miss_s, **given)


def smooth_bearings(
    table: Mapping[str, Any] | Any,
    *,
    settings: SmoothSettings | None = None,
    robust: str = "huber",
    association: str = "weighted",
    clutter_density: float | None = None,
    merge_deg: float = 1.0,
    twin_deg: float = 4.0,
    output_times: str = "states",
    max_miss_s: float = 4.0,
    extend_ends: bool = False,
    end_detections: str = "own",
    link_gate: float = 30.0,
    relink_gate: float = 100.0,
    crossing_gap_scans: int | None = 60,
    link_curvature: bool = True,
    extend_starts: bool = False,
    short_link_q_deg2_per_s3: float = SHORT_LINK_Q_DEG2_PER_S3,
    link_path_alpha: float = LINK_PATH_ALPHA,
    on_rows: Callable[[int], None] | None = None,
    **given: Any,
) -> SmoothingResult:
    """Smooth a bearing table as ``fusion smooth`` does, its scales estimated from the rows.

    Parameters
    ----------
    table : Table or mapping
        Columns ``track_id`` (>= 0: a labelled track, smoothed alone; -1: a detection of
        unknown origin, tracked and smoothed jointly through crossings), ``time`` (s) and
        ``bearing_deg`` (deg).
    settings : SmoothSettings, keyword-only
        Scales fitted before (:func:`fit_smoothing`); default: fitted here, with `given`.
    robust, association, clutter_density, merge_deg, twin_deg, output_times, max_miss_s
        As the options of ``fusion smooth`` (``--robust``, ``--association``,
        ``--clutter-density``, ``--merge-deg``, ``--twin-deg``, ``--output-times``,
        ``--max-miss-s``); angles in degrees.
    extend_ends : bool, keyword-only
        Tracks from unknown-origin rows extended over the ambiguous detections beyond their
        first and last segments (``fusion smooth --end-extension``: True; default False).
    end_detections, link_gate, relink_gate, crossing_gap_scans, link_curvature : keyword-only
        As :class:`~fusion.passive.smoothing.multitrack.MultiTrackSmoother`'s
        (``--end-detections``, ``--link-gate``, ``--relink-gate``,
        ``--crossing-gap-scans``, ``--link-curvature``; the last two on here, off in the
        library).
    extend_starts : bool, keyword-only
        Tracks extended over the ambiguous detections before their first segment only
        (``--start-extension``; default False).
    short_link_q_deg2_per_s3 : float, keyword-only
        Acceleration PSD of the links of chains too short to be kept to later track starts,
        deg^2/s^3 (``--short-link-accel-psd-deg2-per-s3``; 0: none).
    link_path_alpha : float, keyword-only
        Significance level of the link-path test (``--link-path-alpha``; 0: none).
    on_rows : callable, keyword-only
        Progress callback of the smoothing (see
        :func:`fusion.passive.smoothing.table.smooth_bearings`).
    **given
        Scales to use instead of estimating them (``sigma_bearing_deg=0.5``, ...; see
        :func:`fit_smoothing`); ignored with `settings`.

    Returns
    -------
    SmoothingResult

    Raises
    ------
    ValueError
        A labelled track with fewer than 2 distinct times, a bad option.
    RuntimeError
        GTSAM found the graph ill-posed.
    """
    if output_times not in OUTPUT_TIMES:
        raise ValueError(f"output_times must be one of {OUTPUT_TIMES}, got {output_times!r}")
    check_track_lengths(table)
    st = settings if settings is not None else fit_smoothing(
        table, merge_deg=merge_deg, max_miss_s=max_miss_s, clutter_density=clutter_density,
        **given)
    sigma = np.radians(st.sigma_bearing_deg)
    q = st.q_deg2_per_s3 * np.radians(1.0) ** 2
    single = BearingSmoother(sigma_bearing=sigma, q=q, robust=robust)
    # the association's clutter density: given, or counted by the tracker from the detections
    # its tracks leave (closer to the truth than the pair-scatter estimate, issue 18)
    multi = MultiTrackSmoother(sigma_bearing=sigma, q=q, clutter_density=clutter_density,
                               p_detect=st.p_detect, min_length=st.min_length,
                               association=association,
                               init_sigma_rate=np.radians(st.init_sigma_rate_deg_per_s),
                               max_misses=st.max_misses, max_gap_scans=st.max_gap_scans,
                               extend_ends=extend_ends, end_detections=end_detections,
                               link_gate=link_gate, relink_gate=relink_gate,
                               crossing_gap_scans=crossing_gap_scans,
                               link_curvature=link_curvature, extend_starts=extend_starts,
                               short_link_q=short_link_q_deg2_per_s3 * np.radians(1.0) ** 2,
                               link_path_alpha=link_path_alpha)
    bearing_deg = np.asarray(table["bearing_deg"], dtype=float)
    times = np.asarray(table["time"], dtype=float)
    tracks = smooth_rows(np.asarray(table["track_id"]), times, _radians(bearing_deg),
                         single=single, multi=multi, merge_within=float(np.radians(merge_deg)),
                         twin_within=float(np.radians(twin_deg)), on_rows=on_rows)
    if output_times == "grid":
        tracks = tuple(on_grid(tr, period=st.period_s, q=q, max_gap_s=st.max_gap_scans * st.period_s,
                               origin=float(np.min(times))) for tr in tracks)
    counted = getattr(multi, "used_clutter_density", None)
    return SmoothingResult(tracks=tuple(tracks), settings=st,
                           association_clutter_density=None if counted is None else float(counted),
                           to_360=bool(np.all(bearing_deg >= 0)))


def smoothed_columns(tracks: tuple[SmoothedTrack, ...], *, to_360: bool) -> dict[str, NDArray[Any]]:
    """Columns ``track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg``.

    Bearings in [0, 360) with `to_360`, else in [-180, 180) (``docs/formats.md``, section 7).
    """
    cols: dict[str, list[np.ndarray]] = {k: [] for k in (
        "track_id", "time", "bearing_deg", "bearing_rate_deg_per_min", "sigma_bearing_deg")}
    for tr in tracks:
        b = np.degrees(tr.bearing)
        cols["track_id"].append(np.full(len(tr), tr.track_id, np.int64))
        cols["time"].append(tr.times)
        cols["bearing_deg"].append(np.mod(b, 360.0) if to_360 else b)
        cols["bearing_rate_deg_per_min"].append(np.degrees(tr.rate) * 60.0)
        cols["sigma_bearing_deg"].append(np.degrees(tr.sigma_bearing))
    return {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in cols.items()}
