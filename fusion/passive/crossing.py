"""Prediction and detection of bearing-track crossings.

Implements *Target Track Crossing Prediction/Detection* (the method text of that title): every
K seconds each track's bearing rate ``B'`` and bearing intercept ``B0`` come from a least-squares
line over its most recent J samples (regression routine 104A); for every pair of tracks the
crossing time ``t_c`` follows from equation (2); pairs whose ``t_c`` falls outside an accepted
range are dropped (in-range check 104C); inequality (3) predicts a crossing and inequality (4)
detects one (104D, 104E), and either raises an alert (output 106).

Pieces:

- :class:`SlidingLineFit` - recursive least-squares line over a sliding window of J samples for
  many tracks at once (running sums, O(1) per track per update), bearings unwrapped against the
  track's own current line;
- :func:`evaluate_pairs` - equation (2), the in-range check and inequalities (3)/(4) for all
  pairs at once (numpy upper-triangle arrays);
- :class:`CrossingDetector` - the streaming component (``step``) that also de-duplicates alerts;
- :func:`resample_bearings` and :func:`detect_crossings` - the batch entry point for a bearing
  table sampled irregularly.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Alert",
    "AlertKind",
    "CrossingAlert",
    "CrossingDetector",
    "PairCheck",
    "CrossingScore",
    "ResampledBearings",
    "SlidingLineFit",
    "detect_crossings",
    "estimate_period",
    "evaluate_pairs",
    "resample_bearings",
    "score_alerts",
]

logger = logging.getLogger(__name__)

_TWO_PI = 2.0 * np.pi


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Wrap radians to ``[-pi, pi)`` (same convention as :func:`fusion.geometry.wrap_angle`)."""
    return np.mod(a + np.pi, _TWO_PI) - np.pi


class AlertKind(StrEnum):
    """Kind of crossing alert: ``predicted`` (inequality 3) or ``detected`` (inequality 4)."""

    PREDICTED = "predicted"
    DETECTED = "detected"


@dataclass(frozen=True, slots=True)
class CrossingAlert:
    """An alert that two bearing tracks will cross or have crossed.

    Attributes
    ----------
    time : float
        Time of the sample at which the inequality held, s.
    track_a, track_b : int
        The two tracks, ``track_a < track_b``.
    t_cross : float
        Crossing time from equation (2), s (same clock as `time`).
    kind : AlertKind
        ``predicted`` (crossing ahead, inequality 3) or ``detected`` (crossing behind,
        inequality 4).
    """

    time: float
    track_a: int
    track_b: int
    t_cross: float
    kind: AlertKind


#: Short name of :class:`CrossingAlert`.
Alert = CrossingAlert


