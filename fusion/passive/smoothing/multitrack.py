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
from scipy.optimize import linear_sum_assignment

from factors.motion import transition_matrix, wna_covariance
from fusion._validation import check_positive
from fusion.geometry import wrap_angle
from fusion.passive.crossing.timing import crossing_time
from fusion.passive.smoothing.graph import (
    _check_detections,
    _check_loss,
    _initial_states,
    _Measurements,
    _Model,
    _solve,
    _solve_cov,
)
from fusion.passive.smoothing.nearest_neighbour import NearestNeighbourTracker
from fusion.passive.smoothing.types import (
    MultiTrackResult,
    SmoothedTrack,
    TrackerResult,
    TrackPrior,
)

__all__ = ["MultiTrackSmoother"]

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


class MultiTrackSmoother:
    """Joint smoothing of tracks from unlabeled per-scan bearing detections.

    Parameters
    ----------
    sigma_bearing : float, keyword-only
        Bearing measurement standard deviation, rad.
    q : float, keyword-only
        Bearing acceleration PSD, rad^2/s^3.
    clutter_density : float, keyword-only
        Expected false detections per scan per radian (the clutter component of the
        responsibilities).
    p_detect : float, keyword-only
        Probability that a track is detected in a scan.
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
    max_gap_scans : int, keyword-only
        Longest gap, in scan periods, that a segment link may bridge (default 40).
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

    Notes
    -----
    1. Initial tracks: :class:`NearestNeighbourTracker` (global nearest neighbour, Kalman).
    2. Segments: wherever two tracks come closer than `separation` and eq. (2) of "Target Track
       Crossing Prediction/Detection" puts their crossing within ``J`` scans (eq. (3)
       prediction or eq. (4) detection), both tracks are cut and the detections of those
       scans (one scan of margin) are released: their origin is uncertain. What is left are
       segments that follow one target each. Tracks with fewer than `min_length` detections
       (dropped in the end anyway) cut no other track.
    3. Segment relabelling: each segment is smoothed on its bearing-rate graph (its first and
       last `fit_scans` scans, weak prior) and gives ``gtsam.Marginals`` of its first and last
       state. A segment ending at ``t_e`` and one starting at ``t_s > t_e`` are linked with
       cost ``d^2 + ln det S``, ``d^2`` the squared Mahalanobis distance between the end state
       propagated by the constant-rate model and the start state, ``S`` its covariance
       (propagated end covariance + ``Q(t_s - t_e)`` + start covariance); links with ``d^2``
       above `link_gate` are not allowed. One assignment (``linear_sum_assignment``) over all
       ends and starts, preferring more links, chains the segments into tracks: the identity
       after a crossing is the one whose bearing and rate continue those before it.
    4. The released detections in a track's gaps, gated against the track's interpolation
       across the gap, enter every candidate track through association-weighted factors
       (:func:`factors.weighted.weighted_factor`). Per crossing cluster, EM: every track of the
       cluster gets a small graph over the cluster span plus `margin_scans` of context, with its
       own detections as hard factors and each shared detection ``j`` weighted by ``w_jm``.
       Start ``w_jm = 1/M``; M-step: weighted least squares per track; E-step:
       ``w_jm = P_D N(wrap(z_j - theta_m(t_j)); 0, sigma^2) / (lambda + sum_m' P_D N(...))``
       with ``lambda`` the clutter density; repeat until the weights settle.
    5. Final smoothing of every whole track with the settled weights; marginals from
       ``gtsam.Marginals``.

    Responsibilities use the measurement variance alone (as in probabilistic multi-hypothesis
    tracking), not the state covariance, which would need a ``Marginals`` per iteration.
    """

    def __init__(
        self,
        *,
        sigma_bearing: float,
        q: float,
        clutter_density: float = 0.1,
        p_detect: float = 0.9,
        gate: float = 4.0,
        n_confirm: int = 3,
        max_misses: int = 5,
        init_sigma_rate: float = 0.01,
        window_scans: int = 20,
        separation: float | None = None,
        link_gate: float = 30.0,
        max_gap_scans: int = 40,
        fit_scans: int = 30,
        margin_scans: int = 10,
        em_tol: float = 1e-3,
        em_max_iterations: int = 30,
        robust: str = "none",
        robust_k: float = 1.345,
        min_length: int = 5,
    ) -> None:
        self.model = _Model(
            sigma_bearing=check_positive("sigma_bearing", sigma_bearing),
            q=check_positive("q", q),
            loss=_check_loss(robust),
            k=check_positive("robust_k", robust_k),
            max_iterations=50,
        )
        self.clutter_density = check_positive("clutter_density", clutter_density)
        if not 0 < p_detect <= 1:
            raise ValueError(f"p_detect must be in (0, 1], got {p_detect!r}")
        self.p_detect = float(p_detect)
        self.tracker = NearestNeighbourTracker(
            sigma_bearing=sigma_bearing, q=q, gate=gate, init_sigma_rate=init_sigma_rate,
            n_confirm=n_confirm, max_misses=max_misses, window_scans=window_scans,
        )
        sep = 2.5 * np.sqrt(2.0) * sigma_bearing if separation is None else separation
        self.separation = check_positive("separation", sep)
        self.link_gate = check_positive("link_gate", link_gate)
        if max_gap_scans < 1 or fit_scans < 2 or margin_scans < 0:
            raise ValueError("max_gap_scans must be >= 1, fit_scans >= 2, margin_scans >= 0")
        self.max_gap_scans = int(max_gap_scans)
        self.fit_scans = int(fit_scans)
        self.margin_scans = int(margin_scans)
        self.em_tol = check_positive("em_tol", em_tol)
        self.em_max_iterations = int(em_max_iterations)
        self.min_length = int(min_length)

    def _likelihood(self, z: FloatArray, theta: FloatArray) -> FloatArray:
        s = self.model.sigma_bearing
        nu = wrap_angle(z - theta)
        return self.p_detect * np.exp(-0.5 * (nu / s) ** 2) / (np.sqrt(2 * np.pi) * s)

    def run(self, times: ArrayLike, bearings: ArrayLike, *,
            on_progress: Callable[[float], None] | None = None) -> MultiTrackResult:
        """Form, associate and smooth tracks.

        Parameters
        ----------
        times : array_like, shape (n,)
            Detection times, s, non-decreasing; equal times form a scan.
        bearings : array_like, shape (n,)
            Bearings, rad.
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
        ends = [self._segment_ends(seg, z, scan_of, scan_times) for seg in segments]
        chains = self._link(ends, scan_times)
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
        # candidates in the gaps of every track
        cand: list[list[int]] = [[] for _ in range(t.size)]
        for m, ch in enumerate(kept):
            for p, p_next in zip(ch[:-1], ch[1:], strict=True):
                for j in self._gap_candidates(ends[p], ends[p_next], scan_times, z, scan_of,
                                               labels):
                    cand[j].append(m)
        pair_det_l, pair_track_l = [], []
        for j, c in enumerate(cand):
            for m in c:
                pair_det_l.append(j)
                pair_track_l.append(m)
        pair_det = np.array(pair_det_l, np.int64)
        pair_track = np.array(pair_track_l, np.int64)
        shared_idx = np.unique(pair_det)
        weights = np.zeros(pair_det.size)
        for j in shared_idx:
            sel = pair_det == j
            weights[sel] = 1.0 / sel.sum()
        est = []
        for m in range(n_tracks):
            times_m = scan_times[first[m]: last[m] + 1]
            meas = self._track_meas(m, first[m], last[m], z, scan_of, labels, pair_det[:0],
                                    pair_track[:0])
            est.append(_initial_states(times_m, meas, None))
        cands = tuple(tuple(c) for c in cand)
        clusters = self._clusters(shared_idx, cands, scan_of)
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
            prior = self._prior(m, est)
            states, sig = _solve(times_m, meas, prior, self.model, init=est[m], weights=weights,
                                 marginals=True)
            tracks.append(SmoothedTrack(m, times_m, np.asarray(wrap_angle(states[:, 0])),
                                        states[:, 1].copy(), sig[:, 0], sig[:, 1]))
            if on_progress is not None:
                on_progress(0.5 + 0.5 * (m + 1) / n_tracks)
        # final labels: most probable owner of each shared detection, clutter if below 0.5
        out_labels = labels.copy()
        for j in shared_idx:
            sel = np.flatnonzero(pair_det == j)
            best = sel[np.argmax(weights[sel])]
            out_labels[j] = pair_track[best] if weights[best] >= 0.5 else -1
        shared = np.zeros(t.size, bool)
        shared[shared_idx] = True
        logger.info("%d segments linked into %d tracks; %d shared detections in %d crossing "
                    "clusters", len(segments), n_tracks, shared_idx.size, len(clusters))
        return MultiTrackResult(tuple(tracks), out_labels, shared, max_iter)

    # -- segments ---------------------------------------------------------------------------

    def _segments(self, tr: TrackerResult, z: FloatArray,
                  scan_of: NDArray[np.int64]) -> list[NDArray[np.int64]]:
        """Cut the tracker's tracks where two of them are ambiguous; detections per segment."""
        n_scans = tr.scan_times.size
        period = float(np.median(np.diff(tr.scan_times))) if n_scans > 1 else 1.0
        ambiguous = np.zeros((tr.n_tracks, n_scans), bool)
        # a track too short to be kept does not cut others
        counts = np.bincount(tr.labels[tr.labels >= 0], minlength=tr.n_tracks)
        for a in range(tr.n_tracks):
            if counts[a] < self.min_length:
                continue
            for b in range(a + 1, tr.n_tracks):
                if counts[b] < self.min_length:
                    continue
                lo = max(tr.first_scan[a], tr.first_scan[b])
                hi = min(tr.last_scan[a], tr.last_scan[b])
                if hi < lo:
                    continue
                xa = tr.states[a][lo - tr.first_scan[a]: hi - tr.first_scan[a] + 1]
                xb = tr.states[b][lo - tr.first_scan[b]: hi - tr.first_scan[b] + 1]
                sep = np.abs(wrap_angle(xa[:, 0] - xb[:, 0]))
                tc = np.asarray(crossing_time(xa[:, 0], xa[:, 1], xb[:, 0], xb[:, 1]))
                # eq. (3) predicted or eq. (4) detected crossing, and close in bearing
                amb = (sep < self.separation) & (np.abs(tc) <= self._window_s(period))
                if amb.any():
                    k = np.flatnonzero(amb) + lo
                    for d in (-1, 0, 1):  # one scan of margin
                        kk = np.clip(k + d, 0, n_scans - 1)
                        ambiguous[a, kk] = True
                        ambiguous[b, kk] = True
        segments: list[NDArray[np.int64]] = []
        for m in range(tr.n_tracks):
            own = np.flatnonzero(tr.labels == m)
            own = own[np.argsort(scan_of[own], kind="stable")]
            keep = own[~ambiguous[m, scan_of[own]]]
            if keep.size == 0:
                continue
            amb_scans = np.flatnonzero(ambiguous[m])
            # a new segment starts after every ambiguous scan between two kept detections
            cut = np.searchsorted(amb_scans, scan_of[keep])
            for c in np.unique(cut):
                seg = keep[cut == c]
                if seg.size >= self.tracker.n_confirm:
                    segments.append(seg)
        return segments

    def _window_s(self, period: float) -> float:
        """``J K`` of eq. (3)-(4), s."""
        return self.tracker.window_scans * period

    def _segment_ends(self, seg: NDArray[np.int64], z: FloatArray, scan_of: NDArray[np.int64],
                      scan_times: FloatArray) -> tuple:
        """First and last scan of a segment with their states and marginal covariances."""
        s0, s1 = int(scan_of[seg[0]]), int(scan_of[seg[-1]])
        out = []
        w = self.fit_scans
        spans = [(s0, s1)] if s1 - s0 < 2 * w else [(s0, s0 + w - 1), (s1 - w + 1, s1)]
        for a, b in spans:
            sel = seg[(scan_of[seg] >= a) & (scan_of[seg] <= b)]
            times_ab = scan_times[a: b + 1]
            meas = _Measurements(state=(scan_of[sel] - a).astype(np.int64), bearing=z[sel])
            x0 = _initial_states(times_ab, meas, None)
            prior = TrackPrior(bearing=float(x0[0, 0]), rate=float(x0[0, 1]),
                               sigma_bearing=10.0 * self.model.sigma_bearing,
                               sigma_rate=self.tracker.init_sigma_rate)
            try:
                states, covs = _solve_cov(times_ab, meas, prior, self.model, x0,
                                          (0, b - a))
            except RuntimeError as err:  # gtsam: too few bearings for the scans spanned
                # The segment's end keeps its initial line with weak covariances; said, not hidden.
                logger.warning("segment of scans %d-%d: fit failed (%s); its end states keep the "
                               "initial line with weak covariances", a, b, err)
                weak = np.diag([self.model.sigma_bearing**2, self.tracker.init_sigma_rate**2])
                states, covs = x0, [weak, weak]
            out.append((states, covs))
        (st_a, cov_a), (st_b, cov_b) = out[0], out[-1]
        return (s0, st_a[0], cov_a[0], s1, st_b[-1], cov_b[-1])

    def _link(self, ends: list[tuple], scan_times: FloatArray) -> list[list[int]]:
        """Chain segments by one assignment of segment ends to later segment starts."""
        n = len(ends)
        if n == 0:
            return []
        period = float(np.median(np.diff(scan_times))) if scan_times.size > 1 else 1.0
        big = 1e9
        cost = np.full((n, n), np.inf)
        for e in range(n):
            _, _, _, s1, x_e, p_e = ends[e]
            for s in range(n):
                s0, x_s, p_s = ends[s][0], ends[s][1], ends[s][2]
                dt = float(scan_times[s0] - scan_times[s1]) if s0 > s1 else -1.0
                if s == e or dt <= 0 or dt > self.max_gap_scans * period:
                    continue
                f = transition_matrix(dt, 1)
                cov = f @ p_e @ f.T + wna_covariance(dt, self.model.q, 1) + p_s
                nu = x_s - f @ x_e
                nu[0] = wrap_angle(nu[0])
                d2 = float(nu @ np.linalg.solve(cov, nu))
                if d2 <= self.link_gate:
                    cost[e, s] = d2 + float(np.log(np.linalg.det(cov)))
        finite = np.isfinite(cost)
        if not finite.any():
            return [[p] for p in range(n)]
        # admissible links cost less than any pair of non-links: the most links, then the
        # cheapest
        shift = cost[finite].min()
        c = np.where(finite, cost - shift, big)
        rr, cc = linear_sum_assignment(c)
        nxt = {int(r): int(s) for r, s in zip(rr, cc, strict=True) if finite[r, s]}
        has_prev = set(nxt.values())
        chains = []
        for p in range(n):
            if p in has_prev:
                continue
            ch = [p]
            while ch[-1] in nxt:
                ch.append(nxt[ch[-1]])
            chains.append(ch)
        return chains

    def _gap_candidates(self, end: tuple, start: tuple, scan_times: FloatArray, z: FloatArray,
                        scan_of: NDArray[np.int64], labels: NDArray[np.int64]) -> list[int]:
        """Unassigned detections in the gap between two linked segments, gated against the
        track's interpolation across the gap (forward and backward predictions fused)."""
        s1, x_e, p_e = end[3], end[4], end[5]
        s0, x_s, p_s = start[0], start[1], start[2]
        sel = np.flatnonzero((scan_of > s1) & (scan_of < s0) & (labels < 0))
        out = []
        for j in sel:
            dt_f = float(scan_times[scan_of[j]] - scan_times[s1])
            dt_b = float(scan_times[s0] - scan_times[scan_of[j]])
            f_f, f_b = transition_matrix(dt_f, 1), transition_matrix(dt_b, 1)
            # forward prediction from the end, backward prediction from the start
            m_f = f_f @ x_e
            v_f = (f_f @ p_e @ f_f.T + wna_covariance(dt_f, self.model.q, 1))[0, 0]
            m_b = np.linalg.solve(f_b, x_s)
            fi = np.linalg.inv(f_b)
            v_b = (fi @ (p_s + wna_covariance(dt_b, self.model.q, 1)) @ fi.T)[0, 0]
            theta = m_f[0] + wrap_angle(m_b[0] - m_f[0]) * v_f / (v_f + v_b)
            var = v_f * v_b / (v_f + v_b) + self.model.sigma_bearing**2
            if abs(wrap_angle(z[j] - theta)) < self.tracker.gate * np.sqrt(var):
                out.append(int(j))
        return out

    def _prior(self, m: int, est: list[FloatArray]) -> TrackPrior:
        x0 = est[m][0]
        return TrackPrior(bearing=float(x0[0]), rate=float(x0[1]),
                          sigma_bearing=10.0 * self.model.sigma_bearing,
                          sigma_rate=self.tracker.init_sigma_rate)

    def _clusters(self, shared_idx: NDArray[np.int64], cands: tuple[tuple[int, ...], ...],
                  scan_of: NDArray[np.int64]) -> list[NDArray[np.int64]]:
        """Group shared detections: same candidate track and < margin scans apart."""
        if shared_idx.size == 0:
            return []
        parent = np.arange(shared_idx.size)

        def find(a: int) -> int:
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a

        last_seen: dict[int, int] = {}
        for pos, j in enumerate(shared_idx):
            for m in cands[j]:
                if m in last_seen and scan_of[j] - scan_of[shared_idx[last_seen[m]]] <= (
                    self.margin_scans
                ):
                    parent[find(pos)] = find(last_seen[m])
                last_seen[m] = pos
        roots = np.array([find(p) for p in range(shared_idx.size)])
        return [shared_idx[roots == r] for r in np.unique(roots)]

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
        """EM over one crossing cluster; updates `weights` and `est` in place."""
        sel = np.flatnonzero(np.isin(pair_det, cl))
        members = np.unique(pair_track[sel])
        lo = int(scan_of[cl].min()) - self.margin_scans
        hi = int(scan_of[cl].max()) + self.margin_scans
        spans = {m: (max(lo, int(first[m])), min(hi, int(last[m]))) for m in members}
        metas = {m: self._track_meas(m, *spans[m], z, scan_of, labels, pair_det, pair_track)
                 for m in members}
        it = 0
        for it in range(1, self.em_max_iterations + 1):  # noqa: B007
            theta = np.zeros(sel.size)
            for m in members:  # M-step: weighted least squares per track
                s0, s1 = spans[m]
                times_m = scan_times[s0: s1 + 1]
                init = est[m][s0 - first[m]: s1 - first[m] + 1]
                prior = TrackPrior(bearing=float(init[0, 0]), rate=float(init[0, 1]),
                                   sigma_bearing=10.0 * self.model.sigma_bearing,
                                   sigma_rate=self.tracker.init_sigma_rate)
                states, _ = _solve(times_m, metas[m], prior, self.model, init=init,
                                   weights=weights)
                est[m][s0 - first[m]: s1 - first[m] + 1] = states
                on_m = pair_track[sel] == m
                dets = pair_det[sel][on_m]
                theta[on_m] = states[scan_of[dets] - s0, 0]
            # E-step: responsibilities against the tracks' predicted bearings + clutter
            lik = self._likelihood(z[pair_det[sel]], theta)
            denom = np.full(t.size, self.clutter_density)
            np.add.at(denom, pair_det[sel], lik)
            new = lik / denom[pair_det[sel]]
            change = float(np.max(np.abs(new - weights[sel]))) if sel.size else 0.0
            weights[sel] = new
            if change < self.em_tol:
                break
        return it
