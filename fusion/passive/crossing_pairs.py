"""Crossing time of every pair of tracks, its confidence interval and the method's inequalities.

Equation (2) of *Target Track Crossing Prediction/Detection* (block 104B), the in-range check
(104C) and inequalities (3) and (4) (104D, 104E), for all pairs of tracks at once on numpy pair
arrays. With the covariance of each track's window fit (:class:`fusion.passive.line_fit.LineStats`)
each crossing time also gets a confidence interval (:func:`crossing_time_interval`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats as _stats

from fusion.passive.crossing_types import PairCheck
from fusion.passive.line_fit import LineStats

__all__ = [
    "PairCheck",
    "crossing_time_interval",
    "evaluate_pairs",
    "pair_intervals",
    "pairs_in_reach",
    "t_quantile",
]

_TWO_PI = 2.0 * np.pi
_MAX_DOF = 1000


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Wrap radians to ``[-pi, pi)`` (same convention as :func:`fusion.geometry.wrap_angle`)."""
    return np.mod(a + np.pi, _TWO_PI) - np.pi


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


@lru_cache(maxsize=8)
def _t_table(level: float) -> NDArray[np.float64]:
    """Two-sided Student-t quantiles at `level` for 0 .. _MAX_DOF degrees of freedom."""
    dof = np.arange(_MAX_DOF + 1, dtype=float)
    q = _stats.t.ppf(0.5 + level / 2.0, np.maximum(dof, 1.0))
    q[-1] = _stats.norm.ppf(0.5 + level / 2.0)  # the last entry stands for many
    return q


def t_quantile(level: float, dof: ArrayLike) -> NDArray[np.float64]:
    """Two-sided Student-t quantile ``t_{(1 + level)/2}(dof)``, with `dof` rounded down.

    Parameters
    ----------
    level : float
        Confidence level in (0, 1).
    dof : array_like
        Degrees of freedom (>= 1; rounded down, so the quantile errs wide; above 1000 the
        normal quantile).

    Returns
    -------
    ndarray
        Quantiles, same shape as `dof`.
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level!r}")
    d = np.clip(np.floor(np.nan_to_num(np.asarray(dof, dtype=float), nan=1.0)), 1, _MAX_DOF)
    return _t_table(float(level))[d.astype(np.int64)]


def crossing_time_interval(
    d0: ArrayLike, d1: ArrayLike, v00: ArrayLike, v01: ArrayLike, v11: ArrayLike, q: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Fieller confidence interval of the root of a fitted line ``d(tau) = d0 + d1 tau``.

    Parameters
    ----------
    d0, d1 : array_like, shape (p,)
        Bearing difference of the two tracks at the current sample (rad) and its rate
        (rad/s): the root ``tau = -d0 / d1`` is the crossing time relative to the sample, s.
    v00, v01, v11 : array_like, shape (p,)
        Variance of `d0`, covariance of `d0` and `d1`, variance of `d1`.
    q : array_like, shape (p,) or scalar
        Quantile of the interval (Student-t or normal).

    Returns
    -------
    low, high : ndarray, shape (p,)
        Interval bounds relative to the sample, s (``-inf``, ``inf`` where unbounded).
    bounded : ndarray of bool, shape (p,)
        Whether the rate difference is resolved (``d1^2 > q^2 v11``): only then is the set
        an interval.

    Notes
    -----
    The interval is the set of ``tau`` at which the fitted difference is within `q` standard
    deviations of zero, ``(d0 + d1 tau)^2 <= q^2 (v00 + 2 tau v01 + tau^2 v11)``: the
    quadratic ``A tau^2 + 2 B tau + C <= 0`` with ``A = d1^2 - q^2 v11``,
    ``B = d0 d1 - q^2 v01`` and ``C = d0^2 - q^2 v00``. Unlike the delta method it stays
    honest when the rate difference is small against its error (the interval then becomes
    wide or unbounded rather than wrong). For noise-free lines it shrinks to the root.

    Examples
    --------
    >>> lo, hi, ok = crossing_time_interval([1.0], [-0.1], [0.0], [0.0], [0.0], 2.0)
    >>> float(lo[0]), float(hi[0]), bool(ok[0])
    (10.0, 10.0, True)
    """
    d0, d1 = np.asarray(d0, dtype=float), np.asarray(d1, dtype=float)
    q2 = np.asarray(q, dtype=float) ** 2
    a = d1 * d1 - q2 * np.asarray(v11, dtype=float)
    b = d0 * d1 - q2 * np.asarray(v01, dtype=float)
    c = d0 * d0 - q2 * np.asarray(v00, dtype=float)
    bounded = a > 0
    root = np.sqrt(np.maximum(b * b - a * c, 0.0))
    a_ok = np.where(bounded, a, 1.0)
    low = np.where(bounded, (-b - root) / a_ok, -np.inf)
    high = np.where(bounded, (-b + root) / a_ok, np.inf)
    return low, high, bounded