# --------------------------------------------------------------------------------------------
# regression routine (104A): recursive least squares over a sliding window
# --------------------------------------------------------------------------------------------
class SlidingLineFit:
    """Least-squares lines ``y = B0 + B' t`` over the most recent J samples of many tracks.

    The fit is recursive: each track keeps the running sums ``n, S_t, S_y, S_tt, S_ty`` of its
    window; a new sample adds its terms and, once the window is full, the sample leaving the
    window subtracts its own, so an update costs O(1) per track whatever J is. Angles are
    unwrapped on entry against the track's current line (the line's value at the new sample's
    time, or the last sample while fewer than two are held), so a track passing through
    +-180 deg continues smoothly.

    Parameters
    ----------
    window : int
        J, number of samples in the window (> 2).
    max_gap_s : float, optional
        A track whose new sample comes more than this after its previous one starts a new
        window (default: never).
    angular : bool, optional
        Whether values are angles in radians to unwrap (default True).

    Notes
    -----
    Slope and intercept of the window (regression routine 104A of the method text)::

        D   = n S_tt - S_t^2
        B'  = (n S_ty - S_t S_y) / D
        B0  = (S_y - B' S_t) / n

    with times measured from a per-track origin. To keep round-off from accumulating in the
    running sums over long streams, every J updates the sums of a track are recomputed from
    its stored window (O(J) every J updates: still O(1) amortised), its time origin is moved to
    the oldest sample of the window and whole turns are taken out of its unwrapped values.

    Examples
    --------
    >>> fit = SlidingLineFit(window=3, angular=False)
    >>> for t in (0.0, 1.0, 2.0, 3.0):
    ...     fit.update([7], t, [2.0 * t + 1.0])
    >>> value, slope, n = fit.line([7], 3.0)
    >>> float(value[0]), float(slope[0]), int(n[0])
    (7.0, 2.0, 3)
    """

    def __init__(self, *, window: int, max_gap_s: float | None = None, angular: bool = True) -> None:
        if int(window) != window or window < 3:
            raise ValueError(f"window J must be an integer > 2, got {window!r}")
        if max_gap_s is not None and not (np.isfinite(max_gap_s) and max_gap_s > 0):
            raise ValueError(f"max_gap_s must be > 0, got {max_gap_s!r}")
        self.window = int(window)
        self.max_gap_s = max_gap_s
        self.angular = bool(angular)
        self._slot: dict[int, int] = {}
        self._known_ids = np.zeros(0, np.int64)  # sorted ids ...
        self._known_slots = np.zeros(0, np.int64)  # ... and their slots
        self._alloc(16)

    # -- storage ------------------------------------------------------------------------------
    def _alloc(self, cap: int) -> None:
        J = self.window
        self._cap = cap
        self._n = np.zeros(cap, np.int64)  # samples in window
        self._head = np.zeros(cap, np.int64)  # next write position (= oldest when full)
        self._since = np.zeros(cap, np.int64)  # updates since the last exact refresh
        self._t0 = np.zeros(cap)  # time origin
        self._last_t = np.full(cap, -np.inf)
        self._last_y = np.zeros(cap)
        self._s = np.zeros((4, cap))  # S_t, S_y, S_tt, S_ty
        self._bt = np.zeros((cap, J))  # window times (relative to origin)
        self._by = np.zeros((cap, J))  # window values (unwrapped)
        self._bv = np.zeros((cap, J), bool)  # entry holds a sample

    def _grow(self, need: int) -> None:
        old = {k: getattr(self, k) for k in
               ("_n", "_head", "_since", "_t0", "_last_t", "_last_y", "_s", "_bt", "_by", "_bv")}
        cap = self._cap
        while cap < need:
            cap *= 2
        self._alloc(cap)
        for k, v in old.items():
            if k == "_s":
                self._s[:, : v.shape[1]] = v
            else:
                getattr(self, k)[: v.shape[0]] = v

    def slots(self, track_ids: ArrayLike, *, create: bool = False) -> NDArray[np.int64]:
        """Storage slots of `track_ids` (-1 for unknown ids unless `create`), vectorised."""
        ids = np.asarray(track_ids, dtype=np.int64)
        pos = np.searchsorted(self._known_ids, ids)
        hit = pos < self._known_ids.size
        hit[hit] = self._known_ids[pos[hit]] == ids[hit]
        out = np.full(ids.size, -1, np.int64)
        out[hit] = self._known_slots[pos[hit]]
        if create and not np.all(hit):
            new = np.unique(ids[~hit])
            first = len(self._slot)
            if first + new.size > self._cap:
                self._grow(first + new.size)
            for k, tid in enumerate(new.tolist()):
                self._slot[tid] = first + k
            all_ids = np.concatenate([self._known_ids, new])
            all_slots = np.concatenate([self._known_slots, first + np.arange(new.size)])
            order = np.argsort(all_ids, kind="stable")
            self._known_ids, self._known_slots = all_ids[order], all_slots[order]
            return self.slots(ids)
        return out

    @property
    def track_ids(self) -> list[int]:
        """Ids of every track seen so far."""
        return list(self._slot)

    # -- the fit ------------------------------------------------------------------------------
    def _coeffs(self, s: NDArray[np.int64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(intercept at the origin, slope) of slots `s`; slope 0 when fewer than 2 samples."""
        n = self._n[s].astype(float)
        st, sy, stt, sty = self._s[0, s], self._s[1, s], self._s[2, s], self._s[3, s]
        den = n * stt - st * st  # D = n S_tt - S_t^2
        ok = (n >= 2) & (den > 0)
        slope = np.where(ok, (n * sty - st * sy) / np.where(ok, den, 1.0), 0.0)  # B'
        icpt = np.where(n > 0, (sy - slope * st) / np.maximum(n, 1.0), 0.0)  # B0
        return icpt, slope

    def update(self, track_ids: ArrayLike, time: float, values: ArrayLike) -> None:
        """Add one sample at `time` to each of `track_ids`.

        Parameters
        ----------
        track_ids : array_like of int, shape (n,)
            Distinct track ids (new ids get a window).
        time : float
            Sample time, s; later than each track's previous sample.
        values : array_like, shape (n,)
            Sample values (rad when `angular`).
        """
        ids = np.asarray(track_ids)
        y = np.asarray(values, dtype=float)
        if ids.shape != y.shape or ids.ndim != 1:
            raise ValueError("track_ids and values must be 1-D arrays of one length")
        if ids.size == 0:
            return
        s = self.slots(ids, create=True)
        t = float(time)
        if np.any(t <= self._last_t[s]):
            raise ValueError(f"time {t} is not after the previous sample of every track")
        # Tracks that are new or come back after a long gap start an empty window.
        restart = self._n[s] == 0
        if self.max_gap_s is not None:
            restart |= (t - self._last_t[s]) > self.max_gap_s
        if np.any(restart):
            r = s[restart]
            self._n[r] = 0
            self._head[r] = 0
            self._since[r] = 0
            self._s[:, r] = 0.0
            self._bv[r] = False
            self._t0[r] = t
        x = t - self._t0[s]
        if self.angular:
            # Unwrap against the track's current line (last sample while n < 2).
            icpt, slope = self._coeffs(s)
            n = self._n[s]
            ref = np.where(n >= 2, icpt + slope * x, self._last_y[s])
            y = np.where(n == 0, _wrap(y), ref + _wrap(y - ref))
        full = self._n[s] == self.window
        h = self._head[s]
        # Remove the sample leaving the window (full windows), then add the new one.
        if np.any(full):
            sf, hf = s[full], h[full]
            xo, yo = self._bt[sf, hf], self._by[sf, hf]
            self._s[0, sf] -= xo
            self._s[1, sf] -= yo
            self._s[2, sf] -= xo * xo
            self._s[3, sf] -= xo * yo
        self._s[0, s] += x
        self._s[1, s] += y
        self._s[2, s] += x * x
        self._s[3, s] += x * y
        self._bt[s, h] = x
        self._by[s, h] = y
        self._bv[s, h] = True
        self._head[s] = (h + 1) % self.window
        self._n[s] = np.minimum(self._n[s] + 1, self.window)
        self._last_t[s] = t
        self._last_y[s] = y
        self._since[s] += 1
        due = s[self._since[s] >= self.window]
        if due.size:
            self._refresh(due)

    def _refresh(self, s: NDArray[np.int64]) -> None:
        """Recompute the sums of slots `s` exactly, with a new origin and whole turns removed."""
        v = self._bv[s]
        bt = np.where(v, self._bt[s], np.inf)
        shift_t = np.min(bt, axis=1)  # oldest sample becomes the origin
        by = self._by[s]
        if self.angular:
            mean_y = np.sum(np.where(v, by, 0.0), axis=1) / np.maximum(v.sum(axis=1), 1)
            turns = _TWO_PI * np.round(mean_y / _TWO_PI)
        else:
            turns = np.zeros(s.size)
        xt = np.where(v, self._bt[s] - shift_t[:, None], 0.0)
        yy = np.where(v, by - turns[:, None], 0.0)
        self._bt[s] = xt
        self._by[s] = yy
        self._t0[s] += shift_t
        self._last_y[s] -= turns
        self._s[0, s] = xt.sum(axis=1)
        self._s[1, s] = yy.sum(axis=1)
        self._s[2, s] = (xt * xt).sum(axis=1)
        self._s[3, s] = (xt * yy).sum(axis=1)
        self._since[s] = 0

    def line(
        self, track_ids: ArrayLike, time: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """Value and slope of each track's window line at `time`.

        Parameters
        ----------
        track_ids : array_like of int, shape (n,)
            Known track ids.
        time : float
            Where to evaluate the line, s.

        Returns
        -------
        value : ndarray, shape (n,)
            ``B0 + B' (time - origin)`` (unwrapped; rad when `angular`).
        slope : ndarray, shape (n,)
            ``B'``, per second.
        n : ndarray of int64, shape (n,)
            Samples in each window (J when full).
        """
        s = self.slots(track_ids)
        if np.any(s < 0):
            unknown = np.asarray(track_ids)[s < 0]
            raise ValueError(f"unknown track id(s) {unknown.tolist()[:5]}")
        icpt, slope = self._coeffs(s)
        return icpt + slope * (float(time) - self._t0[s]), slope, self._n[s].copy()

    def window_samples(self, track_id: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Times (s, absolute) and unwrapped values of one track's window, oldest first."""
        s = int(self.slots([track_id])[0])
        if s < 0:
            raise ValueError(f"unknown track id {track_id}")
        n, h, J = int(self._n[s]), int(self._head[s]), self.window
        idx = (h - n + np.arange(n)) % J
        return self._bt[s, idx] + self._t0[s], self._by[s, idx].copy()


# --------------------------------------------------------------------------------------------
# crossing time (104B), in-range check (104C), inequalities (104D, 104E)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PairCheck:
    """Pairs that satisfy inequality (3) or (4) at one sample.

    Attributes
    ----------
    index_a, index_b : ndarray of int64, shape (p,)
        Positions of the two tracks in the arrays given to :func:`evaluate_pairs`,
        ``index_a < index_b``.
    t_cross : ndarray, shape (p,)
        Crossing times from equation (2), s.
    predicted : ndarray of bool, shape (p,)
        True where inequality (3) holds, False where inequality (4) holds.
    """

    index_a: NDArray[np.int64]
    index_b: NDArray[np.int64]
    t_cross: NDArray[np.float64]
    predicted: NDArray[np.bool_]


_TRIU_CACHE: dict[int, tuple[NDArray[np.int64], NDArray[np.int64]]] = {}


def _triu(n: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Upper-triangle index pairs (i < j) of n items, cached for the last few sizes."""
    if n not in _TRIU_CACHE:
        if len(_TRIU_CACHE) > 8:
            _TRIU_CACHE.clear()
        ia, ib = np.triu_indices(n, k=1)
        _TRIU_CACHE[n] = (ia.astype(np.int64), ib.astype(np.int64))
    return _TRIU_CACHE[n]


def _candidate_pairs(
    b: NDArray[np.float64], r: NDArray[np.float64], horizon: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Index pairs (i < j) that can pass the in-range check, all others left out exactly.

    A pair passes only if ``|wrap(b_j - b_i)| <= horizon |r_i - r_j|``, which is at most
    ``W_i = horizon max(r_i - min r, max r - r_i)`` (and likewise ``W_j``). When every
    ``W_i < pi`` the bearings are sorted around the circle and each track is paired with the
    tracks up to ``W_i`` ahead of it (a sweep with ``searchsorted``): a passing pair lies
    within ``W`` ahead of one of its tracks, and no pair can be listed from both sides (that
    would need ``W_i + W_j >= 2 pi``). Otherwise every pair is returned.
    """
    n = b.size
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    w = horizon * np.maximum(r - r.min(), r.max() - r)
    w = w * (1.0 + 1e-9) + 1e-12  # margin for round-off: never drops a pair that passes
    if not np.all(w < np.pi):
        return _triu(n)
    order = np.argsort(b, kind="stable")
    bs = b[order]
    ext = np.concatenate([bs, bs + _TWO_PI])
    pos = np.arange(n)
    cnt = np.searchsorted(ext, bs + w[order], side="right") - 1 - pos
    cnt = np.clip(cnt, 0, n - 1)
    total = int(cnt.sum())
    p = np.repeat(pos, cnt)
    first = np.repeat(np.cumsum(cnt) - cnt, cnt)
    q = (p + 1 + np.arange(total) - first) % n
    i, j = order[p], order[q]
    return np.minimum(i, j), np.maximum(i, j)


def evaluate_pairs(
    time: float,
    bearing_rad: ArrayLike,
    rate_rad_per_s: ArrayLike,
    *,
    J: int,
    K: float,
    horizon_s: float | None = None,
    min_rate_diff_rad_per_s: float = 1e-12,
) -> PairCheck:
    """Crossing time of every pair of tracks and the prediction/detection inequalities.

    Parameters
    ----------
    time : float
        Time ``t_i`` of the current sample, s (plays the role of ``i K`` in the method text).
    bearing_rad : array_like, shape (n,)
        Each track's fitted bearing at `time`, rad (any wrap).
    rate_rad_per_s : array_like, shape (n,)
        Each track's fitted bearing rate ``B'``, rad/s.
    J : int
        Samples per window.
    K : float
        Sample period, s.
    horizon_s : float, optional
        In-range check: pairs with ``|t_c - time| > horizon_s`` are dropped (default ``J K``,
        the widest span either inequality can accept).
    min_rate_diff_rad_per_s : float, optional
        In-range check: pairs with ``|B'_a - B'_b|`` at or below this (parallel tracks) are
        dropped, which also keeps equation (2) from dividing by zero.

    Returns
    -------
    PairCheck
        The pairs that satisfy inequality (3) (``predicted``) or (4).

    Notes
    -----
    Equation (2) of *Target Track Crossing Prediction/Detection*,
    ``t_c = (B0_b - B0_a) / (B'_a - B'_b)``, is evaluated with the time origin at the current
    sample, where the intercepts are the fitted bearings at ``t_i`` and their difference can be
    wrapped to ``[-pi, pi)``::

        t_c = t_i + wrap(B_b(t_i) - B_a(t_i)) / (B'_a - B'_b)

    so tracks on either side of the +-180 deg (or 0/360 deg) wrap cross where they meet, and
    tracks on opposite bearings (difference near 180 deg) get a distant ``t_c``. Inequality (3)
    (prediction) is ``t_i < t_c <= t_i + J K``; inequality (4) (detection) is
    ``t_i - J K <= t_c <= t_i``. At most one holds for a pair. All ``n (n - 1) / 2`` pairs are
    screened at once with the division-free test ``|num| <= horizon |den|`` on numpy pair
    arrays; only the survivors are divided. Pairs that cannot pass (bearings further apart
    than ``horizon max|B'_a - B'|`` over the other tracks) are left out beforehand by a
    sweep over the bearings sorted around the circle, which returns exactly the same alerts
    as the full upper triangle and scales with the number of nearby pairs, not with ``n^2``.

    Examples
    --------
    >>> chk = evaluate_pairs(100.0, [0.0, 0.02], [0.001, -0.001], J=10, K=10.0)
    >>> round(float(chk.t_cross[0]), 6), bool(chk.predicted[0])
    (110.0, True)
    """
    b = np.asarray(bearing_rad, dtype=float)
    r = np.asarray(rate_rad_per_s, dtype=float)
    if b.shape != r.shape or b.ndim != 1:
        raise ValueError("bearing_rad and rate_rad_per_s must be 1-D arrays of one length")
    if int(J) != J or J < 3:
        raise ValueError(f"J must be an integer > 2, got {J!r}")
    if not (np.isfinite(K) and K > 0):
        raise ValueError(f"K must be > 0, got {K!r}")
    span = J * K
    horizon = span if horizon_s is None else float(horizon_s)
    if not horizon > 0:
        raise ValueError(f"horizon_s must be > 0, got {horizon_s!r}")
    b = _wrap(b)
    ia, ib = _candidate_pairs(b, r, horizon)
    num = b[ib] - b[ia]  # B0_b - B0_a at the current sample, in (-2 pi, 2 pi)
    num -= _TWO_PI * (num >= np.pi)
    num += _TWO_PI * (num < -np.pi)  # now wrapped to [-pi, pi)
    den = r[ia] - r[ib]  # B'_a - B'_b
    # 104C in-range check, division-free: |t_c - t_i| <= horizon and tracks not parallel.
    keep = np.abs(num) <= horizon * np.abs(den)
    keep &= np.abs(den) > min_rate_diff_rad_per_s
    k = np.flatnonzero(keep)
    tau = num[k] / den[k]  # t_c - t_i, equation (2)
    pred = (tau > 0.0) & (tau <= span)  # inequality (3): iK < t_c <= K(i + J)
    det = (tau >= -span) & (tau <= 0.0)  # inequality (4): K(i - J) <= t_c <= iK
    hit = np.flatnonzero(pred | det)
    a_idx, b_idx = ia[k][hit], ib[k][hit]
    srt = np.lexsort((b_idx, a_idx))
    return PairCheck(
        index_a=a_idx[srt],
        index_b=b_idx[srt],
        t_cross=float(time) + tau[hit][srt],
        predicted=pred[hit][srt],
    )


# --------------------------------------------------------------------------------------------
# streaming component
# --------------------------------------------------------------------------------------------
@dataclass
class _Events:
    """Open crossing events, one row per pair, sorted by pair key (internal, mutable).

    ``key = slot_a * 2**32 + slot_b`` with the tracks' storage slots; ``t_cross`` is the
    latest crossing time seen for the event; ``predicted``/``detected`` say which alerts the
    event has raised.
    """

    key: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    t_cross: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    predicted: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))
    detected: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))

    def keep(self, mask: NDArray[np.bool_]) -> None:
        self.key, self.t_cross = self.key[mask], self.t_cross[mask]
        self.predicted, self.detected = self.predicted[mask], self.detected[mask]


