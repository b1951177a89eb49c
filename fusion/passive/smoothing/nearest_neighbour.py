"""A Kalman bearing tracker with global nearest-neighbour assignment, optionally crossing-aware.

Alone it is the baseline tracker of unlabeled bearing detections; with ``crossing_aware=True``
it predicts crossings with equation (2) of "Target Track Crossing Prediction/Detection"
(:func:`fusion.passive.crossing.timing.crossing_time`) and lets both tracks coast through them,
leaving the ambiguous detections shared. :class:`fusion.passive.smoothing.multitrack.
MultiTrackSmoother` starts from its tracks.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment

from factors.motion import transition_matrix, wna_covariance
from fusion._validation import check_positive
from fusion.geometry import wrap_angle
from fusion.passive.crossing.timing import crossing_time
from fusion.passive.smoothing.graph import _check_detections
from fusion.passive.smoothing.types import TrackerResult

__all__ = ["NearestNeighbourTracker"]

_H = np.array([[1.0, 0.0]])
_I2 = np.eye(2)


class _BearingFilter:
    """Kalman filter of one track, state ``[bearing, rate]``, one bearing per update.

    The arithmetic of filterpy's ``KalmanFilter.predict`` / ``update`` (same products in the
    same order, Joseph-form covariance update), without its per-call bookkeeping (the tracker
    runs thousands of them per file).
    """

    __slots__ = ("x", "P", "R")

    def __init__(self, x: np.ndarray, P: np.ndarray, r: float) -> None:
        self.x, self.P, self.R = x, P, np.array([[r]])

    def predict(self, F: np.ndarray, Q: np.ndarray) -> None:
        self.x = np.dot(F, self.x)
        self.P = np.dot(np.dot(F, self.P), F.T) + Q

    def update(self, z: float) -> None:
        y = np.array([z]) - np.dot(_H, self.x)
        PHT = np.dot(self.P, _H.T)
        K = np.dot(PHT, 1.0 / (np.dot(_H, PHT) + self.R))  # inv of 1 x 1: 1 / S, exactly
        self.x = self.x + np.dot(K, y)
        I_KH = _I2 - np.dot(K, _H)
        self.P = np.dot(np.dot(I_KH, self.P), I_KH.T) + np.dot(np.dot(K, self.R), K.T)


class NearestNeighbourTracker:
    """Kalman bearing tracker with global nearest-neighbour assignment, optionally
    crossing-aware.

    Parameters
    ----------
    sigma_bearing, q : float, keyword-only
        As in :class:`~fusion.passive.smoothing.batch.BearingSmoother`.
    gate : float, keyword-only
        Gate on the normalised innovation, standard deviations (default 4).
    init_sigma_rate : float, keyword-only
        Rate standard deviation of a new track, rad/s.
    n_confirm : int, keyword-only
        Hits that confirm a tentative track (default 3).
    max_misses : int, keyword-only
        Consecutive misses that end a track (default 5; 1 for a tentative track).
    crossing_aware : bool, keyword-only
        Predict crossings (Struzinski eq. (2)-(4)) and let both tracks coast on their
        prediction while their bearings are closer than `separation`; detections gated by
        several coasting tracks are left shared (their candidates recorded).
    separation : float, keyword-only
        Bearing separation below which a predicted crossing is ambiguous, rad (default
        ``gate * sqrt(2) * sigma_bearing``).
    window_scans : int, keyword-only
        ``J`` of eq. (3)-(4): a crossing counts when ``|t_c|`` is within ``J`` scan periods.

    Notes
    -----
    A Kalman filter per track (filterpy's arithmetic, :class:`_BearingFilter`), state
    ``[bearing, rate]``; the innovation is wrapped by handing the filter the measurement on the
    branch nearest the prediction. Assignment:
    ``scipy.optimize.linear_sum_assignment`` on squared normalised innovations, gated.
    """

    def __init__(
        self,
        *,
        sigma_bearing: float,
        q: float,
        gate: float = 4.0,
        init_sigma_rate: float = 0.01,
        n_confirm: int = 3,
        max_misses: int = 5,
        crossing_aware: bool = False,
        separation: float | None = None,
        window_scans: int = 20,
    ) -> None:
        self.sigma_bearing = check_positive("sigma_bearing", sigma_bearing)
        self.q = check_positive("q", q)
        self.gate = check_positive("gate", gate)
        self.init_sigma_rate = check_positive("init_sigma_rate", init_sigma_rate)
        if n_confirm < 1 or max_misses < 1 or window_scans < 1:
            raise ValueError("n_confirm, max_misses and window_scans must be >= 1")
        self.n_confirm = int(n_confirm)
        self.max_misses = int(max_misses)
        self.crossing_aware = bool(crossing_aware)
        sep = gate * np.sqrt(2.0) * sigma_bearing if separation is None else separation
        self.separation = check_positive("separation", sep)
        self.window_scans = int(window_scans)

    def _new_filter(self, z: float) -> _BearingFilter:
        return _BearingFilter(np.array([float(z), 0.0]),
                              np.diag([self.sigma_bearing**2, self.init_sigma_rate**2]),
                              self.sigma_bearing**2)

    def run(self, times: ArrayLike, bearings: ArrayLike, *,
            on_scan: Callable[[float], None] | None = None) -> TrackerResult:
        """Track unlabeled detections.

        Parameters
        ----------
        times : array_like, shape (n,)
            Detection times, s, non-decreasing; detections with equal time form a scan.
        bearings : array_like, shape (n,)
            Bearings, rad.
        on_scan : callable, optional, keyword-only
            ``on_scan(f)`` after each scan, with the fraction of the detections done (progress).

        Returns
        -------
        TrackerResult
        """
        t, z = _check_detections(times, bearings)
        scan_times, scan_of = np.unique(t, return_inverse=True)
        starts = np.searchsorted(scan_of, np.arange(scan_times.size))
        stops = np.append(starts[1:], t.size)
        period = float(np.median(np.diff(scan_times))) if scan_times.size > 1 else 1.0
        labels = np.full(t.size, -1, np.int64)
        candidates: list[tuple[int, ...]] = [()] * t.size
        tracks: list[dict] = []  # kf, first, states, hits, misses, confirmed, dets
        s2 = self.sigma_bearing**2
        steps: dict[float, tuple[np.ndarray, np.ndarray]] = {}  # dt -> F, Q
        for k, tk in enumerate(scan_times):
            if on_scan is not None and k:
                on_scan(starts[k] / t.size)  # the scans before this one are done
            idx = np.arange(starts[k], stops[k])
            live = [i for i, tr in enumerate(tracks) if tr["alive"]]
            for i in live:  # predict
                tr = tracks[i]
                dt = tk - tr["t"]
                if dt > 0:
                    if dt not in steps:
                        steps[dt] = (transition_matrix(dt, 1), wna_covariance(dt, self.q, 1))
                    tr["kf"].predict(*steps[dt])
                    tr["t"] = tk
            coasting: set[int] = set()
            if self.crossing_aware:
                conf = [i for i in live if tracks[i]["confirmed"]]
                for a_pos, a in enumerate(conf):
                    for b in conf[a_pos + 1:]:
                        xa, xb = tracks[a]["kf"].x, tracks[b]["kf"].x
                        sep = abs(wrap_angle(xa[0] - xb[0]))
                        tc = crossing_time(xa[0], xa[1], xb[0], xb[1])  # eq. (2), from now
                        # eq. (3) predicted (0 < t_c <= J K) or eq. (4) detected (-J K <= t_c <= 0)
                        if sep < self.separation and abs(tc) <= self.window_scans * period:
                            coasting.update((a, b))
            # gated cost matrix of squared normalised innovations
            zk = z[idx]
            if live:  # all live tracks at once (the same arithmetic, element by element)
                pred = np.array([tracks[i]["kf"].x[0] for i in live])
                S = np.array([tracks[i]["kf"].P[0, 0] for i in live]) + s2
                d2 = wrap_angle(zk[None, :] - pred[:, None]) ** 2 / S[:, None]
                cost = np.where(d2 < self.gate**2, d2, np.inf)
            else:
                cost = np.full((0, idx.size), np.inf)
            used = np.zeros(idx.size, bool)
            assigned: dict[int, int] = {}
            if coasting:
                rows = [r for r, i in enumerate(live) if i in coasting]
                for c in range(idx.size):
                    owners = tuple(live[r] for r in rows if np.isfinite(cost[r, c]))
                    if len(owners) >= 2:
                        candidates[idx[c]] = owners
                        used[c] = True
                    elif len(owners) == 1:
                        # gated by one coasting track only: still ambiguous near a crossing
                        candidates[idx[c]] = owners
                        used[c] = True
            # global nearest neighbour: confirmed tracks first, tentative ones on the rest
            for confirmed in (True, False):
                free_rows = [r for r, i in enumerate(live)
                             if i not in coasting and tracks[i]["confirmed"] == confirmed]
                free_cols = np.flatnonzero(~used)
                if not (free_rows and free_cols.size):
                    continue
                sub = cost[np.ix_(free_rows, free_cols)]
                rr, cc = linear_sum_assignment(np.where(np.isfinite(sub), sub, 1e6))
                for r, c in zip(rr, cc, strict=True):
                    if np.isfinite(sub[r, c]):
                        assigned[live[free_rows[r]]] = int(free_cols[c])
                        used[free_cols[c]] = True
            for i in live:
                tr = tracks[i]
                if i in assigned:
                    c = assigned[i]
                    kf = tr["kf"]
                    kf.update(kf.x[0] + wrap_angle(zk[c] - kf.x[0]))
                    labels[idx[c]] = i
                    tr["hits"] += 1
                    tr["misses"] = 0
                    if tr["hits"] >= self.n_confirm:
                        tr["confirmed"] = True
                elif i not in coasting:
                    tr["misses"] += 1
                limit = self.max_misses if tr["confirmed"] else 1
                if tr["misses"] > limit:
                    tr["alive"] = False
                else:
                    tr["states"].append(tr["kf"].x.copy())
                    tr["last"] = k
            for c in np.flatnonzero(~used):  # new tentative tracks
                kf = self._new_filter(zk[c])
                labels[idx[c]] = len(tracks)
                tracks.append({"kf": kf, "t": tk, "first": k, "last": k, "states": [kf.x.copy()],
                               "hits": 1, "misses": 0, "confirmed": False, "alive": True})
        if on_scan is not None:
            on_scan(1.0)
        # keep confirmed tracks, drop trailing coasted states after the last hit
        keep = [i for i, tr in enumerate(tracks) if tr["confirmed"]]
        remap = np.full(len(tracks) + 1, -1, np.int64)
        remap[keep] = np.arange(len(keep))
        labels = remap[labels]
        new_cands = tuple(
            tuple(int(remap[o]) for o in c if remap[o] >= 0) if c else () for c in candidates
        )
        first, last, states = [], [], []
        shared_of: dict[int, list[int]] = {}  # track -> the detections it shares
        for j, c in enumerate(new_cands):
            for o in c:
                shared_of.setdefault(o, []).append(j)
        for i in keep:
            tr = tracks[i]
            own = np.flatnonzero(labels == remap[i])
            shared = shared_of.get(int(remap[i]), [])
            last_det = int(max(scan_of[np.r_[own, shared].astype(int)])) if own.size else tr["last"]
            last_scan = min(tr["last"], last_det)
            first.append(tr["first"])
            last.append(last_scan)
            states.append(np.array(tr["states"][: last_scan - tr["first"] + 1]))
        new_cands = tuple(c if len(c) >= 2 else () for c in new_cands)
        # a detection left with a single candidate belongs to it
        for j, c in enumerate(candidates):
            if c and len(new_cands[j]) == 0:
                owners = [int(remap[o]) for o in c if remap[o] >= 0]
                if len(owners) == 1:
                    labels[j] = owners[0]
        return TrackerResult(labels, new_cands, np.array(first, np.int64),
                             np.array(last, np.int64), tuple(states), scan_times)
