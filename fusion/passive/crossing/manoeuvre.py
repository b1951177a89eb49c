"""Manoeuvre allowance of crossing predictions: a bearing rate that wanders, its intensity
estimated from the data.

A window's line says nothing of the turns and speed changes that come after it, nor of those
inside it that the line averages over. The allowance models each track's bearing rate as
``r(t) = r_0 + sqrt(q) W(t)`` (``W`` a Wiener process, ``q`` in rad^2/s^3, each track's own
intensity) and adds to the variance of a pair's difference line at a predicted crossing
the mean squared miss of the two window lines there.

**The miss of a window line** (window span ``T`` ending at the sample, uniform samples, least
squares): the true bearing at ``tau`` ahead minus the line's extrapolation is a linear
functional ``int G(u) dW(u)`` of the rate's increments, so its variance is
``q T^3 phi(tau / T)`` with ``phi(x) = x^3 / 3 + A x^2 + 2 B x + C``: ``x^3 / 3`` is the
increments after the sample (the integrated random walk), ``A``, ``B``, ``C`` those inside the
window the line smooths over (:func:`miss_constants`, computed once by quadrature).

**The intensity from the data** (method of moments, causal): at every sample, the window of
``2 J`` samples of each track is split into its older and its newer ``J`` samples and a line is
fitted to each half. With a wandering rate their slope difference has
``E[(r_new - r_old)^2] = c q T + var r_new + var r_old`` (``T = J K``, ``c`` by the same
quadrature, :func:`miss_constants`; the variances from each half's residuals), so each track's
``q = max(0, sum((r_new - r_old)^2 - var_new - var_old)) / (c T n)`` over its samples, the older
ones forgotten exponentially (:class:`ManoeuvreIntensity`). Straight tracks give ``q`` near 0
and the allowance vanishes; a track that turns gets the intensity its turns have. Geometric
curvature of constant-velocity contacts also enters ``q`` (it changes the rate too); the curvature allowance
(:mod:`fusion.passive.crossing.curvature`) covers the part a window shows.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

__all__ = ["ManoeuvreIntensity", "half_window_slopes", "manoeuvre_variance", "miss_constants"]


@lru_cache(maxsize=1)
def miss_constants(m: int = 2000) -> tuple[float, float, float, float]:
    """``(A, B, C, c)`` of :mod:`fusion.passive.crossing.manoeuvre` for a unit window.

    For a unit increment of the rate at ``u`` the bearing gains ``(s - u)_+``; the line fitted to
    that over the window ``[-1, 0]`` is ``a_u + b_u s``. The miss at ``x`` is then
    ``G(u) = (1 - b_u) x - u - a_u`` for ``u`` in the window (and ``x - u`` after it), giving
    ``A = int (1 - b_u)^2``, ``B = int (1 - b_u)(-u - a_u)``, ``C = int (u + a_u)^2`` over
    ``[-1, 0]``. The slope difference of the windows ``[-1, 0]`` and ``[-2, -1]`` is
    ``int (b2_u - b1_u) dW(u)``: ``c = int (b2_u - b1_u)^2`` over ``[-2, 0]``. Midpoint rule on
    `m` points per unit.
    """
    s = (np.arange(m) + 0.5) / m - 1.0  # the window [-1, 0]
    X = np.column_stack([np.ones(m), s])
    P = np.linalg.pinv(X)  # (2, m): line coefficients of any function sampled on s
    u = s  # increments inside the window
    f = np.maximum(s[None, :] - u[:, None], 0.0)  # (u, s)
    coef = f @ P.T  # (u, 2): a_u, b_u
    a, b = coef[:, 0], coef[:, 1]
    du = 1.0 / m
    A = float(np.sum((1 - b) ** 2) * du)
    B = float(np.sum((1 - b) * (-u - a)) * du)
    C = float(np.sum((u + a) ** 2) * du)
    # slope difference of adjacent windows: increments in [-2, -1] move the newer window's slope
    # by 1 and the older one's by the fit of (s' - u)_+ on [-2, -1]
    b_old = b  # the same function shifted by one window
    c = float((np.sum((1.0 - b_old) ** 2) + np.sum(b ** 2)) * du)
    return A, B, C, c


def manoeuvre_variance(q: NDArray[np.float64] | float, span_s: float, tau: NDArray[np.float64]
                       ) -> NDArray[np.float64]:
    """Mean squared miss (rad^2) of a window line of span `span_s` at `tau` ahead.

    ``q T^3 phi(tau / T)`` (`q` one intensity or one per entry of `tau`); 0 where `tau` is not
    finite or not ahead.
    """
    A, B, C, _ = miss_constants()
    T = float(span_s)
    ahead = np.isfinite(tau) & (tau > 0)
    x = np.where(ahead, tau, 0.0) / T
    return np.where(ahead, q * T ** 3 * (x ** 3 / 3.0 + A * x * x + 2.0 * B * x + C), 0.0)


def half_window_slopes(
    tau: NDArray[np.float64], value: NDArray[np.float64], valid: NDArray[np.bool_], half_s: float,
    min_samples: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Squared slope difference of the older and newer halves of each window, and the sum of the
    two slopes' variances (from each half's residuals).

    Parameters
    ----------
    tau, value, valid : ndarray, shape (n, W)
        The windows (:meth:`~fusion.passive.line_fit.SlidingLineFit.windows`).
    half_s : float
        Samples with ``tau > -half_s`` are the newer half.
    min_samples : int
        Each half needs this many samples (at least 3).

    Returns
    -------
    d2, var_sum : ndarray, shape (n,)
    ok : ndarray of bool, shape (n,)
    """
    newer = valid & (tau > -half_s)
    slopes, variances, oks = [], [], []
    for m in (newer, valid & ~newer):
        w = m.astype(float)
        n = w.sum(axis=1)
        nn = np.maximum(n, 1.0)
        tm = (w * tau).sum(axis=1) / nn
        ym = (w * value).sum(axis=1) / nn
        dt = np.where(m, tau - tm[:, None], 0.0)
        dy = np.where(m, value - ym[:, None], 0.0)
        sxx = (dt * dt).sum(axis=1)
        ok = (n >= max(3, min_samples)) & (sxx > 0)
        sxx = np.where(ok, sxx, 1.0)
        b = (dt * dy).sum(axis=1) / sxx
        rss = ((dy - b[:, None] * dt) ** 2).sum(axis=1)
        slopes.append(b)
        variances.append(rss / np.maximum(n - 2.0, 1.0) / sxx)
        oks.append(ok)
    return (slopes[0] - slopes[1]) ** 2, variances[0] + variances[1], oks[0] & oks[1]