class CrossingDetector:
    """Streaming crossing prediction and detection for many bearing tracks.

    Parameters
    ----------
    J : int, optional
        Samples in each track's least-squares window (> 2; the method text suggests at
        least 10).
    K : float
        Sample period, s: `step` is called every K seconds.
    horizon_s : float, optional
        In-range check of ``t_c`` about the current sample, s (default ``J K``).
    min_rate_diff_deg_per_s : float, optional
        In-range check: pairs whose bearing rates differ by this much or less are treated as
        parallel and never alert (default 1e-9 deg/s: only numerically equal rates).
    merge_window_s : float, optional
        De-duplication window, s (default ``J K``; see Notes).
    max_gap_s : float, optional
        A track silent for longer than this restarts its window (default ``3 K``).

    Notes
    -----
    Per sample (*Target Track Crossing Prediction/Detection*, FIG. 2): each reported track's
    window line is updated (104A, :class:`SlidingLineFit`); tracks reported at this sample with
    a full window of J samples are paired; equation (2), the in-range check (104C) and
    inequalities (3) and (4) (104D, 104E) are evaluated by :func:`evaluate_pairs`, with the
    current sample time ``t_i`` in place of ``i K``.

    De-duplication (the method text raises an alert whenever an inequality holds, which would
    repeat it at up to J consecutive samples): each pair keeps its current crossing *event*,
    identified by the latest ``t_c`` seen for it. A satisfied inequality whose ``t_c`` lies
    within `merge_window_s` of the event's belongs to that event (and updates its ``t_c``);
    otherwise it opens a new event. Per event at most one ``predicted`` alert (only before
    any ``detected`` alert of the event) and at most one ``detected`` alert are issued. Two
    crossings of the same pair closer than `merge_window_s` are reported as one.

    Examples
    --------
    >>> det = CrossingDetector(J=5, K=1.0)
    >>> alerts = []
    >>> for i in range(12):
    ...     alerts += det.step(float(i), [1, 2], [0.5 * i, 8.0 - 0.5 * i])
    >>> [(a.kind.value, a.t_cross) for a in alerts]
    [('predicted', 8.0), ('detected', 8.0)]
    """

    def __init__(
        self,
        *,
        J: int = 10,
        K: float,
        horizon_s: float | None = None,
        min_rate_diff_deg_per_s: float = 1e-9,
        merge_window_s: float | None = None,
        max_gap_s: float | None = None,
    ) -> None:
        if int(J) != J or J < 3:
            raise ValueError(f"J (samples per window) must be an integer > 2, got {J!r}")
        if not (np.isfinite(K) and K > 0):
            raise ValueError(f"K (sample period) must be > 0 s, got {K!r}")
        for name, v in (("horizon_s", horizon_s), ("merge_window_s", merge_window_s),
                        ("max_gap_s", max_gap_s)):
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be > 0, got {v!r}")
        if not (np.isfinite(min_rate_diff_deg_per_s) and min_rate_diff_deg_per_s >= 0):
            raise ValueError(f"min_rate_diff_deg_per_s must be >= 0, got {min_rate_diff_deg_per_s!r}")
        self.J = int(J)
        self.K = float(K)
        self.horizon_s = self.J * self.K if horizon_s is None else float(horizon_s)
        self.min_rate_diff_rad_per_s = float(np.radians(min_rate_diff_deg_per_s))
        self.merge_window_s = self.J * self.K if merge_window_s is None else float(merge_window_s)
        self.max_gap_s = 3.0 * self.K if max_gap_s is None else float(max_gap_s)
        self.reset()

    def reset(self) -> None:
        """Forget every track and event."""
        self._fit = SlidingLineFit(window=self.J, max_gap_s=self.max_gap_s)
        self._events = _Events()
        self._last_time = -np.inf

    @property
    def fit(self) -> SlidingLineFit:
        """The per-track window fits (read them, do not update them)."""
        return self._fit

    def step(
        self, time: float, track_ids: ArrayLike, bearings_deg: ArrayLike
    ) -> list[CrossingAlert]:
        """Process the bearings of one sample and return the new alerts.

        Parameters
        ----------
        time : float
            Sample time, s; strictly increasing from call to call (every K s).
        track_ids : array_like of int, shape (n,)
            Distinct ids of the tracks reported at this sample (negative ids, detections of
            unknown origin, are ignored).
        bearings_deg : array_like, shape (n,)
            Their bearings, deg (any wrap).

        Returns
        -------
        list of CrossingAlert
            Alerts raised at this sample, sorted by track pair.
        """
        t = float(time)
        if not np.isfinite(t):
            raise ValueError(f"time must be finite, got {time!r}")
        if t <= self._last_time:
            raise ValueError(f"time {t} is not after the previous step ({self._last_time})")
        ids = np.asarray(track_ids)
        bdeg = np.asarray(bearings_deg, dtype=float)
        if ids.ndim != 1 or ids.shape != bdeg.shape:
            raise ValueError("track_ids and bearings_deg must be 1-D arrays of one length")
        if ids.size and not np.issubdtype(ids.dtype, np.integer):
            if not np.all(np.isfinite(ids.astype(float))) or np.any(ids != np.round(ids)):
                raise ValueError("track_ids must be integers")
            ids = ids.astype(np.int64)
        if not np.all(np.isfinite(bdeg)):
            raise ValueError("bearings_deg must be finite")
        keep = ids >= 0
        ids, bdeg = ids[keep], bdeg[keep]
        if np.unique(ids).size != ids.size:
            raise ValueError(f"duplicate track ids at time {t}")
        self._last_time = t
        order = np.argsort(ids, kind="stable")
        ids, bdeg = ids[order], bdeg[order]
        self._fit.update(ids, t, np.radians(bdeg))
        value, slope, n = self._fit.line(ids, t)
        full = n >= self.J
        ids, value, slope = ids[full], value[full], slope[full]
        self._prune(t)
        if ids.size < 2:
            return []
        chk = evaluate_pairs(
            t, value, slope, J=self.J, K=self.K, horizon_s=self.horizon_s,
            min_rate_diff_rad_per_s=self.min_rate_diff_rad_per_s,
        )
        return self._alerts(t, ids[chk.index_a], ids[chk.index_b], chk.t_cross, chk.predicted)

    def _prune(self, t: float) -> None:
        """Drop events no later ``t_c`` can join (older than J K + merge window)."""
        limit = t - self.J * self.K - self.merge_window_s
        ev = self._events
        if ev.key.size and ev.t_cross.min() < limit:
            ev.keep(ev.t_cross >= limit)

    def _alerts(
        self,
        t: float,
        a: NDArray[np.int64],
        b: NDArray[np.int64],
        tc: NDArray[np.float64],
        predicted: NDArray[np.bool_],
    ) -> list[CrossingAlert]:
        """Apply the de-duplication rule to the pairs that satisfied an inequality."""
        if a.size == 0:
            return []
        sa, sb = self._fit.slots(a), self._fit.slots(b)
        key = sa * (1 << 32) + sb
        ev = self._events
        pos = np.searchsorted(ev.key, key)
        found = pos < ev.key.size
        found[found] = ev.key[pos[found]] == key[found]
        pf = pos[found]
        same = np.zeros(key.size, bool)
        same[found] = np.abs(tc[found] - ev.t_cross[pf]) <= self.merge_window_s
        old_pred = np.zeros(key.size, bool)
        old_det = np.zeros(key.size, bool)
        old_pred[found] = ev.predicted[pf]
        old_det[found] = ev.detected[pf]
        old_pred &= same  # a new event starts with no alerts
        old_det &= same
        emit_pred = predicted & ~old_pred & ~old_det
        emit_det = ~predicted & ~old_det
        # Existing rows: the event (same or replaced) takes the latest t_c and flags.
        ev.t_cross[pf] = tc[found]
        ev.predicted[pf] = (old_pred | emit_pred)[found]
        ev.detected[pf] = (old_det | emit_det)[found]
        new = ~found
        if np.any(new):
            ev.key = np.concatenate([ev.key, key[new]])
            ev.t_cross = np.concatenate([ev.t_cross, tc[new]])
            ev.predicted = np.concatenate([ev.predicted, emit_pred[new]])
            ev.detected = np.concatenate([ev.detected, emit_det[new]])
            ev.keep(np.argsort(ev.key, kind="stable"))
        emit = np.flatnonzero(emit_pred | emit_det)
        kinds = np.where(emit_pred[emit], 0, 1).tolist()
        kind_of = (AlertKind.PREDICTED, AlertKind.DETECTED)
        out = [
            CrossingAlert(t, ta, tb, tcross, kind_of[k])
            for ta, tb, tcross, k in zip(a[emit].tolist(), b[emit].tolist(), tc[emit].tolist(),
                                         kinds, strict=True)
        ]
        if out:
            logger.debug("t=%.3f: %d crossing alert(s)", t, len(out))
        return out


