"""Track management of the multistatic tracker: M-of-N confirmation, deletion, the motion test.

Section 2.5 of "Target tracking using fuzzy logic association" ("Tracker"): a tentative
(potential) track is confirmed once it has ``m`` hits within its first ``n`` pings (the paper's
tracks are "at least three detections long") and deleted when that can no longer happen; a
confirmed track is deleted after ``max_misses`` consecutive misses (:func:`advance_status`). A
tentative track that comes within reach of a clutter-map hotspot is dropped, since it is the
hotspot, unless its own detections show that it moves (:class:`~fusion.active.motion.MotionTest`:
a hotspot stands still, a submarine does not).

Choices where the paper is silent
---------------------------------
- Motion test of a tentative track: the generalised least-squares velocity of its own associated
  detections (constant velocity, no process noise, each detection with its own position
  covariance) against zero, chi-square with 2 degrees of freedom at ``probability`` (default
  0.999), from its third detection on (:func:`~fusion.active.motion.motion_statistic`). The
  Kalman velocity is not used for this: its covariance carries the process noise and stays too
  wide for a slow target to ever look significant. A slow target seen by several receivers piles
  its echoes into one clutter-map neighbourhood on its first pings and looks like a hotspot there;
  the test keeps its track alive once it has moved significantly. The high confidence (0.999)
  dates from isotropic errors, when far-geometry hotspot echoes scattered by more than
  ``position_sigma_m`` and inflated the statistic of a stationary track; with geometric errors
  0.99 was tried and confirmed more false tracks on the validation seeds, so 0.999 stays.
- Confirmation of stationary tracks (:func:`next_lifecycle` with ``held``). The clutter map flags
  a feature once a 3 x 3 cell neighbourhood has been visited on ``min_pings`` (3) pings; a feature
  seen by one or two receivers in far geometry scatters its echoes over more than one
  neighbourhood (bearing errors of ~170 m per axis against 150-m cells) or skips a ping (it
  echoes on 70 % of them), so it often becomes a hotspot one or two pings after a 3-of-4 track on
  it is confirmed (on its third ping), too late for the hotspot drop, which only ends tentative
  tracks. On validation seeds 200-299 these were 25 of the 51 confirmed false tracks. The track's
  own detections are the same evidence the map looks for (echoes from one place on most pings),
  so on the ping that would confirm it a track must also pass the motion test; if it does not, it
  stays tentative, is confirmed on a later hit that makes it move, is dropped once the map flags
  the feature, and is deleted after ``max_misses`` consecutive misses, like a confirmed track. A
  slow sonar target is held only until it has moved significantly. With a fast update rate and
  small position errors (the Autoferry radar: scans seconds apart, 10-m errors) slow boats take
  many scans to move significantly and are held that long, which costs coverage there (see
  RESULTS). The motion test's speed floor is derived from the position error
  (:func:`fusion.active.motion.still_speed_mps`), so that a fixed sonar-sized floor does not add
  to that wait on a radar.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from fusion.active.motion import MotionTest

if TYPE_CHECKING:
    from fusion.active.platform import PlatformTest

__all__ = [
    "MAX_COAST_MISSES",
    "Lifecycle",
    "advance_status",
    "coast_misses",
    "hotspot_drop",
    "next_lifecycle",
    "HoldTests",
    "hold_tests",
    "stationary_hold",
    "track_status",
]


@dataclass(frozen=True)
class Lifecycle:
    """Track-management counters of one track.

    Attributes
    ----------
    status : {"tentative", "confirmed", "deleted"}
    age : int
        Pings since birth, the birth ping included.
    hits : int
        Pings with an associated detection, the birth ping included.
    misses : int
        Consecutive misses (counted once confirmed).
    """

    status: str = "tentative"
    age: int = 1
    hits: int = 1
    misses: int = 0


def advance_status(state: Lifecycle, hit: bool, *, m: int, n: int, max_misses: int) -> Lifecycle:
    """One ping of M-of-N confirmation and miss-count deletion.

    Parameters
    ----------
    state : Lifecycle
        Counters before the ping.
    hit : bool
        Whether the track got a detection on this ping.
    m, n : int
        Confirm once ``m`` hits are reached within the first ``n`` pings of the track; delete a
        tentative track when that can no longer happen.
    max_misses : int
        Delete a confirmed track after this many consecutive misses.

    Returns
    -------
    Lifecycle
    """
    if state.status == "deleted":
        return state
    age, hits = state.age + 1, state.hits + int(hit)
    if state.status == "tentative":
        if hits >= m:
            return Lifecycle("confirmed", age, hits, 0)
        if hits + (n - age) < m:
            return Lifecycle("deleted", age, hits, 0)
        return Lifecycle("tentative", age, hits, 0)
    misses = 0 if hit else state.misses + 1
    return Lifecycle("deleted" if misses >= max_misses else "confirmed", age, hits, misses)


def track_status(history: Sequence[bool], *, m: int, n: int, max_misses: int) -> str:
    """Status after a hit/miss history; ``history[0]`` is the birth ping (a hit).

    Examples
    --------
    >>> track_status([True, True, False, True], m=3, n=4, max_misses=3)
    'confirmed'
    >>> track_status([True, False, False], m=3, n=4, max_misses=3)
    'deleted'
    """
    state = Lifecycle()
    for hit in history[1:]:
        state = advance_status(state, bool(hit), m=m, n=n, max_misses=max_misses)
    return state.status



def next_lifecycle(
    state: Lifecycle, hit: bool | int, *, dropped: bool, held: bool, m: int, n: int,
    max_misses: int, window: bool = True,
) -> Lifecycle:
    """One ping of track management, hotspot drop and stationary hold included.

    Parameters
    ----------
    state, hit
        As in :func:`advance_status`.
    dropped : bool
        A tentative track within reach of a hotspot whose detections do not move: deleted.
    held : bool
        A tentative track about to be confirmed whose detections do not move: stays tentative
        (a hit).
    m, n, max_misses : int
        As in :func:`advance_status`.
    window : bool, optional
        True (default): a tentative track is deleted once ``m`` hits within its first ``n``
        pings can no longer happen (:func:`advance_status`). False: no window; a tentative
        track is deleted after ``max_misses`` consecutive misses instead (for a tracker that
        ends weak tentative tracks by their track score).

    Returns
    -------
    Lifecycle
        A track held earlier (tentative with ``hits >= m``) that misses is deleted after
        ``max_misses`` consecutive misses, like a confirmed track; otherwise
        :func:`advance_status`. `hit` may be a count of detections (each counts towards ``m``).
    """
    if dropped:
        return Lifecycle("deleted", state.age + 1, state.hits + int(hit), 0)
    if held:
        return Lifecycle("tentative", state.age + 1, state.hits + max(int(hit), 1), 0)
    if state.status == "tentative" and (state.hits >= m or not window) and not hit:
        misses = state.misses + 1
        return Lifecycle("deleted" if misses >= max_misses else "tentative",
                         state.age + 1, state.hits, misses)
    return advance_status(state, hit, m=m, n=n if window else max(n, state.age + 2),
                          max_misses=max_misses)


#: Most consecutive missed pings a confirmed track coasts, whatever the detection probability.
MAX_COAST_MISSES = 20


def coast_misses(pds: Sequence[float], *, probability: float, floor: int) -> int:
    """Consecutive missed pings that delete a confirmed track, matched to the detection
    probabilities.

    Parameters
    ----------
    pds : sequence of float
        ``P_D`` of each receiver of the ping.
    probability : float
        Chance of that many consecutive misses of a real target, in (0, 1).
    floor : int
        Fewest misses (``max_misses``).

    Returns
    -------
    int
        The fewest ``k`` with ``q^k <= probability``, ``q = prod_r (1 - P_D,r)`` the chance
        that no receiver detects the target on a ping, at least `floor` and at most
        :data:`MAX_COAST_MISSES` (a target one receiver sees on a third of the pings coasts
        for 12 misses, not 5).

    Examples
    --------
    >>> coast_misses([1 / 3], probability=0.01, floor=5)
    12
    >>> coast_misses([0.9, 0.9], probability=0.01, floor=5)
    5
    """
    q = float(np.prod([1.0 - p for p in pds])) if len(pds) else 1.0
    if q <= 0.0:
        return int(floor)
    if q >= 1.0:
        return max(int(floor), MAX_COAST_MISSES)
    need = int(np.ceil(np.log(probability) / np.log(q)))
    return max(int(floor), min(need, MAX_COAST_MISSES))


def hotspot_drop(near: NDArray[np.bool_], seen: Sequence[Sequence[Sequence[float]]],
                 motion_test: MotionTest) -> NDArray[np.bool_]:
    """Tentative tracks near a hotspot to delete: those whose own detections do not move.

    Parameters
    ----------
    near : ndarray of bool, shape (n_tracks,)
        Tentative tracks within reach of a hotspot region.
    seen : sequence of rows
        Each track's detections (:meth:`MotionTest.moves`).
    motion_test : MotionTest

    Returns
    -------
    ndarray of bool, shape (n_tracks,)
        A potential track inside a hotspot's reach is the hotspot, not a target, unless its
        detections move significantly (a slow target mistaken for a hotspot).
    """
    out = np.array(near, dtype=bool)
    for i in np.flatnonzero(out).tolist():
        out[i] = motion_test.moves(seen[i]) is not True
    return out


def stationary_hold(
    candidates: NDArray[np.bool_], lives: Sequence[Lifecycle],
    seen: Sequence[Sequence[Sequence[float]]], *, m: int | NDArray[np.int64],
    motion_test: MotionTest | None,
    score_short: NDArray[np.bool_] | None, platform_test: PlatformTest | None = None,
    shadowed: NDArray[np.bool_] | None = None, counts: Sequence[int] | None = None,
) -> NDArray[np.bool_]:
    """Tentative tracks with a hit that would confirm them but that stay tentative.

    Parameters
    ----------
    candidates : ndarray of bool, shape (n_tracks,)
        Tentative tracks with a hit on this ping.
    lives : sequence of Lifecycle
        Their counters before the ping.
    seen : sequence of rows
        Their detections (:meth:`MotionTest.moves`).
    m : int or ndarray of int, shape (n_tracks,)
        Hits that confirm (per track: a successor needs one fewer, :mod:`fusion.active.births`).
    motion_test : MotionTest or None
        Hold tracks whose detections stand still (None: no such hold).
    score_short : ndarray of bool, shape (n_tracks,), or None
        Tracks whose track score is still below the confirmation score (held too).
    platform_test : PlatformTest, optional
        Hold tracks whose detections are steady relative to a sensor that moved
        (:class:`fusion.active.platform.PlatformTest`; the rows then carry the sensor position
        in columns 6-7). None (default): no such hold.
    shadowed : ndarray of bool, shape (n_tracks,), optional
        Tracks whose latest detection lies behind a near confirmed track
        (:class:`fusion.active.shadow.ShadowTest`): held too.
    counts : sequence of int, optional
        Hits each track adds on this ping (default 1 each; the tracker's
        ``hits_per_detection`` counts detections).

    Returns
    -------
    ndarray of bool, shape (n_tracks,)

    Notes
    -----
    A feature echoes from one place, a submarine moves. The clutter map may not have flagged the
    feature yet, so this is the track-level form of the map's test; once the map flags it, the
    hotspot's echoes count as clutter in the track score (or the hotspot drop ends the track). A
    track whose hits are no better explained by a target than by clutter waits for more evidence
    the same way.
    """
    hold = np.zeros(len(candidates), dtype=bool)
    for i in np.flatnonzero(candidates).tolist():
        if lives[i].hits + (1 if counts is None else counts[i]) < (m if np.ndim(m) == 0 else m[i]):
            continue
        if score_short is not None and score_short[i]:
            hold[i] = True
        elif motion_test is not None:
            hold[i] = motion_test.moves(seen[i]) is False
        if not hold[i] and platform_test is not None:
            hold[i] = platform_test.fixed(seen[i]) is True
        if not hold[i] and shadowed is not None:
            hold[i] = bool(shadowed[i])
    return hold


@dataclass(frozen=True)
class HoldTests:
    """The tests that keep a tentative track tentative (:func:`stationary_hold`): the motion
    test of its own detections, the platform test (None: off) and the shadow test (None: off),
    with the speed below which an object counts as standing still, m/s."""

    min_speed_mps: float
    motion: MotionTest
    platform: PlatformTest | None
    shadow: object | None


def hold_tests(*, fuzzy: bool, position_sigma_m: float, motion_probability: float,
               min_speed_mps: float | None, still_wander_s: float, motion_recent: bool,
               reject_platform_fixed: bool, shadow: bool,
               shadow_extent_sigmas: float) -> HoldTests:
    """The hold tests of a tracker from its settings (:class:`fusion.active.tracker.Tracker`).

    `min_speed_mps` None: ``position_sigma_m / still_wander_s``
    (:func:`fusion.active.motion.still_speed_mps`). The platform and shadow tests exist in fuzzy
    mode only.

    Examples
    --------
    >>> t = hold_tests(fuzzy=True, position_sigma_m=125.0, motion_probability=0.999,
    ...                min_speed_mps=None, still_wander_s=250.0, motion_recent=False,
    ...                reject_platform_fixed=True, shadow=False, shadow_extent_sigmas=8.0)
    >>> t.min_speed_mps, t.platform is not None, t.shadow is None
    (0.5, True, True)
    """
    from fusion.active.motion import still_speed_mps
    from fusion.active.platform import PlatformTest
    from fusion.active.shadow import ShadowTest

    if min_speed_mps is None:
        min_speed_mps = still_speed_mps(position_sigma_m, still_wander_s)
    speed = float(min_speed_mps)
    return HoldTests(
        min_speed_mps=speed,
        motion=MotionTest(probability=motion_probability, min_speed_mps=speed,
                          recent=motion_recent),
        platform=(PlatformTest(probability=motion_probability, min_speed_mps=speed)
                  if fuzzy and reject_platform_fixed else None),
        shadow=(ShadowTest(position_sigma_m=position_sigma_m, extent_sigmas=shadow_extent_sigmas)
                if fuzzy and shadow else None))
