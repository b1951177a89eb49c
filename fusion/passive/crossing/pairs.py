"""Crossing time of every pair of tracks, its confidence interval and the method's inequalities.

Equation (2) of *Target Track Crossing Prediction/Detection* (block 104B), the in-range check
(104C) and inequalities (3) and (4) (104D, 104E), for all pairs of tracks at once on numpy pair
arrays. Equation (2) itself is :func:`fusion.passive.crossing.timing.crossing_time_terms`, the one
copy in the code base. With the covariance of each track's window fit
(:class:`fusion.passive.line_fit.LineStats`) each crossing time also gets a confidence interval
(:func:`~fusion.passive.crossing.interval.crossing_time_interval`, importable from here too).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.passive.crossing.curvature import CurvatureStats
from fusion.passive.crossing.interval import crossing_time_interval, t_quantile, welch_dof
from fusion.passive.crossing.manoeuvre import manoeuvre_variance
from fusion.passive.crossing.timing import crossing_time_terms
from fusion.passive.crossing.types import PairCheck
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


def _sweep(b: NDArray[np.float64], w: NDArray[np.float64]
           ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Pairs (i < j) of one set within ``w_i`` ahead of ``b_i`` on the circle (every ``w < pi``)."""
    n = b.size
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


def _cross(b_g: NDArray[np.float64], b_h: NDArray[np.float64], w: float
           ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Positions (i in g, j in h) with ``|wrap(b_h[j] - b_g[i])| <= w`` or more (``w < pi``)."""
    m = b_h.size
    order = np.argsort(b_h, kind="stable")
    bs = b_h[order]
    ext = np.concatenate([bs - _TWO_PI, bs, bs + _TWO_PI])
    lo = np.searchsorted(ext, b_g - w, side="left")
    cnt = np.searchsorted(ext, b_g + w, side="right") - lo
    cnt = np.minimum(cnt, m)  # an arc shorter than the circle holds each point at most once
    total = int(cnt.sum())
    i = np.repeat(np.arange(b_g.size), cnt)
    first = np.repeat(np.cumsum(cnt) - cnt, cnt)
    j = order[(np.repeat(lo, cnt) + np.arange(total) - first) % m]
    return i, j


#: Rate groups of the screen when one sweep cannot bound the pairs (see _candidate_pairs).
_RATE_GROUPS = 16
#: Fewest tracks per rate group.
_GROUP_MIN = 32


def _candidate_pairs(
    b: NDArray[np.float64], r: NDArray[np.float64], horizon: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Index pairs (i < j) that can pass the in-range check, all others left out exactly.

    A pair passes only if ``|wrap(b_j - b_i)| <= horizon |r_i - r_j|``, which is at most
    ``W_i = horizon max(r_i - min r, max r - r_i)`` (and likewise ``W_j``). When every
    ``W_i < pi`` the bearings are sorted around the circle and each track is paired with the
    tracks up to ``W_i`` ahead of it (a sweep with ``searchsorted``): a passing pair lies
    within ``W`` ahead of one of its tracks, and no pair can be listed from both sides (that
    would need ``W_i + W_j >= 2 pi``). Otherwise (a wide spread of rates over a long reach)
    the tracks are cut into groups of neighbouring rates: within a group the same sweep with
    the group's rates, between groups ``g`` and ``h`` the bearings within
    ``horizon max |r_h - r_g|`` of each other (every pair of the two groups where that bound
    reaches half the circle).
    """
    n = b.size
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    w = horizon * np.maximum(r - r.min(), r.max() - r)
    w = w * (1.0 + 1e-9) + 1e-12  # margin for round-off: never drops a pair that passes
    if np.all(w < np.pi):
        return _sweep(b, w)
    n_groups = min(_RATE_GROUPS, n // _GROUP_MIN)
    if n_groups < 2:
        return _triu(n)
    by_rate = np.argsort(r, kind="stable")
    groups = np.array_split(by_rate, n_groups)
    rmin = [float(r[g].min()) for g in groups]
    rmax = [float(r[g].max()) for g in groups]
    out_i, out_j = [], []
    for g, grp in enumerate(groups):
        wg = horizon * np.maximum(r[grp] - rmin[g], rmax[g] - r[grp]) * (1.0 + 1e-9) + 1e-12
        if np.all(wg < np.pi):
            i, j = _sweep(b[grp], wg)
        else:
            i, j = _triu(grp.size)
        out_i.append(grp[i])
        out_j.append(grp[j])
        for h in range(g + 1, n_groups):
            oth = groups[h]
            wgh = horizon * (rmax[h] - rmin[g]) * (1.0 + 1e-9) + 1e-12  # rates sorted: h >= g
            if wgh < np.pi:
                i, j = _cross(b[grp], b[oth], wgh)
            else:
                i = np.repeat(np.arange(grp.size), oth.size)
                j = np.tile(np.arange(oth.size), grp.size)
            out_i.append(grp[i])
            out_j.append(oth[j])
    i, j = np.concatenate(out_i), np.concatenate(out_j)
    return np.minimum(i, j), np.maximum(i, j)


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
    num, den = crossing_time_terms(b[ia], r[ia], b[ib], r[ib])  # wrap(B0_b - B0_a), B'_a - B'_b
    # 104C in-range check, division-free: |t_c - t_i| <= reach and tracks not parallel.
    keep = np.abs(num) <= reach_s * np.abs(den)
    keep &= np.abs(den) > min_rate_diff_rad_per_s
    k = np.flatnonzero(keep)
    return ia[k], ib[k], num[k] / den[k]  # t_c - t_i, equation (2)


def _curvature_terms(cs: CurvatureStats, index_a: NDArray[np.int64], index_b: NDArray[np.int64]
                     ) -> tuple[NDArray[np.float64], ...]:
    """The pairs' curvature statistics, gathered once for several leads."""
    return (cs.alpha[index_a], cs.beta[index_a], cs.c[index_a], cs.var_c[index_a],
            cs.alpha[index_b], cs.beta[index_b], cs.c[index_b], cs.var_c[index_b])


def _curvature_miss(terms: tuple[NDArray[np.float64], ...], t: NDArray[np.float64]
                    ) -> NDArray[np.float64]:
    """:func:`~fusion.passive.crossing.curvature.curvature_variance` at finite `t`, from
    :func:`_curvature_terms` (the same operations in the same order)."""
    al_a, be_a, c_a, vc_a, al_b, be_b, c_b, vc_b = terms
    tt = t * t
    ga, gb = tt - al_a - be_a * t, tt - al_b - be_b * t
    return (c_b * gb - c_a * ga) ** 2 + vc_a * ga * ga + vc_b * gb * gb


def pair_intervals(
    index_a: NDArray[np.int64],
    index_b: NDArray[np.int64],
    bearing_rad: NDArray[np.float64],
    stats: LineStats,
    *,
    level: float,
    var_scale: float = 1.0,
    curvature: CurvatureStats | None = None,
    manoeuvre: tuple[NDArray[np.float64], float] | None = None,
    far_side: bool = False,
    own_width: bool = False,
    max_width_s: float | None = None,
) -> tuple[NDArray[np.float64], ...]:
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
    var_scale : float, optional
        Factor on the lines' covariance (default 1; the extrapolation factor of
        :class:`~fusion.passive.crossing.calibration.ExtrapolationScale` for predictions).
    curvature : CurvatureStats, optional
        The windows' second-order terms: a crossing ahead of the sample (``tau > 0``) gets the
        variance the lines miss at ``tau`` from the curvature they leave out
        (:func:`~fusion.passive.crossing.curvature.curvature_variance`) added to the
        difference's variance (default None: the lines' covariance only).
    manoeuvre : (ndarray, float), optional
        Each track's rate-wander intensity and the window span: the miss
        :func:`~fusion.passive.crossing.manoeuvre.manoeuvre_variance` of the two lines is added
        ahead of the sample (default None).
    far_side : bool, optional
        The upper bound recomputed with the lead-dependent variances taken at it.
    own_width : bool, optional
        Also return the width of the interval with `curvature` only (no `manoeuvre`, no
        `far_side`), from the same terms (default False).
    max_width_s : float, optional
        Only pairs whose interval may be this narrow are widened: a pair whose interval from
        the lines' covariance alone is unbounded or wider (the lead-dependent terms only add
        variance, so it stays wider) may be returned unbounded, with NaN bounds and width,
        without its curvature, manoeuvre and far-end terms (when a quarter of the pairs or
        more are such; default None: every pair computed).

    Returns
    -------
    tau, low, high : ndarray, shape (p,)
        ``t_c - t_i`` and the interval bounds, s.
    bounded : ndarray of bool, shape (p,)
        Whether the interval is bounded (rate difference resolved).
    width : ndarray, shape (p,)
        Only with `own_width`: the width of the interval without the manoeuvre and far-end terms.

    Notes
    -----
    The two tracks' fits are independent, so the difference line ``d = B_b - B_a`` has the
    sums of their covariances. The quantile is Student-t with the Welch-Satterthwaite degrees
    of freedom of the rate difference, ``(v_a + v_b)^2 / (v_a^2 / (n_a - 2) + v_b^2 / (n_b - 2))``.
    """
    b = _wrap(bearing_rad)
    r = stats.slope
    num, den = crossing_time_terms(b[index_a], r[index_a], b[index_b], r[index_b])
    d0, d1 = num, -den  # the difference line B_b - B_a: value at the sample (rad), rate (rad/s)
    va, vb = stats.var_slope[index_a], stats.var_slope[index_b]
    v11 = va + vb
    dof = welch_dof(va, vb, stats.n[index_a] - 2.0, stats.n[index_b] - 2.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        tau = np.where(den != 0, num / np.where(den != 0, den, 1.0), np.inf)  # equation (2)
    q = t_quantile(level, dof)
    if var_scale != 1.0:
        q = q * np.sqrt(var_scale)
    v00 = stats.var_value[index_a] + stats.var_value[index_b]
    v01 = stats.cov[index_a] + stats.cov[index_b]
    widened = curvature is not None or manoeuvre is not None
    tau_all, kept = tau, None
    if max_width_s is not None and widened:  # leave out the pairs the widening cannot resolve
        low, high, bounded = crossing_time_interval(d0, d1, v00, v01, v11, q)
        with np.errstate(invalid="ignore"):
            keep = bounded & (high - low <= max_width_s)
        if keep.sum() < 0.75 * keep.size:  # worth the gathers (the others lose nothing)
            kept = np.flatnonzero(keep)
            index_a, index_b, d0, d1, v00, v01, v11, q, tau = (
                x[kept] for x in (index_a, index_b, d0, d1, v00, v01, v11, q, tau))
    # Fieller's interval (crossing_time_interval) term by term: only C changes with the variance
    q2 = q ** 2
    A = d1 * d1 - q2 * v11
    B = d0 * d1 - q2 * v01
    d00 = d0 * d0
    bounded = A > 0
    A_ok = np.where(bounded, A, 1.0)

    def roots(v: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        root = np.sqrt(np.maximum(B * B - A * (d00 - q2 * v), 0.0))
        return (np.where(bounded, (-B - root) / A_ok, -np.inf),
                np.where(bounded, (-B + root) / A_ok, np.inf))

    cterms = None if curvature is None else _curvature_terms(curvature, index_a, index_b)
    q_man = None if manoeuvre is None else manoeuvre[0][index_a] + manoeuvre[0][index_b]
    ahead = np.isfinite(tau) & (tau > 0)
    cv_tau = None
    if curvature is not None:  # the curvature the lines leave out, at the crossing
        cv_tau = np.where(ahead, _curvature_miss(cterms, np.where(ahead, tau, 0.0)), 0.0)

    def ahead_var(at: NDArray[np.float64], cv: NDArray[np.float64] | None = None
                  ) -> NDArray[np.float64]:
        """The variance the lines' own covariance leaves out, at `at` ahead (0 behind); `cv`
        the curvature term at `at` if known."""
        extra = np.zeros(at.shape)
        if curvature is not None:  # the curvature the lines leave out
            if cv is None:
                ok = np.isfinite(at) & (at > 0)
                cv = np.where(ok, _curvature_miss(cterms, np.where(ok, at, 0.0)), 0.0)
            extra = extra + cv
        if manoeuvre is not None:  # the rate wander the lines cannot show
            extra = extra + manoeuvre_variance(q_man, manoeuvre[1], at)
        return extra

    width = None
    if own_width:
        lo_own, hi_own = roots(v00 if curvature is None else v00 + cv_tau)
        width = hi_own - lo_own
    if not widened:
        low, high = roots(v00)
    else:  # at the predicted crossing, then (`far_side`) again at the interval's far end
        low, high = roots(v00 + ahead_var(tau, cv_tau))
        if far_side:
            far = np.where(bounded & np.isfinite(high) & (high > tau), high, tau)
            high = roots(v00 + ahead_var(far))[1]
    bounded &= np.isfinite(low) & np.isfinite(high)
    out = (low, high, bounded) if width is None else (low, high, bounded, width)
    if kept is not None:  # the pairs left out: unbounded, NaN bounds and width
        full = tuple(np.full(tau_all.size, np.nan if x.dtype.kind == "f" else False, x.dtype)
                     for x in out)
        for f, x in zip(full, out, strict=True):
            f[kept] = x
        out = full
    return (tau_all, *out)


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