# --------------------------------------------------------------------------------------------
# batch entry point
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ResampledBearings:
    """Bearing tracks on a common K-second grid.

    Attributes
    ----------
    track_id : ndarray of int64, shape (m,)
        Track of each row.
    time : ndarray, shape (m,)
        Grid times ``origin + k K``, s; rows sorted by time, then track id.
    bearing_deg : ndarray, shape (m,)
        Bearings, deg in [0, 360).
    period_s : float
        K, s.
    """

    track_id: NDArray[np.int64]
    time: NDArray[np.float64]
    bearing_deg: NDArray[np.float64]
    period_s: float


def estimate_period(track_id: ArrayLike, time: ArrayLike) -> float:
    """Median positive time step within tracks, s (a default for K)."""
    tid = np.asarray(track_id)
    tt = np.asarray(time, dtype=float)
    order = np.lexsort((tt, tid))
    tid, tt = tid[order], tt[order]
    dt = np.diff(tt)[(np.diff(tid) == 0)]
    dt = dt[dt > 0]
    if dt.size == 0:
        raise ValueError("cannot infer the sample period: no track has two distinct times")
    return float(np.median(dt))


def resample_bearings(
    track_id: ArrayLike,
    time: ArrayLike,
    bearing_deg: ArrayLike,
    *,
    period_s: float,
    max_gap_s: float | None = None,
    origin_s: float | None = None,
) -> ResampledBearings:
    """Put bearing tracks on a common grid ``origin + k K`` by linear interpolation.

    Parameters
    ----------
    track_id : array_like of int, shape (m,)
        Track of each sample (negative ids, detections of unknown origin, are dropped).
    time : array_like, shape (m,)
        Sample times, s, in any order; irregular spacing allowed.
    bearing_deg : array_like, shape (m,)
        Bearings, deg.
    period_s : float
        Grid step K, s.
    max_gap_s : float, optional
        Grid points inside a gap longer than this between two samples of a track are left
        out, so the track stops and starts again (default ``3 K``).
    origin_s : float, optional
        Grid origin, s (default: the earliest sample time).

    Returns
    -------
    ResampledBearings

    Notes
    -----
    Each track's bearings are unwrapped in time order and linearly interpolated at the grid
    points inside its own time span (a track that starts late or stops early covers only its
    span). Samples at equal times are averaged (on the unwrapped values). Input already on
    the grid is returned unchanged. There is no smoothing: the least-squares window of the
    detector does that.
    """
    tid = np.asarray(track_id)
    tt = np.asarray(time, dtype=float)
    bb = np.asarray(bearing_deg, dtype=float)
    if not (tid.shape == tt.shape == bb.shape) or tid.ndim != 1:
        raise ValueError("track_id, time and bearing_deg must be 1-D arrays of one length")
    if not (np.all(np.isfinite(tt)) and np.all(np.isfinite(bb))):
        raise ValueError("time and bearing_deg must be finite")
    if not (np.isfinite(period_s) and period_s > 0):
        raise ValueError(f"period K must be > 0 s, got {period_s!r}")
    gap = 3.0 * period_s if max_gap_s is None else float(max_gap_s)
    if not gap > 0:
        raise ValueError(f"max_gap_s must be > 0, got {max_gap_s!r}")
    keep = tid >= 0
    tid, tt, bb = tid[keep].astype(np.int64), tt[keep], bb[keep]
    if tid.size == 0:
        return ResampledBearings(np.zeros(0, np.int64), np.zeros(0), np.zeros(0), float(period_s))
    t0 = float(tt.min()) if origin_s is None else float(origin_s)
    eps = 1e-9 * period_s
    out_id, out_t, out_b = [], [], []
    for k in np.unique(tid):
        m = tid == k
        ts, inv = np.unique(tt[m], return_inverse=True)
        order = np.argsort(tt[m], kind="stable")
        unw = np.empty(m.sum())
        unw[order] = np.degrees(np.unwrap(np.radians(bb[m][order])))
        ys = np.bincount(inv, weights=unw) / np.bincount(inv)  # mean at equal times
        k_lo = int(np.ceil((ts[0] - t0) / period_s - 1e-9))
        k_hi = int(np.floor((ts[-1] - t0) / period_s + 1e-9))
        if k_hi < k_lo:
            continue
        grid = t0 + np.arange(k_lo, k_hi + 1) * period_s
        grid = np.clip(grid, ts[0], ts[-1]) if ts.size > 1 else grid
        if ts.size == 1:
            vals = np.full(grid.size, ys[0])
            ok = np.abs(grid - ts[0]) <= eps
        else:
            vals = np.interp(grid, ts, ys)
            # Leave out grid points inside long gaps (the track stopped meanwhile).
            j = np.clip(np.searchsorted(ts, grid, side="right") - 1, 0, ts.size - 2)
            on_sample = np.isclose(grid, ts[j], rtol=0, atol=eps) | np.isclose(
                grid, ts[j + 1], rtol=0, atol=eps)
            ok = on_sample | ((ts[j + 1] - ts[j]) <= gap)
        n_ok = int(ok.sum())
        out_id.append(np.full(n_ok, k, np.int64))
        out_t.append(t0 + np.arange(k_lo, k_hi + 1)[ok] * period_s)
        out_b.append(np.mod(vals[ok], 360.0))
    if not out_id:
        return ResampledBearings(np.zeros(0, np.int64), np.zeros(0), np.zeros(0), float(period_s))
    rid, rt, rb = np.concatenate(out_id), np.concatenate(out_t), np.concatenate(out_b)
    order = np.lexsort((rid, rt))
    return ResampledBearings(rid[order], rt[order], rb[order], float(period_s))


