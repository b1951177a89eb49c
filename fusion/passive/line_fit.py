"""Recursive least-squares lines over sliding windows, for many tracks at once.

The regression routine (104A) of *Target Track Crossing Prediction/Detection*: each track's bearing
rate and bearing intercept from a least-squares line over its most recent J samples, updated in
O(1) per track per sample from running sums, with the covariance of the fit from the window's
residuals (:meth:`SlidingLineFit.stats`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["LineStats", "SlidingLineFit"]

_TWO_PI = 2.0 * np.pi


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Wrap radians to ``[-pi, pi)`` (same convention as :func:`fusion.geometry.wrap_angle`)."""
    return np.mod(a + np.pi, _TWO_PI) - np.pi


@dataclass(frozen=True)
class LineStats:
    """Window lines of several tracks evaluated at one time, with their covariance.

    Attributes
    ----------
    value : ndarray, shape (n,)
        Fitted value at the evaluation time (rad for bearings, unwrapped).
    slope : ndarray, shape (n,)
        Fitted slope ``B'``, per second.
    n : ndarray of int64, shape (n,)
        Samples in each window.
    residual_var : ndarray, shape (n,)
        Residual variance ``s^2 = RSS / (n - 2)`` (NaN below 3 samples).
    var_value : ndarray, shape (n,)
        Variance of `value`.
    var_slope : ndarray, shape (n,)
        Variance of `slope`, per s^2.
    cov : ndarray, shape (n,)
        Covariance of `value` and `slope`, per s.
    """

    value: NDArray[np.float64]
    slope: NDArray[np.float64]
    n: NDArray[np.int64]
    residual_var: NDArray[np.float64]
    var_value: NDArray[np.float64]
    var_slope: NDArray[np.float64]
    cov: NDArray[np.float64]


class SlidingLineFit:
    """Least-squares lines ``y = B0 + B' t`` over the most recent J samples of many tracks.

    The fit is recursive: each track keeps the running sums ``n, S_t, S_y, S_tt, S_ty, S_yy`` of its
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
        self._s = np.zeros((5, cap))  # S_t, S_y, S_tt, S_ty, S_yy
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

    def _known(self, track_ids: ArrayLike) -> NDArray[np.int64]:
        """Storage slots of `track_ids`, all known (else :class:`ValueError` naming some)."""
        s = self.slots(track_ids)
        if np.any(s < 0):
            unknown = np.asarray(track_ids)[s < 0]
            raise ValueError(f"unknown track id(s) {unknown.tolist()[:5]}")
        return s

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
            self._s[4, sf] -= yo * yo
        self._s[0, s] += x
        self._s[1, s] += y
        self._s[2, s] += x * x
        self._s[3, s] += x * y
        self._s[4, s] += y * y
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
        self._s[4, s] = (yy * yy).sum(axis=1)
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
        s = self._known(track_ids)
        icpt, slope = self._coeffs(s)
        return icpt + slope * (float(time) - self._t0[s]), slope, self._n[s].copy()

    def stats(self, track_ids: ArrayLike, time: float) -> LineStats:
        """Each track's window line at `time` with its covariance from the window residuals.

        `track_ids` and `time` as in :meth:`line`.

        Returns
        -------
        LineStats
            Value, slope, sample count, residual variance and the covariance of (value, slope);
            the variances are NaN for windows of fewer than 3 samples.

        Notes
        -----
        Ordinary least squares on the window: with ``n`` samples, ``tbar = S_t / n`` and
        ``S_xx = S_tt - S_t^2 / n``, the residual sum of squares is
        ``RSS = S_yy - S_y^2 / n - B'^2 S_xx`` and the residual variance ``s^2 = RSS / (n - 2)``.
        The fitted value at ``t`` and the slope have variances ``s^2 (1/n + (t - tbar)^2 / S_xx)``
        and ``s^2 / S_xx`` and covariance ``s^2 (t - tbar) / S_xx``.
        """
        s = self._known(track_ids)
        icpt, slope = self._coeffs(s)
        n = self._n[s].astype(float)
        st, sy, stt, syy = self._s[0, s], self._s[1, s], self._s[2, s], self._s[4, s]
        nn = np.maximum(n, 1.0)
        sxx = stt - st * st / nn  # S_xx
        ok = (n >= 3) & (sxx > 0)
        rss = np.maximum(syy - sy * sy / nn - slope * slope * sxx, 0.0)
        var = np.where(ok, rss / np.maximum(n - 2.0, 1.0), np.nan)  # s^2
        x = float(time) - self._t0[s]
        dx = x - st / nn  # t - tbar
        sxx_ok = np.where(ok, sxx, np.nan)
        return LineStats(
            value=icpt + slope * x,
            slope=slope,
            n=self._n[s].copy(),
            residual_var=var,
            var_value=var * (1.0 / nn + dx * dx / sxx_ok),
            var_slope=var / sxx_ok,
            cov=var * dx / sxx_ok,
        )

    def window_samples(self, track_id: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Times (s, absolute) and unwrapped values of one track's window, oldest first."""
        s = int(self.slots([track_id])[0])
        if s < 0:
            raise ValueError(f"unknown track id {track_id}")
        n, h, J = int(self._n[s]), int(self._head[s]), self.window
        idx = (h - n + np.arange(n)) % J
        return self._bt[s, idx] + self._t0[s], self._by[s, idx].copy()

    def windows(
        self, track_ids: ArrayLike, time: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """Every window of `track_ids` at once, times relative to `time` (unordered).

        Returns
        -------
        tau : ndarray, shape (n, J)
            Sample time minus `time`, s (0 where `valid` is False).
        value : ndarray, shape (n, J)
            Unwrapped values on the branch of :meth:`stats` (0 where not valid).
        valid : ndarray of bool, shape (n, J)
            Entries holding a sample.
        """
        s = self._known(track_ids)
        v = self._bv[s].copy()
        tau = np.where(v, self._bt[s] + (self._t0[s] - float(time))[:, None], 0.0)
        return tau, np.where(v, self._by[s], 0.0), v