def pairs_in_reach(
    bearing_rad: NDArray[np.float64],
    rate_rad_per_s: NDArray[np.float64],
    *,
    reach_s: float,
    min_rate_diff_rad_per_s: float,
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """Pairs whose crossing time is within `reach_s` of the current sample (in-range check).

    Parameters
    ----------
    bearing_rad, rate_rad_per_s : ndarray, shape (n,)
        Fitted bearings at the sample (rad, any wrap) and bearing rates (rad/s).
    reach_s : float
        Largest ``|t_c - t_i|`` kept, s.
    min_rate_diff_rad_per_s : float
        Pairs with ``|B'_a - B'_b|`` at or below this are parallel and dropped.

    Returns
    -------
    index_a, index_b : ndarray of int64, shape (p,)
        The pairs, ``index_a < index_b`` (in the order of the sweep).
    tau : ndarray, shape (p,)
        ``t_c - t_i`` from equation (2), s.
    """
    b = _wrap(bearing_rad)
    r = rate_rad_per_s
    ia, ib = _candidate_pairs(b, r, reach_s)
    num = b[ib] - b[ia]  # B0_b - B0_a at the current sample, in (-2 pi, 2 pi)
    num -= _TWO_PI * (num >= np.pi)
    num += _TWO_PI * (num < -np.pi)  # now wrapped to [-pi, pi)
    den = r[ia] - r[ib]  # B'_a - B'_b
    # 104C in-range check, division-free: |t_c - t_i| <= reach and tracks not parallel.
    keep = np.abs(num) <= reach_s * np.abs(den)
    keep &= np.abs(den) > min_rate_diff_rad_per_s
    k = np.flatnonzero(keep)
    return ia[k], ib[k], num[k] / den[k]  # t_c - t_i, equation (2)


def pair_intervals(
    index_a: NDArray[np.int64],
    index_b: NDArray[np.int64],
    bearing_rad: NDArray[np.float64],
    stats: LineStats,
    *,
    level: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Crossing time and its Fieller interval for given pairs, relative to the current sample.

    Parameters
    ----------
    index_a, index_b : ndarray of int64, shape (p,)
        The pairs (positions in `bearing_rad` and `stats`).
    bearing_rad : ndarray, shape (n,)
        Fitted bearings at the sample, rad (any wrap).
    stats : LineStats
        The tracks' window fits (slopes and covariances), shape (n,) each.
    level : float
        Confidence level of the interval.

    Returns
    -------
    tau, low, high : ndarray, shape (p,)
        ``t_c - t_i`` and the interval bounds, s.
    bounded : ndarray of bool, shape (p,)
        Whether the interval is bounded (rate difference resolved).

    Notes
    -----
    The two tracks' fits are independent, so the difference line ``d = B_b - B_a`` has the
    sums of their covariances. The quantile is Student-t with the Welch-Satterthwaite degrees
    of freedom of the rate difference, ``(v_a + v_b)^2 / (v_a^2 / (n_a - 2) + v_b^2 / (n_b - 2))``.
    """
    b = _wrap(bearing_rad)
    r = stats.slope
    d0 = b[index_b] - b[index_a]
    d0 = d0 - _TWO_PI * (d0 >= np.pi) + _TWO_PI * (d0 < -np.pi)  # wrapped to [-pi, pi)
    d1 = r[index_b] - r[index_a]
    va, vb = stats.var_slope[index_a], stats.var_slope[index_b]
    v11 = va + vb
    dof = _welch_dof(va, vb, stats.n[index_a] - 2.0, stats.n[index_b] - 2.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        tau = np.where(d1 != 0, -d0 / np.where(d1 != 0, d1, 1.0), np.inf)
    q = t_quantile(level, dof)
    low, high, bounded = crossing_time_interval(
        d0, d1, stats.var_value[index_a] + stats.var_value[index_b],
        stats.cov[index_a] + stats.cov[index_b], v11, q)
    bounded &= np.isfinite(low) & np.isfinite(high)
    return tau, low, high, bounded


def _welch_dof(var_a, var_b, dof_a, dof_b):
    """Welch-Satterthwaite degrees of freedom of a sum of two variance estimates."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(var_a + var_b > 0,
                        (var_a + var_b) ** 2 / (var_a * var_a / dof_a + var_b * var_b / dof_b),
                        np.minimum(dof_a, dof_b))


def evaluate_pairs(
    time: float,
    bearing_rad: ArrayLike,
    rate_rad_per_s: ArrayLike,
    *,
    J: int,
    K: float,
    horizon_s: float | None = None,
    min_rate_diff_rad_per_s: float = 1e-12,
    stats: LineStats | None = None,
    level: float = 0.95,
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
    stats : LineStats, optional
        The tracks' window fits, shape (n,) each: with them every pair also gets the Fieller
        interval of its crossing time at `level` (:func:`pair_intervals`).
    level : float, optional
        Confidence level of the intervals.

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
    if stats is not None and np.shape(stats.slope) != b.shape:
        raise ValueError(f"stats must describe the {b.size} tracks, got {np.shape(stats.slope)}")
    ia, ib, tau = pairs_in_reach(b, r, reach_s=horizon,
                                 min_rate_diff_rad_per_s=min_rate_diff_rad_per_s)
    pred = (tau > 0.0) & (tau <= span)  # inequality (3): iK < t_c <= K(i + J)
    det = (tau >= -span) & (tau <= 0.0)  # inequality (4): K(i - J) <= t_c <= iK
    hit = np.flatnonzero(pred | det)
    a_idx, b_idx = ia[hit], ib[hit]
    srt = np.lexsort((b_idx, a_idx))
    a_idx, b_idx = a_idx[srt], b_idx[srt]
    t_cross = float(time) + tau[hit][srt]
    low = high = None
    if stats is not None:
        _, lo, hi, _ = pair_intervals(a_idx, b_idx, b, stats, level=level)
        low, high = float(time) + lo, float(time) + hi
    return PairCheck(index_a=a_idx, index_b=b_idx, t_cross=t_cross, predicted=pred[hit][srt],
                     t_cross_low=low, t_cross_high=high)
