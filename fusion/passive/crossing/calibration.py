"""How far ahead a window's fit can be trusted, measured on the bearings themselves.

A crossing is predicted by extrapolating each track's window fit up to half a window ahead; the
fit's covariance counts the noise of the samples, not the turns, speed changes and curvature it
does not model, so on manoeuvring traffic the intervals of predictions hold the crossing less
often than their level says. The data can say by how much: every track's window of a while ago
predicted the samples that came since. :func:`holdout_errors` gives, per track, the errors of
the line fitted to the J samples that ended `ahead` samples ago on the `ahead` samples since,
with the line's prediction variance and residual variance; :class:`ExtrapolationScale` pools
them over the tracks and the recent past and finds the factor ``k`` by which the prediction
variance must grow for the errors to fall inside their nominal interval as often as the level
says.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fusion.passive.crossing.interval import t_quantile

__all__ = ["ExtrapolationScale", "holdout_errors"]


def holdout_errors(
    tau: NDArray[np.float64],
    value: NDArray[np.float64],
    valid: NDArray[np.bool_],
    *,
    J: int,
    K: float,
    ahead: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Errors of each track's earlier window line on the samples that came after it.

    Parameters
    ----------
    tau, value, valid : ndarray, shape (n, m)
        Each track's recent samples (:meth:`fusion.passive.line_fit.SlidingLineFit.windows` of
        a window of at least ``J + ahead`` samples): times from the current sample, s (on the
        grid of period `K`), unwrapped bearings, rad, and which entries hold a sample.
    J : int
        Samples of the earlier window.
    K : float
        Grid period, s.
    ahead : int
        Samples since that window ended (>= 1).

    Returns
    -------
    err2 : ndarray, shape (p,)
        Squared errors ``(y - yhat)^2`` of the later samples, rad^2.
    var_pred : ndarray, shape (p,)
        Variance of the line's value at those samples, ``s^2 (1/n + (t - tbar)^2 / S_xx)``.
    var_res : ndarray, shape (p,)
        The line's residual variance ``s^2``.
    dof : ndarray, shape (p,)
        Its degrees of freedom ``n - 2``.

    Notes
    -----
    Only tracks whose earlier window holds all J samples count. Under the line's model the
    standardized error ``(y - yhat) / sqrt(var_pred + s^2)`` is Student-t with ``n - 2``
    degrees of freedom (the prediction interval of a new observation).
    """
    lag = -(ahead - 0.5) * K  # later samples: tau > lag
    old = valid & (tau < lag) & (tau > lag - J * K)
    new = valid & (tau >= lag)
    w = old.astype(float)
    n = w.sum(axis=1)
    nn = np.maximum(n, 1.0)
    tb = (w * tau).sum(axis=1) / nn
    yb = (w * value).sum(axis=1) / nn
    dt = (tau - tb[:, None]) * w
    dy = (value - yb[:, None]) * w
    sxx = (dt * dt).sum(axis=1)
    full = (n >= J) & (sxx > 0)
    sxx_ok = np.where(full, sxx, 1.0)
    slope = (dt * dy).sum(axis=1) / sxx_ok
    res = dy - slope[:, None] * dt
    s2 = (res * res).sum(axis=1) / np.maximum(n - 2.0, 1.0)
    use = new & full[:, None]
    rows, cols = np.nonzero(use)
    x = tau[rows, cols] - tb[rows]
    yhat = yb[rows] + slope[rows] * x
    err2 = (value[rows, cols] - yhat) ** 2
    var_pred = s2[rows] * (1.0 / nn[rows] + x * x / sxx_ok[rows])
    return err2, var_pred, s2[rows], n[rows] - 2.0


class ExtrapolationScale:
    """Pooled factor by which extrapolated fits' variances must grow to hold their level.

    Parameters
    ----------
    level : float
        Level of the intervals to calibrate (their errors are compared with the Student-t
        quantile at this level; at most 0.99 is used -- the tail beyond is too thin to count).
    memory : int, optional
        Held-out errors kept (the most recent), pooled over tracks and samples (default 4000).

    Notes
    -----
    With the errors of :func:`holdout_errors`, ``k`` is the smallest factor >= 1 for which the
    fraction of errors with ``|y - yhat| <= q sqrt(k var_pred + s^2)`` (``q`` the Student-t
    quantile of each error's degrees of freedom) reaches the level; found by bisection on
    ``log k`` (the fraction grows with ``k``). The observation noise ``s^2`` is not scaled: the
    crossing is a property of the lines, not of the next sample, so it is the lines'
    extrapolation variance that the intervals of predictions multiply by ``k``.
    """

    def __init__(self, level: float, *, memory: int = 4000) -> None:
        self.level = min(float(level), 0.99)
        self.memory = int(memory)
        self.reset()

    def reset(self) -> None:
        """Forget every error."""
        self._e2 = np.zeros(0)
        self._vp = np.zeros(0)
        self._s2 = np.zeros(0)
        self._q2 = np.zeros(0)
        self.k = 1.0

    def add(self, err2: NDArray[np.float64], var_pred: NDArray[np.float64],
            var_res: NDArray[np.float64], dof: NDArray[np.float64]) -> float:
        """Add held-out errors, update and return ``k``."""
        if err2.size:
            q2 = t_quantile(self.level, dof) ** 2
            m = self.memory
            self._e2 = np.concatenate([self._e2, err2])[-m:]
            self._vp = np.concatenate([self._vp, var_pred])[-m:]
            self._s2 = np.concatenate([self._s2, var_res])[-m:]
            self._q2 = np.concatenate([self._q2, q2])[-m:]
            self.k = self._solve()
        return self.k

    def _inside(self, k: float) -> float:
        return float(np.mean(self._e2 <= self._q2 * (k * self._vp + self._s2)))

    def _solve(self) -> float:
        if self._e2.size < 50 or self._inside(1.0) >= self.level:
            return 1.0
        lo, hi = 0.0, np.log(1e6)
        if self._inside(np.exp(hi)) < self.level:
            return float(np.exp(hi))
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            if self._inside(np.exp(mid)) >= self.level:
                hi = mid
            else:
                lo = mid
        return float(np.exp(hi))