def detect_crossings(
    table: Any,
    *,
    J: int = 10,
    K: float | None = None,
    horizon_s: float | None = None,
    min_rate_diff_deg_per_s: float = 1e-9,
    merge_window_s: float | None = None,
    max_gap_s: float | None = None,
) -> list[CrossingAlert]:
    """Crossing alerts of a whole bearing table (batch entry point).

    Parameters
    ----------
    table : fusion.io.Table or mapping
        Columns ``track_id`` (int), ``time`` (s) and ``bearing_deg`` (deg), shape (m,) each;
        rows with ``track_id`` -1 (unknown origin) are ignored.
    J : int, optional
        Samples per least-squares window.
    K : float, optional
        Sample period, s (default: the median time step within tracks).
    horizon_s, min_rate_diff_deg_per_s, merge_window_s, max_gap_s
        As in :class:`CrossingDetector` (`max_gap_s` also bounds interpolation gaps).

    Returns
    -------
    list of CrossingAlert
        Sorted by time, then pair, predicted before detected.

    Notes
    -----
    The table is resampled onto the grid ``t_min + k K`` (:func:`resample_bearings`) and fed
    to a :class:`CrossingDetector` one grid time at a time.
    """
    cols: Mapping[str, Any] = table.columns if hasattr(table, "columns") else table
    for name in ("track_id", "time", "bearing_deg"):
        if name not in cols:
            raise ValueError(f"bearing table has no column {name!r}")
    tid = np.asarray(cols["track_id"])
    n_unknown = int(np.sum(tid < 0))
    if n_unknown:
        logger.info("ignoring %d detection(s) of unknown origin (track_id -1)", n_unknown)
    keep = tid >= 0
    period = estimate_period(tid[keep], np.asarray(cols["time"])[keep]) if K is None else K
    det = CrossingDetector(
        J=J, K=period, horizon_s=horizon_s, min_rate_diff_deg_per_s=min_rate_diff_deg_per_s,
        merge_window_s=merge_window_s, max_gap_s=max_gap_s,
    )
    rs = resample_bearings(
        tid, cols["time"], cols["bearing_deg"], period_s=det.K, max_gap_s=det.max_gap_s
    )
    for k in np.unique(rs.track_id):
        if np.sum(rs.track_id == k) < det.J:
            logger.warning("track %d has fewer than J=%d samples on the grid: never paired", k, det.J)
    alerts: list[CrossingAlert] = []
    if rs.time.size == 0:
        return alerts
    bounds = np.flatnonzero(np.diff(rs.time)) + 1
    starts = np.concatenate([[0], bounds])
    stops = np.concatenate([bounds, [rs.time.size]])
    for s0, s1 in zip(starts.tolist(), stops.tolist(), strict=True):
        alerts += det.step(float(rs.time[s0]), rs.track_id[s0:s1], rs.bearing_deg[s0:s1])
    return alerts


