"""Speed prior from a pilot run: the speeds of confirmed, consistent tracks.

:func:`fusion.active.settings.track_settings` reads the velocity prior of a new track from
chains of straight-line triplets of detections. Where clutter is dense, chance strings clutter
into straight, fast "chains" that the chance test lets through, and the prior comes out far above
the speeds of the real objects (9.8 m/s for a 1.6-m/s target in 15 clutter echoes per receiver and
ping; 3 and 5.7 m/s for harbour boats doing 2.3-3 m/s, issue 20). A wide prior widens every new
track's gate, lets it take more clutter and weakens the track score of its hits. The objects
the tracker itself confirms are better evidence: :func:`pilot_speed_prior` runs the tracker
once over the same pings with the triplet settings and takes the speeds of the confirmed tracks
that are consistent:

- at least ``min_hits`` pings with a detection while confirmed, on at least half of their
  confirmed pings (a track coasting through clutter is not a measured speed);
- speed (end-to-end displacement of the confirmed track over its confirmed span) above
  ``min_speed_mps`` (a still object says nothing about how fast targets move);
- not more than three times the median speed of the others (one fast false track does not
  decide).

The prior is the length-weighted median of those speeds, per axis: a target at twice the
median speed starts within two standard deviations of a still start. With no consistent moving
track the triplet estimate stays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fusion.active.tracker import Tracker
from fusion.active.types import Ping, TrackingResult

__all__ = ["PilotSpeed", "fitted_tracker_options", "pilot_speed_prior", "track_speeds"]

#: Fewest detections of a confirmed track whose speed counts.
MIN_HITS = 5


@dataclass(frozen=True)
class PilotSpeed:
    """What the pilot run found.

    Attributes
    ----------
    speed_sigma_mps : float or None
        The prior (None: no consistent moving track).
    speeds_mps : tuple of float
        Speeds of the tracks used, m/s.
    tracks : int
        Confirmed tracks of the pilot run.
    """

    speed_sigma_mps: float | None
    speeds_mps: tuple[float, ...]
    tracks: int


def track_speeds(result: TrackingResult, *, min_hits: int = MIN_HITS,
                 min_speed_mps: float = 0.5) -> tuple[list[float], list[int], int]:
    """Speeds and hit counts of the consistent moving confirmed tracks of a tracking result.

    Parameters
    ----------
    result : fusion.active.types.TrackingResult
    min_hits : int, optional
        Fewest confirmed pings with a detection.
    min_speed_mps : float, optional
        Slower tracks are left out, m/s.

    Returns
    -------
    speeds : list of float
        m/s, one per kept track.
    hits : list of int
        Their confirmed hits.
    confirmed : int
        Confirmed tracks in all.
    """
    rows: dict[int, list[tuple[float, float, float, bool]]] = {}
    for p in result.pings:
        conf = p.status == "confirmed"
        for tid, st, hit in zip(p.track_id[conf].tolist(), p.state[conf].reshape(-1, 4).tolist(),
                                (p.detection[conf] >= 0).tolist(), strict=True):
            rows.setdefault(tid, []).append((p.time, st[0], st[1], hit))
    speeds, hits = [], []
    for r in rows.values():
        a = np.asarray(r, dtype=float)
        n_hit = int(a[:, 3].sum())
        span = a[-1, 0] - a[0, 0]
        if n_hit < min_hits or n_hit < 0.5 * len(r) or span <= 0:
            continue
        v = float(np.hypot(a[-1, 1] - a[0, 1], a[-1, 2] - a[0, 2]) / span)
        if v > min_speed_mps:
            speeds.append(v)
            hits.append(n_hit)
    return speeds, hits, len(rows)


def _weighted_median(values: Sequence[float], weights: Sequence[float]) -> float:
    v, w = np.asarray(values, float), np.asarray(weights, float)
    order = np.argsort(v)
    c = np.cumsum(w[order])
    return float(v[order][np.searchsorted(c, 0.5 * c[-1])])


def pilot_speed_prior(pings: Sequence[Ping], tracker: Tracker, *,
                      min_hits: int = MIN_HITS, min_speed_mps: float = 0.5) -> PilotSpeed:
    """Velocity prior per axis from the confirmed tracks of a pilot run (module docstring).

    Parameters
    ----------
    pings : sequence of Ping
        The pings to run over (e.g. the first ``--fit-pings``).
    tracker : Tracker
        The tracker of the pilot run (configured with the triplet settings); it is reset
        before and after.
    min_hits, min_speed_mps : optional
        As in :func:`track_speeds`.

    Returns
    -------
    PilotSpeed
    """
    result = tracker.run(list(pings))
    tracker.reset()
    speeds, hits, n = track_speeds(result, min_hits=min_hits, min_speed_mps=min_speed_mps)
    if not speeds:
        return PilotSpeed(None, (), n)
    s, h = np.asarray(speeds), np.asarray(hits, float)
    if s.size > 1:
        keep = np.array([s[i] <= 3.0 * np.median(np.delete(s, i)) for i in range(s.size)])
        s, h = s[keep], h[keep]
    return PilotSpeed(_weighted_median(s, h), tuple(float(x) for x in s), n)


def fitted_tracker_options(pings: Sequence[Ping], **tracker_kw: object) -> dict[str, object]:
    """:class:`~fusion.active.tracker.Tracker` options ``fusion track`` chooses for these pings
    with no scale given: the triplet scales (:func:`fusion.active.settings.track_settings`),
    then the speed prior of a pilot run of the tracker with those scales and `tracker_kw`
    (:func:`pilot_speed_prior`; fuzzy mode only). `tracker_kw` is not part of the result."""
    from fusion.active.settings import track_settings

    st = track_settings(pings)
    if tracker_kw.get("mode", "fuzzy") == "fuzzy":
        pilot = pilot_speed_prior(
            pings, Tracker(**{**st.tracker_options(), **tracker_kw}),
            min_speed_mps=float(tracker_kw.get("min_speed_mps", 0.5)))  # type: ignore[arg-type]
        if pilot.speed_sigma_mps is not None:
            st = st.with_track_speed(pilot.speed_sigma_mps, len(pilot.speeds_mps))
    return st.tracker_options()