class ManoeuvreIntensity:
    """Running estimate of each track's rate-wander intensity ``q`` (rad^2/s^3).

    Each track keeps exponentially forgotten sums (memory `memory_s`) of ``d2 - var_sum`` and of
    ``c T`` (:func:`half_window_slopes`); its ``q`` is ``scale max(0, excess) / weight``.
    A track's own history, not a pool: a few vessels passing close to the sensor turn their
    bearings fast, and a pooled intensity would give every other track their wander.

    Parameters
    ----------
    scale : float
        Factor on the estimates.
    memory_s : float
        Time constant of the forgetting, s.
    period_s : float
        Time between updates, s.
    """

    def __init__(self, scale: float, memory_s: float, period_s: float) -> None:
        self.scale = float(scale)
        self.decay = float(np.exp(-float(period_s) / float(memory_s)))
        self.ids = np.zeros(0, np.int64)
        self.excess = np.zeros(0)
        self.weight = np.zeros(0)

    def _rows(self, ids: NDArray[np.int64]) -> NDArray[np.int64]:
        new = np.setdiff1d(ids, self.ids)
        if new.size:
            allid = np.concatenate([self.ids, new])
            order = np.argsort(allid, kind="stable")
            self.ids = allid[order]
            self.excess = np.concatenate([self.excess, np.zeros(new.size)])[order]
            self.weight = np.concatenate([self.weight, np.zeros(new.size)])[order]
        return np.searchsorted(self.ids, ids)

    def add(self, ids: NDArray[np.int64], d2: NDArray[np.float64], var_sum: NDArray[np.float64],
            ok: NDArray[np.bool_], half_s: float) -> NDArray[np.float64]:
        """Add one sample's half-window slope differences of `ids`; their current ``q``."""
        rows = self._rows(ids)
        self.excess[rows] *= self.decay
        self.weight[rows] *= self.decay
        r = rows[ok]
        self.excess[r] += d2[ok] - var_sum[ok]
        self.weight[r] += miss_constants()[3] * float(half_s)
        w = self.weight[rows]
        return self.scale * np.where(w > 0, np.maximum(self.excess[rows], 0.0)
                                     / np.where(w > 0, w, 1.0), 0.0)