# --------------------------------------------------------------------------------------------
# scoring against ground truth
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CrossingScore:
    """Alerts scored against true crossings.

    Attributes
    ----------
    n_crossings : int
        True crossings scored (those with enough data before and after, see
        :func:`score_alerts`).
    n_predicted_ahead : int
        Of those, crossings with a matching ``predicted`` alert raised at least one sample
        period K before the true crossing time.
    n_detected : int
        Crossings with a matching ``detected`` alert raised no later than ``J K`` after it.
    detection_delay_s : ndarray, shape (n_detected,)
        Alert time minus true crossing time of each detected crossing, s.
    n_non_crossing_pairs : int
        Pairs that never cross.
    n_false_pairs : int
        Of those, pairs with at least one alert.
    n_spurious_alerts : int
        Alerts on crossing pairs that match none of the pair's true crossings.
    """

    n_crossings: int
    n_predicted_ahead: int
    n_detected: int
    detection_delay_s: NDArray[np.float64]
    n_non_crossing_pairs: int
    n_false_pairs: int
    n_spurious_alerts: int

    @property
    def predicted_fraction(self) -> float:
        """Fraction of scored crossings predicted at least K ahead (NaN if none scored)."""
        return self.n_predicted_ahead / self.n_crossings if self.n_crossings else float("nan")

    @property
    def detected_fraction(self) -> float:
        """Fraction of scored crossings detected within J K (NaN if none scored)."""
        return self.n_detected / self.n_crossings if self.n_crossings else float("nan")

    @property
    def false_pair_fraction(self) -> float:
        """Fraction of never-crossing pairs with an alert (NaN if there are none)."""
        if not self.n_non_crossing_pairs:
            return float("nan")
        return self.n_false_pairs / self.n_non_crossing_pairs


