"""Crossing episodes of the passive pipeline: tracks through a predicted crossing, then EM association.

When the crossing detector predicts that two tracks of one frequency band will cross, their lines
merge into one main lobe for a while and a track's own peak search cannot tell them apart. For
that *episode* the tracks coast on their constant-rate prediction (no bearing enters their
graphs) while every peak they find is kept as a detection of unknown origin. When the episode
closes, the detections go, with each track's own bearings from just before the episode, into the
association-weighted multi-track graph (:class:`fusion.passive.smoothing.MultiTrackSmoother`,
EM); the tracks it forms are matched to the pipeline's tracks through those labelled context
bearings and checked against the tracks' own constant-rate predictions, and every detection it
assigns is handed back to its track as a bearing on the state of its scan, still inside the
track's fixed-lag window. When the match or the check fails, each scan's detections go to the
nearest predictions instead.

- :class:`EpisodeBook` keeps the episodes: scheduled from alerts, open, due.
- :class:`CrossingResolver` resolves a closed episode (:meth:`CrossingResolver.resolve`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from fusion._validation import check_positive
from fusion.passive.smoothing import MultiTrackSmoother

__all__ = ["CrossingEpisode", "CrossingResolution", "CrossingResolver", "EpisodeBook"]

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


@dataclass
class CrossingEpisode:
    """An episode's data (mutable while it is open).

    Attributes
    ----------
    members : list of int
        Track ids in the episode.
    t_open, t_close, t_cross : float
        Episode span (planned until it opens and closes) and predicted crossing time, s.
    context : dict of int to list of (float, float, float)
        Per member, its own ``(time, bearing (rad), sigma (rad))`` from before the episode.
    detections : list of (float, float, float)
        ``(time, bearing, sigma)`` of the peaks found by the members during the episode.
    predictions : dict of int to list of (float, float, float)
        Per member and episode scan, ``(time, predicted bearing (rad), innovation std (rad))``.
    opened : bool
        Whether the episode has opened.
    clear : int
        Consecutive scans, since it opened, in which the members' peaks were apart.
    """

    members: list[int]
    t_open: float
    t_close: float
    t_cross: float
    context: dict[int, list[tuple[float, float, float]]] = field(default_factory=dict)
    detections: list[tuple[float, float, float]] = field(default_factory=list)
    predictions: dict[int, list[tuple[float, float, float]]] = field(default_factory=dict)
    opened: bool = False
    clear: int = 0

    def record(
        self,
        track_id: int,
        time: float,
        *,
        bearing: float,
        sigma: float,
        predicted: float,
        innovation_std: float,
        context: list[tuple[float, float, float]],
    ) -> None:
        """Keep one member's scan: its peak (once per peak), its prediction, and, on its first
        scan in the episode, its own bearings from before (`context`)."""
        if track_id not in self.context:
            self.context[track_id] = list(context)
        if not any(d[0] == time and d[1] == bearing for d in self.detections):
            self.detections.append((time, bearing, sigma))  # two members on one peak: once
        self.predictions.setdefault(track_id, []).append((time, predicted, innovation_std))


@dataclass(frozen=True)
class CrossingResolution:
    """How a crossing episode was resolved.

    Attributes
    ----------
    tracks : tuple of int
        Track ids of the episode.
    t_start, t_end : float
        Episode span, s.
    t_cross : float
        Predicted crossing time, s.
    method : str
        ``"multitrack"`` (EM association through the multi-track graph) or ``"nearest"`` (the
        fallback: per scan, the assignment of detections to the tracks' predictions).
    n_detections : int
        Detections of unknown origin in the episode.
    n_assigned : int
        Of those, detections handed to a track.
    fallback : str
        Why the multi-track graph's association was not used (``method == "nearest"``):
        ``"graph failed"`` (GTSAM could not solve it), ``"no match"`` (its tracks do not match
        the episode's one to one), ``"contradicts motion"``, ``"no context"``; empty otherwise.
        Counted and printed by the passive benchmark instead of falling back silently.
    """

    tracks: tuple[int, ...]
    t_start: float
    t_end: float
    t_cross: float
    method: str
    n_detections: int
    n_assigned: int
    fallback: str = ""


class EpisodeBook:
    """Scheduled and open crossing episodes.

    Parameters
    ----------
    separation_lobes : float
        Two tracks are *merged* while the peaks their searches find are closer than this many
        main-lobe widths; half the planned episode is the time the pair needs to draw that far
        apart at their rate difference.
    min_half_s : float
        Shortest planned half episode, s.
    max_span_s : float
        Longest episode, s (it must fit in the tracks' fixed lag).
    clear_scans : int
        Consecutive scans without merged peaks, after the predicted crossing, that close an
        episode.

    Notes
    -----
    An episode is scheduled by a predicted crossing at ``t_c`` with the planned window
    ``t_c -+ half``. It opens at the start of that window or as soon as the pair's peaks merge,
    whichever comes first, and closes once past ``t_c`` the peaks have been apart for
    `clear_scans` scans (the lines separated again), or when it reaches `max_span_s`, or when a
    member ends. Episodes sharing a track and overlapping in time are one episode.
    """

    def __init__(self, *, separation_lobes: float = 1.5, min_half_s: float, max_span_s: float,
                 clear_scans: int = 3) -> None:
        self.separation_lobes = check_positive("separation_lobes", separation_lobes)
        self.min_half_s = check_positive("min_half_s", min_half_s)
        self.max_span_s = check_positive("max_span_s", max_span_s)
        if self.max_span_s < 2.0 * self.min_half_s:
            raise ValueError(f"max_span_s ({max_span_s}) is below 2 min_half_s ({min_half_s})")
        if int(clear_scans) != clear_scans or clear_scans < 1:
            raise ValueError(f"clear_scans must be a positive integer, got {clear_scans!r}")
        self.clear_scans = int(clear_scans)
        self.episodes: list[CrossingEpisode] = []

    def schedule(self, pair: tuple[int, int], *, now: float, t_cross: float,
                 rate_diff: float, beamwidth: float) -> None:
        """Plan an episode around a predicted crossing (merged with overlapping ones).

        Parameters
        ----------
        pair : (int, int)
            The two tracks.
        now : float
            Current time, s.
        t_cross : float
            Predicted crossing time, s.
        rate_diff : float
            Bearing-rate difference of the pair, rad/s.
        beamwidth : float
            Main-lobe width at the crossing bearing, rad.
        """
        half = self.separation_lobes * beamwidth / max(abs(rate_diff), 1e-12)
        half = min(max(half, self.min_half_s), 0.5 * self.max_span_s)
        t_open, t_close = max(now, t_cross - half), t_cross + half
        for ep in self.episodes:
            if set(pair) & set(ep.members) and t_open <= ep.t_close and ep.t_open <= t_close:
                ep.members.extend(m for m in pair if m not in ep.members)
                if not ep.opened:
                    ep.t_open = min(ep.t_open, t_open)
                ep.t_close = max(ep.t_close, t_close)
                ep.t_cross = max(ep.t_cross, t_cross)
                return
        self.episodes.append(CrossingEpisode(members=list(pair), t_open=t_open,
                                             t_close=t_close, t_cross=t_cross))

    def _merged(self, ep: CrossingEpisode, beams: dict[int, float],
                lobes: dict[int, float]) -> bool:
        ms = [m for m in ep.members if m in beams]
        return any(abs(beams[a] - beams[b]) < self.separation_lobes * min(lobes[a], lobes[b])
                   for i, a in enumerate(ms) for b in ms[i + 1:])

    def observe(self, time: float, beams: dict[int, float], lobes: dict[int, float]) -> None:
        """Open and watch episodes with this scan's peaks.

        Parameters
        ----------
        time : float
            Scan time, s.
        beams : dict of int to float
            Beam of the peak each live track found at this scan.
        lobes : dict of int to float
            Main-lobe width of each track's band, beams.
        """
        for ep in self.episodes:
            merged = self._merged(ep, beams, lobes)
            if not ep.opened and (time >= ep.t_open - 1e-9 or merged):
                ep.opened = True
                ep.t_open = time
            if ep.opened:
                ep.clear = 0 if merged else ep.clear + 1

    def member_of(self, track_id: int) -> CrossingEpisode | None:
        """The open episode holding `track_id`, if any."""
        for ep in self.episodes:
            if ep.opened and track_id in ep.members:
                return ep
        return None

    def close_due(self, time: float, *, ended: set[int]) -> list[CrossingEpisode]:
        """Remove and return the open episodes that close now (see the class notes).

        Scheduled episodes whose tracks ended are dropped; ended members leave their episode.
        """
        due, keep = [], []
        for ep in self.episodes:
            gone = [m for m in ep.members if m in ended]
            if not ep.opened:
                if not gone:
                    keep.append(ep)
                continue
            apart = time >= ep.t_cross and ep.clear >= self.clear_scans
            if gone or apart or time - ep.t_open >= self.max_span_s - 1e-9:
                ep.members = [m for m in ep.members if m not in ended]
                ep.t_close = time
                if ep.members:
                    due.append(ep)
            else:
                keep.append(ep)
        self.episodes = keep
        return due


class CrossingResolver:
    """Association of a closed crossing episode's detections through the multi-track graph.

    Parameters
    ----------
    clutter_density : float
        Clutter component of the EM responsibilities, detections per scan per radian.
    p_detect : float
        Probability that a track shows a peak in a scan.
    min_share : float
        Share of a track's labelled context bearings that one multi-track track must own to be
        matched to it.
    gate : float
        Gate of the fallback assignment, innovation standard deviations.
    min_consistent : float
        Share of a track's detections from the multi-track graph, past the predicted crossing,
        that must be nearer its own prediction than any other track's.

    Notes
    -----
    The association-weighted multi-track graph of the design notes ("Factor graphs": near a
    predicted crossing, measurements of uncertain origin enter both tracks through association-
    weighted factors), run by :class:`~fusion.passive.smoothing.MultiTrackSmoother` with the
    bearing noise of the episode's measurements. Its tracks are matched to the episode's tracks
    by the majority owner of each track's context bearings (at least `min_share` of them, one
    to one). The graph sees only bearings, not the tracks' states before the episode; on long
    merges (slow crossings, tuning seeds 100-104) it linked the segments as if the lines had
    bounced. Its association is therefore kept only if it agrees with the tracks' own motion:
    past the predicted crossing, at least `min_consistent` of the detections it gives a track
    are nearer (in innovation standard deviations) that track's constant-rate prediction than
    any other track's. Otherwise, or if the match fails, the detections of each scan are
    assigned to the tracks' predictions (``scipy.optimize.linear_sum_assignment`` on squared
    normalised innovations, gated).
    """

    def __init__(
        self,
        *,
        clutter_density: float = 0.1,
        p_detect: float = 0.9,
        min_share: float = 0.5,
        gate: float = 4.0,
        min_consistent: float = 0.5,
    ) -> None:
        self.clutter_density = check_positive("clutter_density", clutter_density)
        if not 0.0 < p_detect <= 1.0:
            raise ValueError(f"p_detect must lie in (0, 1], got {p_detect!r}")
        self.p_detect = float(p_detect)
        if not 0.0 < min_share <= 1.0:
            raise ValueError(f"min_share must lie in (0, 1], got {min_share!r}")
        self.min_share = float(min_share)
        self.gate = check_positive("gate", gate)
        if not 0.0 <= min_consistent <= 1.0:
            raise ValueError(f"min_consistent must lie in [0, 1], got {min_consistent!r}")
        self.min_consistent = float(min_consistent)

    def resolve(
        self, episode: CrossingEpisode, *, scan_period: float, q: float
    ) -> tuple[CrossingResolution, dict[int, tuple[FloatArray, FloatArray, FloatArray]]]:
        """Assign the episode's detections to its tracks.

        Parameters
        ----------
        episode : CrossingEpisode
            A closed episode.
        scan_period : float
            Time between scans, s.
        q : float
            Bearing-acceleration PSD of the tracks, rad^2/s^3.

        Returns
        -------
        resolution : CrossingResolution
        assigned : dict of int to (ndarray, ndarray, ndarray)
            Per track, the ``(times, bearings, sigmas)`` handed to it.
        """
        dets = np.array(episode.detections, dtype=float).reshape(-1, 3)
        assigned: dict[int, tuple[FloatArray, FloatArray, FloatArray]] = {}
        method = "multitrack"
        owner, why = (self._multitrack(episode, dets, scan_period, q) if dets.shape[0]
                      else (None, "no detections"))
        if owner is None:
            method = "nearest"
            owner = self._nearest(episode, dets)
        for m in episode.members:
            sel = owner == m
            assigned[m] = (dets[sel, 0], dets[sel, 1], dets[sel, 2])
        res = CrossingResolution(
            tracks=tuple(episode.members), t_start=episode.t_open, t_end=episode.t_close,
            t_cross=episode.t_cross, method=method, n_detections=int(dets.shape[0]),
            n_assigned=int(np.sum(owner >= 0)), fallback=why if method == "nearest" else "",
        )
        logger.debug("crossing of tracks %s resolved by %s: %d of %d detections assigned",
                     res.tracks, method, res.n_assigned, res.n_detections)
        return res, assigned

    def _multitrack(self, episode: CrossingEpisode, dets: FloatArray, scan_period: float,
                    q: float) -> tuple[NDArray[np.int64] | None, str]:
        """Owner of each detection through the multi-track graph, or None and the reason."""
        ctx_t, ctx_z, ctx_m = [], [], []
        for m in episode.members:
            for t, z, _ in episode.context.get(m, []):
                ctx_t.append(t)
                ctx_z.append(z)
                ctx_m.append(m)
        if not ctx_t:
            return None, "no context"
        t = np.concatenate([np.array(ctx_t), dets[:, 0]])
        z = np.concatenate([np.array(ctx_z), dets[:, 1]])
        truth = np.concatenate([np.array(ctx_m, np.int64), np.full(dets.shape[0], -1, np.int64)])
        order = np.argsort(t, kind="stable")
        sigma = float(np.median(np.concatenate([dets[:, 2], [s for m in episode.members
                                                              for *_, s in episode.context.get(m, [])]])))
        n_scans = int(round((t.max() - t.min()) / scan_period)) + 1
        mts = MultiTrackSmoother(
            sigma_bearing=sigma, q=check_positive("q", q), clutter_density=self.clutter_density,
            p_detect=self.p_detect, window_scans=max(3, n_scans // 2), max_gap_scans=n_scans,
            fit_scans=max(2, min(30, len(ctx_t) // max(1, len(episode.members)))),
            margin_scans=5,
            # one link assignment, as measured for this resolver (the second assignment
            # across crossings, relink_gate > link_gate, was measured for fusion smooth only)
            relink_gate=30.0,
        )
        try:
            labels_sorted = mts.run(t[order], z[order]).labels
        except (ValueError, RuntimeError) as e:  # RuntimeError: GTSAM's indeterminate system
            logger.warning("multi-track graph failed on the crossing of tracks %s (%s): nearest "
                           "assignment instead", episode.members, " ".join(str(e).split())[:120])
            return None, "graph failed"
        labels = np.empty_like(labels_sorted)
        labels[order] = labels_sorted
        match: dict[int, int] = {}
        for m in episode.members:
            lab = labels[truth == m]
            lab = lab[lab >= 0]
            if lab.size == 0:
                return None, "no match"
            u, c = np.unique(lab, return_counts=True)
            i = int(np.argmax(c))
            if c[i] < self.min_share * np.sum(truth == m) or int(u[i]) in match:
                return None, "no match"
            match[int(u[i])] = m
        ep_labels = labels[truth < 0]
        owner = np.array([match.get(int(lab), -1) for lab in ep_labels], dtype=np.int64)
        if not self._consistent(episode, dets, owner):
            logger.info("multi-track association of the crossing of tracks %s contradicts their "
                        "motion: nearest assignment instead", episode.members)
            return None, "contradicts motion"
        return owner, ""

    def _consistent(self, episode: CrossingEpisode, dets: FloatArray,
                    owner: NDArray[np.int64]) -> bool:
        """Whether, past the predicted crossing, each member's detections are nearer its own
        prediction than any other member's (for at least `min_consistent` of them)."""
        pred = {m: {t: (b, s) for t, b, s in episode.predictions.get(m, [])}
                for m in episode.members}
        for m in episode.members:
            rows = [r for r in np.flatnonzero(owner == m)
                    if dets[r, 0] > episode.t_cross and float(dets[r, 0]) in pred[m]]
            if not rows:
                continue
            own_nearest = []
            for r in rows:
                t, z = float(dets[r, 0]), dets[r, 1]
                d = {k: abs(z - pred[k][t][0]) / pred[k][t][1] for k in episode.members
                     if t in pred[k]}
                own_nearest.append(min(d, key=d.get) == m)
            if np.mean(own_nearest) < self.min_consistent:
                return False
        return True

    def _nearest(self, episode: CrossingEpisode, dets: FloatArray) -> NDArray[np.int64]:
        """Per scan, gated assignment of detections to the members' predictions."""
        owner = np.full(dets.shape[0], -1, np.int64)
        pred = {m: {t: (b, s) for t, b, s in episode.predictions.get(m, [])}
                for m in episode.members}
        for t in np.unique(dets[:, 0]) if dets.shape[0] else []:
            rows = np.flatnonzero(dets[:, 0] == t)
            ms = [m for m in episode.members if float(t) in pred[m]]
            if not ms:
                continue
            cost = np.full((rows.size, len(ms)), 1e9)
            for j, m in enumerate(ms):
                b, s = pred[m][float(t)]
                d2 = ((dets[rows, 1] - b) / s) ** 2
                cost[:, j] = np.where(d2 <= self.gate**2, d2, 1e9)
            rr, cc = linear_sum_assignment(cost)
            for r, c in zip(rr, cc, strict=True):
                if cost[r, c] < 1e9:
                    owner[rows[r]] = ms[c]
        return owner

