"""Curved bearing tracks: a constant-velocity bearing curve chosen by an F-test, and crossings.

The method text fits a straight line over each track's window (regression routine 104A) and
allows other regressions ("polynomial curve fitting ..., approximating functions"). A contact in
straight-line motion relative to the sensor has a curved bearing history (the rate is
``h / R(t)^2``): near a close pass the bearing sweeps fast and the straight line predicts
crossings with tracks far away. Here each window also gets the bearing curve of a
constant-velocity contact, ``atan2(x0 + vx t, y0 + vy t)`` (three free parameters; pseudo-linear
start, Gauss-Newton steps), kept only when the data ask for it: the F-test of the curve against
the line at level `alpha`. A pair with at least one curved track crosses where the difference
of its two fits changes sign nearest the current sample, with the interval of times at which
the fitted difference is within ``q`` standard deviations of zero (Fieller's interval for two
lines, on a grid for curves), from the fits' own covariance.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from fusion.passive.line_fit import LineStats

__all__ = ["CurveStats", "curve_fits", "curved_candidates", "curved_pair_intervals", "f_quantile"]

_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class CurveStats:
    """Window fits of several tracks at one time: a line, or a constant-velocity bearing curve.

    Attributes
    ----------
    value, slope : ndarray, shape (n,)
        The lines (:class:`~fusion.passive.line_fit.LineStats`): bearing at the sample (rad,
        unwrapped) and rate (rad/s).
    line : LineStats
        The lines with their covariance.
    p : ndarray, shape (n, 4)
        Constant-velocity relative track ``(x0, vx, y0, vy)`` up to scale, times in units of
        `scale` from the sample: the bearing is ``atan2(x0 + vx u, y0 + vy u)``.
    cov : ndarray, shape (n, 4, 4)
        Covariance of `p` (rank 3: the scale is not observable).
    scale : ndarray, shape (n,)
        Time unit of `p`, s (the window's span).
    dof : ndarray, shape (n,)
        Residual degrees of freedom of the model kept (``n - 2`` or ``n - 3``).
    residual_var : ndarray, shape (n,)
        Residual variance of the model kept, rad^2.
    curved : ndarray of bool, shape (n,)
        Whether the F-test kept the curve.
    """

    line: LineStats
    p: NDArray[np.float64]
    cov: NDArray[np.float64]
    scale: NDArray[np.float64]
    dof: NDArray[np.float64]
    residual_var: NDArray[np.float64]
    curved: NDArray[np.bool_]

    def subset(self, index: NDArray[np.int64]) -> CurveStats:
        """The rows `index` of every array."""
        ln = self.line
        line = LineStats(*(getattr(ln, f)[index] for f in (
            "value", "slope", "n", "residual_var", "var_value", "var_slope", "cov")))
        return CurveStats(line, self.p[index], self.cov[index], self.scale[index],
                          self.dof[index], self.residual_var[index], self.curved[index])

    def bearing(self, index: NDArray[np.int64], tau: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Bearing (rad, wrapped) and its variance at times `tau` (s, shape (p, m)) of rows `index`.

        Straight rows give their line (``value + slope tau``) with the line's variance.
        """
        ln = self.line
        v, r = ln.value[index][:, None], ln.slope[index][:, None]
        b_line = v + r * tau
        var_line = (ln.var_value[index][:, None] + 2.0 * tau * ln.cov[index][:, None]
                    + tau * tau * ln.var_slope[index][:, None])
        c = np.flatnonzero(self.curved[index])  # only these rows need the curve
        if c.size == 0:
            return b_line, var_line
        ic = index[c]
        tc = tau[c] if tau.shape[0] == index.size else np.broadcast_to(tau, b_line.shape)[c]
        u = tc / self.scale[ic][:, None]
        p = self.p[ic]
        x = p[:, 0:1] + p[:, 1:2] * u
        y = p[:, 2:3] + p[:, 3:4] * u
        r2 = np.maximum(x * x + y * y, 1e-300)
        g = np.stack([y, y * u, -x, -x * u], axis=-1) / r2[..., None]  # d bearing / d p
        var_cv = np.einsum("pmi,pij,pmj->pm", g, self.cov[ic], g)
        b_cv = np.arctan2(x, y)
        # the curve on the line's branch at tau = 0
        b_cv = b_line[c] + _wrap(b_cv - b_line[c])
        b_out, var_out = b_line.copy(), var_line.copy()
        b_out[c], var_out[c] = b_cv, var_cv
        return b_out, var_out


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.mod(a + np.pi, _TWO_PI) - np.pi


@lru_cache(maxsize=32)
def _f_table(alpha: float) -> NDArray[np.float64]:
    # imported here: scipy.stats costs ~0.8 s CPU to import, and most users of the crossing
    # package (fusion smooth among them) never need a quantile
    from scipy import stats as _stats

    d = np.arange(1, 2001, dtype=float)
    return np.concatenate([[np.inf], _stats.f.isf(alpha, 1.0, d)])


def f_quantile(alpha: float, dof: NDArray[np.float64]) -> NDArray[np.float64]:
    """Upper `alpha` quantile of F(1, dof) (dof rounded down, at most 2000; inf below 1)."""
    d = np.clip(np.floor(np.nan_to_num(dof, nan=0.0)), 0, 2000).astype(np.int64)
    return _f_table(float(alpha))[d]


def _cv_jacobian(p: NDArray[np.float64], u: NDArray[np.float64]
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    x = p[:, 0:1] + p[:, 1:2] * u
    y = p[:, 2:3] + p[:, 3:4] * u
    r2 = np.maximum(x * x + y * y, 1e-300)
    g = np.stack([y, y * u, -x, -x * u], axis=-1) / r2[..., None]
    return np.arctan2(x, y), g


def _free_scale(gg: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """``G^T G + c p p^T`` (``c`` its mean eigenvalue, a ridge of 1e-12 c): invertible.

    The bearing does not change along `p` (a unit vector; ``G p = 0``), so ``p`` spans the
    null space of ``G^T G`` and is an eigenvector of the sum, which then solves the
    minimum-norm Gauss-Newton step for any right-hand side ``G^T r`` (orthogonal to ``p``)
    and gives ``(G^T G)^+ = M^-1 - p p^T / c`` without an eigendecomposition.
    """
    c = np.maximum(np.einsum("nii->n", gg) / 4.0, 1e-300)[:, None, None]
    return gg + c * (p[:, :, None] * p[:, None, :]) + 1e-12 * c * np.eye(4)


def curve_fits(
    tau: NDArray[np.float64],
    value: NDArray[np.float64],
    valid: NDArray[np.bool_],
    line: LineStats,
    *,
    alpha: float,
    iterations: int = 3,
) -> CurveStats:
    """Constant-velocity bearing curves of the windows, kept where an F-test finds them better.

    Parameters
    ----------
    tau, value, valid : ndarray, shape (n, J)
        The windows (:meth:`fusion.passive.line_fit.SlidingLineFit.windows`): times from the
        current sample, s, unwrapped bearings, rad, and which entries hold a sample.
    line : LineStats
        The same windows' lines at the current sample (value, slope, covariance).
    alpha : float
        Level of the F-test of the curve against the line (smaller keeps fewer curves).
    iterations : int, optional
        Gauss-Newton steps after the pseudo-linear start (default 3).

    Returns
    -------
    CurveStats

    Notes
    -----
    A contact in straight-line motion relative to the sensor has the relative position
    ``(x0 + vx t, y0 + vy t)`` and the bearing ``atan2(x0 + vx t, y0 + vy t)``: a curve of
    three free parameters (the scale of the position is not observable). Each sample gives
    ``(x0 + vx t) cos B - (y0 + vy t) sin B = 0``, linear in ``p = (x0, vx, y0, vy)``: the
    pseudo-linear estimate is the eigenvector of the smallest eigenvalue of ``A^T A``. A few
    Gauss-Newton steps on the bearing residuals follow (the pseudo-linear estimate is biased),
    with the minimum-norm step (the scale direction is free). The covariance is
    ``s^2 (G^T G)^+`` with ``G`` the bearing's Jacobian and ``s^2 = RSS / (n - 3)``. The curve
    replaces the line when ``F = (RSS_line - RSS_cv) / (RSS_cv / (n - 3))`` exceeds the upper
    `alpha` quantile of ``F(1, n - 3)``.
    """
    n_tr = tau.shape[0]
    w = valid.astype(float)
    n = w.sum(axis=1)
    scale = np.maximum(np.max(np.abs(tau) * w, axis=1), 1e-9)
    u = tau / scale[:, None]
    cb, sb = np.cos(value), np.sin(value)
    a = np.stack([cb, cb * u, -sb, -sb * u], axis=-1) * w[..., None]
    m = np.einsum("nji,njk->nik", a, a)
    _, vecs = np.linalg.eigh(m)
    p = vecs[:, :, 0]
    b0, _ = _cv_jacobian(p, np.zeros((n_tr, 1)))
    flip = np.abs(_wrap(b0[:, 0] - line.value)) > np.pi / 2  # the other end of the line of sight
    p = np.where(flip[:, None], -p, p)
    for _ in range(iterations):
        b, g = _cv_jacobian(p, u)
        r = _wrap(value - b) * w
        g = g * w[..., None]
        gg = np.einsum("nji,njk->nik", g, g)
        step = np.linalg.solve(_free_scale(gg, p), np.einsum("nji,nj->ni", g, r)[..., None])
        p = p + step[..., 0]
        p = p / np.maximum(np.linalg.norm(p, axis=1, keepdims=True), 1e-300)
    b, g = _cv_jacobian(p, u)
    rss_cv = ((_wrap(value - b) * w) ** 2).sum(axis=1)
    rss_line = np.nan_to_num(line.residual_var * (n - 2.0), nan=0.0)
    dof = np.maximum(n - 3.0, 1.0)
    s2 = rss_cv / dof
    g = g * w[..., None]
    gg = np.einsum("nji,njk->nik", g, g)
    m_free = _free_scale(gg, p)
    pp = p[:, :, None] * p[:, None, :] / np.einsum("nii->n", m_free - gg)[:, None, None]
    cov = s2[:, None, None] * (np.linalg.inv(m_free) - pp)  # (G^T G)^+: p spans its null space
    with np.errstate(divide="ignore", invalid="ignore"):
        f_stat = (rss_line - rss_cv) / s2
    ok = (n >= 6) & np.all(np.isfinite(p), axis=1)
    curved = ok & (((rss_cv > 0) & (f_stat > f_quantile(alpha, n - 3.0)))
                   | ((rss_cv <= 0) & (rss_line > 0)))
    return CurveStats(line=line, p=p, cov=cov, scale=scale,
                      dof=np.where(curved, n - 3.0, n - 2.0),
                      residual_var=np.where(curved, s2, line.residual_var), curved=curved)


def curved_pair_intervals(
    index_a: NDArray[np.int64],
    index_b: NDArray[np.int64],
    cs: CurveStats,
    *,
    q: NDArray[np.float64] | float,
    reach_s: float,
    back_s: float,
    n_grid: int = 129,
    ahead_var_scale: float = 1.0,
    ahead_var: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_],
           NDArray[np.float64]]:
    """Crossing time, interval and direction of pairs of window curves.

    Parameters
    ----------
    index_a, index_b : ndarray of int64, shape (p,)
        The pairs (rows of `cs`).
    cs : CurveStats
        The tracks' window fits.
    q : float or ndarray, shape (p,)
        Quantile of the interval.
    reach_s, back_s : float
        Crossings are looked for in ``[-back_s, reach_s]`` (s from the current sample).
    n_grid : int, optional
        Points of the time grid the curves are evaluated on.
    ahead_var_scale : float, optional
        Factor on the difference's variance ahead of the sample (default 1; the extrapolation
        factor of :class:`~fusion.passive.crossing.calibration.ExtrapolationScale`).
    ahead_var : callable, optional
        ``ahead_var(tau)`` (`tau` shape (p, n_grid), s) is a variance (rad^2) added to the
        difference's ahead of the sample (the manoeuvre allowance of
        :mod:`fusion.passive.crossing.manoeuvre`; default None: the fits' covariance only).
        On the grid it is taken at every point, so both ends of the interval use their own.

    Returns
    -------
    tau, low, high : ndarray, shape (p,)
        The crossing nearest the current sample within the range and its interval, s from the
        sample (NaN where there is none).
    bounded : ndarray of bool, shape (p,)
        Whether a crossing exists and its interval ends inside the range.
    direction : ndarray, shape (p,)
        Sign of the difference's change through the crossing (+1: track b passes track a
        going clockwise).

    Notes
    -----
    The difference ``d(tau) = B_b(tau) - B_a(tau)`` (wrapped) and its variance (the sum of the
    two fits' delta-method variances) are evaluated on a grid; the crossing is the sign change
    of ``d`` (with ``|d| < 90 deg``, not the jump at the far side of the circle) nearest the
    sample, refined linearly; the interval is the connected set around it where
    ``d^2 <= q^2 var d`` -- Fieller's interval for lines, evaluated on the grid for curves --
    with its ends refined linearly. An interval that reaches an end of the range is not
    bounded: the data do not place the crossing.
    """
    p = index_a.size
    grid = np.linspace(-back_s, reach_s, n_grid)
    tt = np.broadcast_to(grid, (p, n_grid))
    ba, va = cs.bearing(index_a, tt)
    bb, vb = cs.bearing(index_b, tt)
    d = _wrap(bb - ba)
    var = va + vb
    if ahead_var_scale != 1.0:
        var = np.where(tt > 0, ahead_var_scale * var, var)
    if ahead_var is not None:
        var = var + np.where(tt > 0, ahead_var(tt), 0.0)
    q2 = (np.asarray(q, dtype=float) * np.ones(p))[:, None] ** 2
    gfun = d * d - q2 * var
    sc = (np.sign(d[:, :-1]) != np.sign(d[:, 1:])) & (np.abs(d[:, :-1]) < np.pi / 2) \
        & (np.abs(d[:, 1:]) < np.pi / 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = d[:, :-1] / (d[:, :-1] - d[:, 1:])
    roots = grid[:-1] + frac * (grid[1] - grid[0])
    score = np.where(sc, np.abs(roots), np.inf)
    k = np.argmin(score, axis=1)
    rows = np.arange(p)
    has = np.isfinite(score[rows, k])
    tau = np.where(has, roots[rows, k], np.nan)
    direction = np.where(has, np.sign(d[rows, np.minimum(k + 1, n_grid - 1)] - d[rows, k]), 0.0)
    inside = gfun <= 0
    # the connected run of `inside` around the crossing (the cell k, k + 1 holds it)
    low = np.full(p, np.nan)
    high = np.full(p, np.nan)
    bounded = np.zeros(p, bool)
    idx = np.arange(n_grid)
    for_rows = np.flatnonzero(has)
    if for_rows.size:
        ins = inside[for_rows]
        kk = k[for_rows]
        # make the crossing's own cells inside (d = 0 there)
        ins[np.arange(kk.size), kk] |= np.abs(d[for_rows, kk]) <= np.abs(d[for_rows, kk + 1])
        ins[np.arange(kk.size), kk + 1] |= np.abs(d[for_rows, kk + 1]) < np.abs(d[for_rows, kk])
        c = np.where(ins[np.arange(kk.size), kk], kk, kk + 1)
        out_left = np.where(~ins & (idx[None, :] < c[:, None]), idx[None, :], -1).max(axis=1)
        out_right = np.where(~ins & (idx[None, :] > c[:, None]), idx[None, :], n_grid).min(axis=1)
        ok = (out_left >= 0) & (out_right < n_grid)
        gl = gfun[for_rows]
        r_ = np.arange(kk.size)
        lo_i = np.clip(out_left, 0, n_grid - 2)
        hi_i = np.clip(out_right, 1, n_grid - 1)
        with np.errstate(invalid="ignore", divide="ignore"):
            fl = gl[r_, lo_i] / (gl[r_, lo_i] - gl[r_, lo_i + 1])
            fh = gl[r_, hi_i - 1] / (gl[r_, hi_i - 1] - gl[r_, hi_i])
        step = grid[1] - grid[0]
        low[for_rows] = grid[lo_i] + np.clip(np.nan_to_num(fl), 0, 1) * step
        high[for_rows] = grid[hi_i - 1] + np.clip(np.nan_to_num(fh), 0, 1) * step
        bounded[for_rows] = ok
    low = np.minimum(low, tau)
    high = np.maximum(high, tau)
    return tau, low, high, bounded, direction


def curved_candidates(
    cs: CurveStats, *, reach_s: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Pairs (i < j) with a curved track whose bearings can meet within `reach_s` either way.

    A pair is kept when the bearing ranges of its two fits over ``[-R, R]`` (R = `reach_s`)
    overlap on the circle (a constant-velocity bearing is monotonic, so its range is that of
    the end points).
    """
    cur = np.flatnonzero(cs.curved)
    n = cs.curved.size
    if cur.size == 0 or n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    r = float(reach_s)
    ends = np.broadcast_to(np.linspace(-r, r, 9), (n, 9))
    b, _ = cs.bearing(np.arange(n), ends)
    b = np.unwrap(b, axis=1)  # a constant-velocity bearing is monotonic: no extreme inside
    lo, hi = b.min(axis=1), b.max(axis=1)  # range of each track's bearing over [-R, R]
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    i = np.repeat(cur, n)
    j = np.tile(np.arange(n), cur.size)
    keep = i != j
    i, j = i[keep], j[keep]
    keep = np.abs(_wrap(mid[j] - mid[i])) <= half[i] + half[j] + 1e-12
    a, bb = np.minimum(i[keep], j[keep]), np.maximum(i[keep], j[keep])
    key = np.unique(a * n + bb)
    return key // n, key % n
