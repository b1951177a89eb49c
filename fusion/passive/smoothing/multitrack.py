"""Tracks from unlabeled bearing detections, smoothed jointly through crossings.

:class:`MultiTrackSmoother`: initial tracks from the nearest-neighbour tracker, cut where two of
them come close with a crossing predicted or detected (equation (2)-(4) of "Target Track Crossing
Prediction/Detection"), segments relinked by one assignment, then expectation-maximisation around
every crossing: shared detections enter each candidate track through association-weighted
factors whose weights are the detections' responsibilities, re-estimated until they settle;
graphs stay small (one per track and crossing cluster).
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._validation import check_positive
from fusion.geometry import wrap_angle
from fusion.passive.smoothing.association import (
    clutter_and_detection,
    joint_weights,
    nearest_weights,
)
from fusion.passive.smoothing.candidates import track_candidates
from fusion.passive.smoothing.em import SharedBearingPosterior
from fusion.passive.smoothing.graph import (
    _check_detections,
    _initial_states,
    _Measurements,
    _Model,
    _solve,
)
from fusion.passive.smoothing.linking import crossing_clusters, link_segments
from fusion.passive.smoothing.linkpath import short_segment_path_test, tracker_p_detect
from fusion.passive.smoothing.nearest_neighbour import NearestNeighbourTracker
from fusion.passive.smoothing.rescue import link_short_chains
from fusion.passive.smoothing.segments import across_crossings, cut_segments, segment_end_states
from fusion.passive.smoothing.types import (
    MultiTrackResult,
    SmoothedTrack,
    TrackerResult,
    TrackPrior,
)

__all__ = ["ASSOCIATIONS", "END_DETECTIONS", "MultiTrackSmoother"]

#: Association of the shared detections: ``weighted`` (posterior association probabilities
#: as the weights of the bearing factors) or ``nearest`` (per scan a gated nearest assignment,
#: weights 0 or 1: the measured baseline).
ASSOCIATIONS = ("weighted", "nearest")

#: Detections a track's ends may be extended over: ``own`` those the initial tracker gave the
#: tracker track its end segment came from (or left shared with it), ``tracked`` any the
#: tracker took.
END_DETECTIONS = ("own", "tracked")

#: Largest number of shared detections of one scan whose joint events are enumerated; a busier
#: scan gets per-detection responsibilities (counted in ``MultiTrackResult.fallbacks``).
MAX_JOINT = 7

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


class MultiTrackSmoother:
    """Joint smoothing of tracks from unlabeled per-scan bearing detections.

    Parameters
    ----------
    sigma_bearing, q : float, keyword-only
        As in :class:`~fusion.passive.smoothing.batch.BearingSmoother`.
    clutter_density : float or None, keyword-only
        Expected false detections per scan per radian (the clutter term of the association
        probabilities); None: counted from the detections no track owns
        (:func:`~fusion.passive.smoothing.association.clutter_and_detection`).
    p_detect : float or None, keyword-only
        Probability that a track is detected in a scan (the missed-detection term); None:
        counted from the tracks' detections per scan.
    association : {"weighted", "nearest"}, keyword-only
        ``weighted``: the shared detections' factors are weighted by their posterior
        association probabilities (joint events per scan, :func:`~fusion.passive.smoothing.
        association.joint_weights`); ``nearest``: by 0/1 from a gated nearest assignment per
        scan (the baseline the weights are measured against).
    gate, n_confirm, max_misses, init_sigma_rate, window_scans :
        Options of the initial :class:`NearestNeighbourTracker` (global nearest neighbour);
        `window_scans` is also ``J`` of the crossing test, eq. (3)-(4).
    separation : float, keyword-only
        Two tracks closer than this in bearing, with a predicted or detected crossing, are
        ambiguous, rad (default ``2.5 * sqrt(2) * sigma_bearing``).
    link_gate : float, keyword-only
        Gate on the squared Mahalanobis distance (2 degrees of freedom) of a segment link
        (default 30; the 99.9 % point of chi-square is 13.8, but the constant-rate model
        underrates the curvature of bearing tracks near closest approach).
    relink_gate : float, keyword-only
        Wider gate of a second link assignment among the segment ends and starts the first
        left unlinked, where the gap holds an ambiguous scan of either (default 100; not above
        `link_gate`: no second assignment). A fragment
        whose rate changed too much for `link_gate` through a dense crossing zone joins the
        one track end left free for it instead of starting a new track (Notes, 3).
    max_gap_scans : int, keyword-only
        Longest gap, in scan periods, that a segment link may bridge (default 40).
    crossing_gap_scans, link_curvature : keyword-only
        Of :func:`~fusion.passive.smoothing.linking.link_segments`: longest gap of a link
        across a crossing (default None: `max_gap_scans`), links with the segments' bearing
        accelerations (default False); ``fusion smooth``: 60 and True.
    fit_scans : int, keyword-only
        Scans at each end of a segment used for its end states (default 30).
    margin_scans : int, keyword-only
        Scans of context on each side of a crossing cluster in its EM graphs.
    em_tol : float, keyword-only
        EM stops when no responsibility changes by more than this.
    em_max_iterations : int, keyword-only
        EM iteration cap per cluster.
    robust : {"none", "huber", "cauchy"}, keyword-only
        Loss on the hard (single-owner) bearing factors of the final smoothing.
    min_length : int, keyword-only
        Tracks with fewer detections are dropped (default 5).
    extend_ends : bool, keyword-only
        Extend each track over the unassigned detections before its first and after its last
        segment (default False: on real camera bearings it added false crossing alerts; see Notes, 4).
    end_detections : {"own", "tracked"}, keyword-only
        Detections an end may be extended over: ``own`` (default) those the initial tracker
        gave the tracker track the end segment came from, or left shared with it; ``tracked``
        any the tracker took (:data:`END_DETECTIONS`).
    extend_starts : bool, keyword-only
        Extend each track over those detections before its first segment only (default False).
    short_link_q : float, keyword-only
        Acceleration PSD of the links of chains shorter than `min_length` to later track
        starts, rad^2/s^3 (:mod:`~fusion.passive.smoothing.rescue`; default 0, <= q: none).
    link_path_alpha : float, keyword-only
        A link from or to a segment with fewer than `min_length` detections is refused when
        the scans of its gap with no detection near its path have binomial tail probability
        below this under the detection probability
        (:mod:`~fusion.passive.smoothing.linkpath`; default 0: no test; ``fusion smooth``:
        1e-8).

    Notes
    -----
    1. Initial tracks: :class:`NearestNeighbourTracker` (global nearest neighbour, Kalman).
    2. Segments: wherever two tracks come closer than `separation` and eq. (2) of "Target Track
       Crossing Prediction/Detection" puts their crossing within ``J`` scans (eq. (3)
       prediction or eq. (4) detection), both tracks are cut and the detections of those
       scans (one scan of margin) are released: their origin is uncertain. What is left are
       segments that follow one target each. Tracks with fewer than `min_length` detections
       (dropped in the end anyway) cut no other track.
    3. Segment relabelling: each segment's first and last `fit_scans` scans are smoothed on
       their graph (weak prior) for the end states and covariances. A segment ending at
       ``t_e`` and one starting at ``t_s > t_e`` are linked with cost ``d^2 + ln det S``,
       ``d^2`` the squared Mahalanobis distance between the propagated end state and the start
       state, ``S`` its covariance; links with ``d^2`` above `link_gate` are not allowed. One
       assignment over all ends and starts, preferring more links, chains the segments into
       tracks: the identity after a crossing is the one whose bearing and rate continue it.
       The ends and starts left unlinked get a second assignment among themselves with the
       wider `relink_gate`, only across a crossing (an ambiguous scan of either tracker track
       in the gap); the first assignment's links are kept.
    4. The released detections in a track's gaps, gated against its interpolation across the
       gap (:mod:`~fusion.passive.smoothing.candidates`; with `extend_ends` also those before
       its first and after its last segment, where it starts or ends beside another track),
       enter every candidate track through association-weighted factors. Per crossing
       cluster, EM: every track of the cluster gets a graph over the cluster span plus
       `margin_scans`, its own detections hard and each shared detection ``j`` weighted by
       ``w_jm``. Start ``w_jm = 1/M``; M-step: weighted least squares per track (Gaussian loss:
       in closed form, :mod:`~fusion.passive.smoothing.em`); E-step: ``w_jm`` the posterior
       probability that ``j`` came from track ``m`` at the tracks' current bearings, summed
       over the scan's joint events (each track at most one detection, missed with
       ``1 - P_D``, each detection from one track or clutter of density ``lambda``) and
       computed with the measurement variance alone (as in probabilistic multi-hypothesis
       tracking); repeat until the weights settle. With ``association="nearest"`` the E-step
       is a gated nearest assignment per scan (weights 0 or 1).
    5. Final smoothing of every whole track with the settled weights, with its marginals.
    """

    def __init__(
        self,
        *,
        sigma_bearing: float,
        q: float,
        clutter_density: float | None = 0.1,
        p_detect: float | None = 0.9,
        association: str = "weighted",
        gate: float = 4.0,
        n_confirm: int = 3,
        max_misses: int = 5,
        init_sigma_rate: float = 0.01,
        window_scans: int = 20,
        separation: float | None = None,
        link_gate: float = 30.0,
        relink_gate: float = 100.0,
        max_gap_scans: int = 40,
        crossing_gap_scans: int | None = None,
        link_curvature: bool = False,
        fit_scans: int = 30,
        margin_scans: int = 10,
        em_tol: float = 1e-3,
        em_max_iterations: int = 30,
        robust: str = "none",
        robust_k: float = 1.345,
        min_length: int = 5,
        extend_ends: bool = False,
        end_detections: str = "own",
        extend_starts: bool = False,
        short_link_q: float = 0.0,
        link_path_alpha: float = 0.0,
    ) -> None:
        self.model = _Model.checked(sigma_bearing=sigma_bearing, q=q, robust=robust,
                                    robust_k=robust_k, max_iterations=50)
        self.clutter_density = (None if clutter_density is None
                                else check_positive("clutter_density", clutter_density))
        if p_detect is not None and not 0 < p_detect <= 1:
            raise ValueError(f"p_detect must be in (0, 1], got {p_detect!r}")
        self.p_detect = None if p_detect is None else float(p_detect)
        if association not in ASSOCIATIONS:
            raise ValueError(f"association must be one of {', '.join(ASSOCIATIONS)}, got "
                             f"{association!r}")
        self.association = association
        #: Clutter density and detection probability the last run associated with (given or
        #: counted from the data), per scan per radian and per scan.
        self.used_clutter_density: float | None = None
        self.used_p_detect: float | None = None
        self.tracker = NearestNeighbourTracker(
            sigma_bearing=sigma_bearing, q=q, gate=gate, init_sigma_rate=init_sigma_rate,
            n_confirm=n_confirm, max_misses=max_misses, window_scans=window_scans,
        )
        sep = 2.5 * np.sqrt(2.0) * sigma_bearing if separation is None else separation
        self.separation = check_positive("separation", sep)
        self.link_gate = check_positive("link_gate", link_gate)
        self.relink_gate = check_positive("relink_gate", relink_gate)
        if max_gap_scans < 1 or fit_scans < 2 or margin_scans < 0:
            raise ValueError("max_gap_scans must be >= 1, fit_scans >= 2, margin_scans >= 0")
        self.max_gap_scans = int(max_gap_scans)
        self.crossing_gap_scans, self.link_curvature = crossing_gap_scans, bool(link_curvature)
        self.fit_scans = int(fit_scans)
        self.margin_scans = int(margin_scans)
        self.em_tol = check_positive("em_tol", em_tol)
        self.em_max_iterations = int(em_max_iterations)
        self.min_length = int(min_length)
        self.extend_ends, self.extend_starts = bool(extend_ends), bool(extend_starts)
        self.short_link_q = check_positive("short_link_q", short_link_q, allow_zero=True)
        if not 0.0 <= link_path_alpha < 1.0:
            raise ValueError(f"link_path_alpha must be in [0, 1), got {link_path_alpha!r}")
        self.link_path_alpha = float(link_path_alpha)
        if end_detections not in END_DETECTIONS:
            raise ValueError(f"end_detections must be one of {', '.join(END_DETECTIONS)}, got "
                             f"{end_detections!r}")
        self.end_detections = end_detections

    def _density(self, z: FloatArray, theta: FloatArray) -> FloatArray:
        """Measurement density ``N(wrap(z - theta); 0, sigma^2)``, 1/rad."""
        s = self.model.sigma_bearing
        nu = wrap_angle(z - theta)
        return np.exp(-0.5 * (nu / s) ** 2) / (np.sqrt(2 * np.pi) * s)

    def run(self, times: ArrayLike, bearings: ArrayLike, *,
            on_progress: Callable[[float], None] | None = None) -> MultiTrackResult:
        """Form, associate and smooth tracks.

        Parameters
        ----------
        times, bearings : array_like, shape (n,)
            Unlabeled detections (:mod:`fusion.passive.smoothing`), times non-decreasing.
        on_progress : callable, optional, keyword-only
            ``on_progress(f)`` as the work goes on, with the fraction done: the tracker's pass
            over the scans is the first half (after each scan), the tracks' smoothing the
            second (after each track).

        Returns
        -------
        MultiTrackResult
        """
        t, z = _check_detections(times, bearings)
        tr = self.tracker.run(t, z, on_scan=None if on_progress is None
                              else (lambda f: on_progress(0.5 * f)))
        scan_times = tr.scan_times
        scan_of = np.searchsorted(scan_times, t)
        segments = self._segments(tr, z, scan_of)
        # what a track's ends may be extended over: detections the tracker took (``tracked``)
        # or those of its end segment's tracker track and those left shared with it (``own``)
        tracked = (tr.labels >= 0) | np.array([len(c) > 0 for c in tr.candidates], bool)
        self._failed_fits: list[tuple[int, int, str]] = []
        self._n_fits = 0
        ends = [self._segment_ends(seg, z, scan_of, scan_times) for seg in segments]
        if self._failed_fits:  # a changed result is said at the default level, with a count
            spans = ", ".join(f"{a}-{b}" for a, b, _ in self._failed_fits[:5])
            logger.warning("segment-end fit failed (%s) on %d of %d fits (scans %s%s); those ends "
                           "keep their initial line with weak covariances",
                           self._failed_fits[0][2], len(self._failed_fits), self._n_fits, spans,
                           ", ..." if len(self._failed_fits) > 5 else "")
        across = across_crossings(self._ambiguous, tr, segments, ends)
        sizes = np.array([s.size for s in segments], np.int64)
        chains = link_segments(
            ends, scan_times, q=self.model.q, link_gate=self.link_gate, relink_allowed=across,
            max_gap_scans=self.max_gap_scans, relink_gate=self.relink_gate,
            crossing_gap_scans=self.crossing_gap_scans, curvature=self.link_curvature,
            implausible=self._path_test(ends, scan_times, scan_of, z, tr, sizes))
        chains = link_short_chains(  # short chains before a crossing: no late start
            chains, sizes, ends, scan_times,
            q=self.model.q, min_length=self.min_length, gate=self.link_gate,
            q_link=self.short_link_q, max_gap_scans=self.max_gap_scans)
        # hard labels per track, drop short tracks
        labels = np.full(t.size, -1, np.int64)
        kept: list[list[int]] = []
        for ch in chains:
            if sum(segments[p].size for p in ch) >= self.min_length:
                for p in ch:
                    labels[segments[p]] = len(kept)
                kept.append(ch)
        n_tracks = len(kept)
        first = np.array([scan_of[segments[ch[0]][0]] for ch in kept], np.int64)
        last = np.array([scan_of[segments[ch[-1]][-1]] for ch in kept], np.int64)
        # candidates in the gaps of every track (and beyond its ends: extend_starts/_ends)
        cand = track_candidates(
            kept, ends, scan_times, z, scan_of, labels, first, last, q=self.model.q,
            sigma_bearing=self.model.sigma_bearing, gate=self.tracker.gate,
            starts=self.extend_ends or self.extend_starts, finishes=self.extend_ends,
            max_misses=self.tracker.max_misses, max_scans=self.max_gap_scans,
            eligible=lambda p: self._eligible(tr, segments[p], tracked))
        pairs_l = [(j, m) for j, c in enumerate(cand) for m in c]
        pair_det = np.array([j for j, _ in pairs_l], np.int64)
        pair_track = np.array([m for _, m in pairs_l], np.int64)
        shared_idx = np.unique(pair_det)
        released = np.zeros(t.size, bool)
        released[shared_idx] = True
        lam_hat, pd_hat = clutter_and_detection(labels, scan_of, first, last, released, z)
        lam = lam_hat if self.clutter_density is None else self.clutter_density
        p_d = pd_hat if self.p_detect is None else self.p_detect
        self.used_clutter_density, self.used_p_detect = lam, p_d
        self._n_approx = 0
        weights = 1.0 / np.bincount(pair_det, minlength=t.size)[pair_det]  # 1/M each
        est = []
        for m in range(n_tracks):
            times_m = scan_times[first[m]: last[m] + 1]
            meas = self._track_meas(m, first[m], last[m], z, scan_of, labels, pair_det[:0],
                                    pair_track[:0])
            est.append(_initial_states(times_m, meas, None))
        cands = tuple(tuple(c) for c in cand)
        clusters = crossing_clusters(shared_idx, cands, scan_of, self.margin_scans)
        max_iter = 0
        for cl in clusters:
            max_iter = max(max_iter, self._em_cluster(
                cl, t, z, scan_times, scan_of, labels, first, last, est, weights,
                pair_det, pair_track))
        tracks = []
        for m in range(n_tracks):
            times_m = scan_times[first[m]: last[m] + 1]
            meas = self._track_meas(m, first[m], last[m], z, scan_of, labels, pair_det,
                                    pair_track)
            prior = self._span_prior(est[m])
            states, sig = _solve(times_m, meas, prior, self.model, init=est[m], weights=weights,
                                 marginals=True)
            tracks.append(SmoothedTrack(m, times_m, np.asarray(wrap_angle(states[:, 0])),
                                        states[:, 1].copy(), sig[:, 0], sig[:, 1]))
            if on_progress is not None:
                on_progress(0.5 + 0.5 * (m + 1) / n_tracks)
        # final labels: the most probable origin of each shared detection (a track, or clutter
        # with probability 1 - sum of its weights)
        out_labels = labels.copy()
        for j in shared_idx:
            sel = np.flatnonzero(pair_det == j)
            best = sel[np.argmax(weights[sel])]
            out_labels[j] = pair_track[best] if weights[best] >= 1.0 - weights[sel].sum() else -1
        shared = np.zeros(t.size, bool)
        shared[shared_idx] = True
        logger.info("%d segments linked into %d tracks; %d shared detections in %d crossing "
                    "clusters; %s association, clutter %.3g /scan/rad, P_D %.3g%s",
                    len(segments), n_tracks, shared_idx.size, len(clusters), self.association,
                    lam, p_d, "" if self._n_approx == 0 else
                    f"; {self._n_approx} busy scans with per-detection responsibilities")
        return MultiTrackResult(tuple(tracks), out_labels, shared, max_iter,
                                pairs=(pair_det, pair_track, weights.copy()),
                                association=self.association, clutter_density=lam,
                                p_detect=p_d, approximate_scans=self._n_approx)

    # -- segments ---------------------------------------------------------------------------

    def _segments(self, tr: TrackerResult, z: FloatArray,
                  scan_of: NDArray[np.int64]) -> list[NDArray[np.int64]]:
        """Cut the tracker's tracks where two of them are ambiguous (Notes, 2); the
        ambiguous scans are kept for the second link assignment."""
        period = float(np.median(np.diff(tr.scan_times))) if tr.scan_times.size > 1 else 1.0
        segments, self._ambiguous = cut_segments(
            tr, scan_of, separation=self.separation, min_length=self.min_length,
            window_s=self._window_s(period), n_confirm=self.tracker.n_confirm)
        return segments

    def _path_test(self, ends, scan_times, scan_of, z, tr: TrackerResult, sizes):
        """:func:`~fusion.passive.smoothing.linkpath.short_segment_path_test` (None: off)."""
        return None if self.link_path_alpha <= 0.0 else short_segment_path_test(
            ends, sizes, self.min_length, scan_times, scan_of, z, q=self.model.q,
            sigma=self.model.sigma_bearing, alpha=self.link_path_alpha,
            p_detect=tracker_p_detect(tr) if self.p_detect is None else self.p_detect)

    def _eligible(self, tr: TrackerResult, seg: NDArray[np.int64],
                  tracked: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Detections an end of segment `seg` may be extended over (``end_detections``)."""
        if self.end_detections == "tracked":
            return tracked
        k = int(tr.labels[seg[0]])  # the tracker track the segment came from
        return (tr.labels == k) | np.array([k in c for c in tr.candidates], bool)

    def _window_s(self, period: float) -> float:
        """``J K`` of eq. (3)-(4), s."""
        return self.tracker.window_scans * period

    def _segment_ends(self, seg: NDArray[np.int64], z: FloatArray, scan_of: NDArray[np.int64],
                      scan_times: FloatArray) -> tuple:
        """:func:`~fusion.passive.smoothing.segments.segment_end_states` with this smoother's
        model; failed fits are counted in ``self._failed_fits`` (said once per run)."""
        self._n_fits += 1 if scan_of[seg[-1]] - scan_of[seg[0]] < 2 * self.fit_scans else 2
        return segment_end_states(seg, z, scan_of, scan_times, fit_scans=self.fit_scans,
                                  model=self.model, init_sigma_rate=self.tracker.init_sigma_rate,
                                  failed=self._failed_fits)

    def _track_meas(self, m: int, s0: int, s1: int, z: FloatArray, scan_of: NDArray[np.int64],
                    labels: NDArray[np.int64], pair_det: NDArray[np.int64],
                    pair_track: NDArray[np.int64]) -> _Measurements:
        """Track m's bearings on scans s0..s1: own (hard) and shared (weighted)."""
        own = np.flatnonzero((labels == m) & (scan_of >= s0) & (scan_of <= s1))
        pw = np.flatnonzero((pair_track == m) & (scan_of[pair_det] >= s0)
                            & (scan_of[pair_det] <= s1))
        dets = np.r_[own, pair_det[pw]]
        return _Measurements(
            state=(scan_of[dets] - s0).astype(np.int64),
            bearing=z[dets],
            weight_index=np.r_[np.full(own.size, -1, np.int64), pw].astype(np.int64),
        )

    def _em_cluster(self, cl, t, z, scan_times, scan_of, labels, first, last, est, weights,
                    pair_det, pair_track) -> int:
        """EM over one crossing cluster; updates `weights` and `est` in place.

        With the Gaussian loss each member's M-step is the closed form of
        :class:`~fusion.passive.smoothing.em.SharedBearingPosterior` (its graph solved once
        without the cluster's shared bearings, then conditioned on them with the current
        weights); with a robust loss every M-step solves each member's graph again.
        """
        sel = np.flatnonzero(np.isin(pair_det, cl))
        members = np.unique(pair_track[sel])
        lo = int(scan_of[cl].min()) - self.margin_scans
        hi = int(scan_of[cl].max()) + self.margin_scans
        spans = {m: (max(lo, int(first[m])), min(hi, int(last[m]))) for m in members}
        metas = {m: self._track_meas(m, *spans[m], z, scan_of, labels, pair_det, pair_track)
                 for m in members}
        on = {m: pair_track[sel] == m for m in members}
        closed = self.model.loss == "none"
        post = {}
        for m in members:
            s0, s1 = spans[m]
            init = est[m][s0 - first[m]: s1 - first[m] + 1]
            if closed:
                dets = pair_det[sel][on[m]]
                post[m] = SharedBearingPosterior(
                    scan_times[s0: s1 + 1], metas[m], self._span_prior(init), self.model, init,
                    weights, sel[on[m]], scan_of[dets] - s0, z[dets])
        it = 0
        for it in range(1, self.em_max_iterations + 1):  # noqa: B007
            theta = np.zeros(sel.size)
            for m in members:  # M-step: weighted least squares per track
                if closed:
                    theta[on[m]] = post[m].bearings(weights[sel][on[m]])
                    continue
                s0, s1 = spans[m]
                init = est[m][s0 - first[m]: s1 - first[m] + 1]
                states, _ = _solve(scan_times[s0: s1 + 1], metas[m], self._span_prior(init),
                                   self.model, init=init, weights=weights)
                est[m][s0 - first[m]: s1 - first[m] + 1] = states
                theta[on[m]] = states[scan_of[pair_det[sel][on[m]]] - s0, 0]
            # E-step: association probabilities at the tracks' current bearings
            dj, mj = pair_det[sel], pair_track[sel]
            if self.association == "weighted":
                new, n_approx = joint_weights(scan_of[dj], dj, mj, self._density(z[dj], theta),
                                              p_detect=self.used_p_detect,
                                              clutter_density=self.used_clutter_density,
                                              max_joint=MAX_JOINT)
                if it == 1:
                    self._n_approx += n_approx
            else:
                d2 = (wrap_angle(z[dj] - theta) / self.model.sigma_bearing) ** 2
                new = nearest_weights(scan_of[dj], dj, mj, d2, gate=self.tracker.gate)
            change = float(np.max(np.abs(new - weights[sel]))) if sel.size else 0.0
            weights[sel] = new
            if change < self.em_tol:
                break
        if closed:  # the members' whole spans at the settled weights
            for m in members:
                s0, s1 = spans[m]
                est[m][s0 - first[m]: s1 - first[m] + 1] = post[m].states_at(weights[sel][on[m]])
        return it

    def _span_prior(self, init: FloatArray) -> TrackPrior:
        """The weak prior on the first state of a member's span, centred on `init[0]`, its
        bearing wrapped (the graph takes the first state's branch; a clutter track's line
        may wind past 2 pi: seed 9208 with ``short_link_q`` 3e-3 deg^2/s^3)."""
        return TrackPrior(bearing=float(wrap_angle(init[0, 0])), rate=float(init[0, 1]),
                          sigma_bearing=10.0 * self.model.sigma_bearing,
                          sigma_rate=self.tracker.init_sigma_rate)