def score_alerts(
    alerts: list[CrossingAlert],
    crossings: list[tuple[int, int, float]],
    non_crossing_pairs: list[tuple[int, int]],
    *,
    J: int,
    K: float,
    t_start: float,
    t_end: float,
    match_tol_s: float | None = None,
) -> CrossingScore:
    """Score alerts against true crossings.

    Parameters
    ----------
    alerts : list of CrossingAlert
        Output of the detector.
    crossings : list of (int, int, float)
        True crossings ``(track_a, track_b, t_cross)``, ``track_a < track_b``.
    non_crossing_pairs : list of (int, int)
        Pairs that never cross.
    J : int
        Samples per window.
    K : float
        Sample period, s.
    t_start, t_end : float
        First and last sample time, s.
    match_tol_s : float, optional
        An alert belongs to the pair's true crossing nearest its ``t_cross`` if within this
        (default ``J K``).

    Returns
    -------
    CrossingScore

    Notes
    -----
    A crossing is scored when ``t_start + (J + 1) K <= t_c <= t_end - J K``: a full window
    exists one sample before it and a full window of samples follows it.
    """
    tol = J * K if match_tol_s is None else float(match_tol_s)
    by_pair: dict[tuple[int, int], list[float]] = {}
    for a, b, tc in crossings:
        by_pair.setdefault((min(a, b), max(a, b)), []).append(float(tc))
    pred_time: dict[tuple[int, int, int], float] = {}
    det_time: dict[tuple[int, int, int], float] = {}
    spurious = 0
    alerted_pairs = set()
    for al in alerts:
        key = (al.track_a, al.track_b)
        alerted_pairs.add(key)
        tcs = by_pair.get(key)
        if not tcs:
            continue
        j = int(np.argmin([abs(al.t_cross - tc) for tc in tcs]))
        if abs(al.t_cross - tcs[j]) > tol:
            spurious += 1
            continue
        slot = pred_time if al.kind == AlertKind.PREDICTED else det_time
        k3 = (key[0], key[1], j)
        slot[k3] = min(slot.get(k3, np.inf), al.time)
    n = n_pred = n_det = 0
    delays = []
    for key, tcs in by_pair.items():
        for j, tc in enumerate(tcs):
            if not (t_start + (J + 1) * K <= tc <= t_end - J * K):
                continue
            n += 1
            if pred_time.get((*key, j), np.inf) <= tc - K:
                n_pred += 1
            dt = det_time.get((*key, j), np.inf)
            if dt <= tc + J * K:
                n_det += 1
                delays.append(dt - tc)
    ncp = {(min(a, b), max(a, b)) for a, b in non_crossing_pairs}
    return CrossingScore(
        n_crossings=n,
        n_predicted_ahead=n_pred,
        n_detected=n_det,
        detection_delay_s=np.array(delays, dtype=float),
        n_non_crossing_pairs=len(ncp),
        n_false_pairs=len(ncp & alerted_pairs),
        n_spurious_alerts=spurious,
    )
