"""The delay track of a sensor pair through a processing window.

A source that moves makes the TDOA of a pair drift through a window: by up to ``2 v / c`` (about
1-3 ms per second for a whale at 1-2 m/s) and with a curvature of a few microseconds over 12 s
at ranges near 1 km, more than the per-click precision. The SCM2 of a coarse TDOA
(:func:`fusion.clicks.scm.scm2`) matches only the clicks within about 2 ms of it, a few seconds
of the window; :func:`match_along_track` follows the drift through the whole window;
:func:`consensus_inliers` drops cycle slips and mismatched click pairs; :func:`fit_delays` fits
a polynomial of the degree the data support. Additions to *Localization of Short Duration
Periodic Signals* (Baggenstoss, NUWC 102089), used by :class:`fusion.clicks.tdoa.TdoaRefiner`.
"""

from __future__ import annotations

from math import comb

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.clicks._consensus import msac_consensus, qr_fit, trimmed_consensus

__all__ = ["consensus_inliers", "fit_delays", "match_along_track", "shift_matrix"]

#: chi-square(1) quantile at 99 %: the likelihood-ratio threshold for one more drift term.
_LRT_CHI2 = 6.635


def shift_matrix(n: int, dt: float) -> NDArray[np.float64]:
    """Re-expansion of a polynomial about a shifted origin.

    Parameters
    ----------
    n : int
        Number of coefficients (degree + 1).
    dt : float
        Shift of the origin.

    Returns
    -------
    ndarray, shape (n, n)
        ``S`` such that ``sum_k c_k u^k = sum_k (S c)_k (u - dt)^k``.
    """
    s = np.zeros((n, n))
    for k in range(n):
        for m in range(k, n):
            s[k, m] = comb(m, k) * dt ** (m - k)
    return s


def fit_delays(
    t: ArrayLike, d: ArrayLike, sig: ArrayLike, *, max_degree: int = 2
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
    """Weighted polynomial fit of per-click delays over time, degree chosen by the data.

    Parameters
    ----------
    t : array_like, shape (n,)
        Click times, s.
    d : array_like, shape (n,)
        Per-click delays, s.
    sig : array_like, shape (n,)
        Their standard deviations, s (> 0).
    max_degree : int, optional
        Highest degree tried.

    Returns
    -------
    coef : ndarray, shape (degree + 1,)
        ``d(t) = sum_k coef[k] (t - t_ref)^k``.
    cov : ndarray, shape (degree + 1, degree + 1)
        Covariance of `coef` from `sig`.
    t_ref : float
        The weighted centroid of `t` (weights ``sig^-2``), s.
    birge : float
        ``sqrt(chi2 / (n - degree - 1))``, NaN when no degree of freedom is left.

    Notes
    -----
    The degree rises from 0 while one more term lowers chi-square by more than the 99 %
    quantile of chi-square(1) (a likelihood-ratio test with known sigmas) and leaves at least
    one degree of freedom; with 2 clicks the fit is their weighted mean.
    """
    t, d, sig = (np.asarray(a, dtype=float).ravel() for a in (t, d, sig))
    w = 1.0 / sig**2
    t_ref = float(np.sum(w * t) / np.sum(w))
    top = max(0, min(int(max_degree), t.size - 2))  # keep a degree of freedom
    x = (t - t_ref)[:, None] ** np.arange(top + 1) / sig[:, None]  # whitened design
    y = d / sig
    fit = qr_fit(x, y)
    if fit is None:  # times that do not determine the degree: the old way, degree by degree
        return _fit_delays_svd(t, d, sig, t_ref, top)
    _, r, proj = fit
    deg = 0  # nested fits: one more term lowers chi-square by proj[deg + 1]^2
    while deg < top and proj[deg + 1] ** 2 > _LRT_CHI2:
        deg += 1
    rinv = np.linalg.inv(r[: deg + 1, : deg + 1])
    coef = rinv @ proj[: deg + 1]
    res = y - x[:, : deg + 1] @ coef
    chi2 = float(res @ res)
    dof = t.size - coef.size
    birge = float(np.sqrt(chi2 / dof)) if dof >= 1 else float("nan")
    return coef, rinv @ rinv.T, t_ref, birge


def _fit_delays_svd(t: NDArray, d: NDArray, sig: NDArray, t_ref: float,
                    top: int) -> tuple[NDArray, NDArray, float, float]:
    """:func:`fit_delays` by SVD least squares, degree by degree (rank-deficient designs)."""
    xw_all = (t - t_ref)[:, None] ** np.arange(top + 1) / sig[:, None]
    dw = d / sig

    def fit(deg: int) -> tuple[NDArray, NDArray, float]:
        xw = xw_all[:, : deg + 1]
        coef, *_ = np.linalg.lstsq(xw, dw, rcond=None)
        res = dw - xw @ coef
        return coef, np.linalg.pinv(xw.T @ xw), float(res @ res)

    coef, cov, chi2 = fit(0)
    for deg in range(1, top + 1):
        c2, v2, x2 = fit(deg)
        if chi2 - x2 <= _LRT_CHI2:
            break
        coef, cov, chi2 = c2, v2, x2
    dof = t.size - coef.size
    birge = float(np.sqrt(chi2 / dof)) if dof >= 1 else float("nan")
    return coef, cov, t_ref, birge


def consensus_inliers(
    t: ArrayLike,
    d: ArrayLike,
    sig: ArrayLike,
    *,
    max_degree: int = 2,
    outlier_z: float = 4.0,
    max_rate: float = 0.004,
    max_accel: float = 5e-5,
    max_candidates: int = 4000,
    n_local: int = 10,
) -> NDArray[np.bool_]:
    """Clicks whose delays agree with the best consensus polynomial through them.

    Parameters
    ----------
    t, d, sig : array_like, shape (n,)
        Click times (s), per-click delays (s) and their standard deviations (s).
    max_degree : int, optional
        Highest degree of the candidate polynomials (lowered so that at least 2 clicks can
        disagree with a candidate).
    outlier_z : float, optional
        Residual, in sigmas, beyond which a click disagrees.
    max_rate : float, optional
        Largest drift ``|d tau / dt|`` of a candidate at the centre of the clicks, s/s
        (default 0.004: ``2 v / c`` for 3 m/s).
    max_accel : float, optional
        Largest ``|d^2 tau / dt^2|`` of a candidate, s/s^2 (default 5e-5: ``2 v^2 / (c r)``
        for 3 m/s at 240 m from a sensor).
    max_candidates : int, optional
        At most this many candidate subsets per degree (evenly thinned beyond it).
    n_local : int, optional
        The best candidates refitted to their own inliers before the final choice.

    Returns
    -------
    ndarray of bool, shape (n,)
        True for the clicks kept.

    Notes
    -----
    Candidates are the constants through each click, the lines through each pair and the
    parabolas through each triple (up to `max_degree`) that a moving source can produce; the
    one with the least truncated cost ``sum_n min(z_n^2, outlier_z^2)`` wins (MSAC: Torr and
    Zisserman, *Comput. Vis. Image Underst.* 78, 2000), after the best `n_local` have been
    refitted by weighted least squares to their inliers (locally optimised RANSAC: Chum, Matas
    and Kittler, *DAGM* 2003), since a curve through a few noisy clicks extrapolates poorly.
    A cycle slip of the correlation fine structure (one carrier period, tens of sigmas) or a
    mismatched click pulls a least-squares fit of a few clicks; the consensus is unaffected
    while most clicks agree. After a refit on the consensus set (:func:`fit_delays`), the
    clicks within `outlier_z` sigmas, times the robust scatter of the set when above 1, are
    kept.

    The search is skipped when it cannot change the outcome: when the least-squares fit
    through every click (within the rate and curvature limits) keeps them all within
    `outlier_z` and no set of clicks would lower its chi-square by more than ``outlier_z^2``
    per click dropped (the deletion formula of regression diagnostics), every polynomial with
    an outlier costs more than that fit, which is then the consensus of every click.
    """
    t, d, sig = (np.asarray(a, dtype=float).ravel() for a in (t, d, sig))
    n = t.size
    top = min(max_degree, n - 3)
    if top < 0:
        return np.ones(n, dtype=bool)
    u = t - 0.5 * (t.min() + t.max())
    ps = u[:, None] ** np.arange(top + 1) / sig[:, None]  # whitened design and data
    ds = d / sig
    trimmed = trimmed_consensus(ps, ds, outlier_z, max_rate, max_accel, max(1, n // 5))
    if trimmed is None:
        best = msac_consensus(u, d, sig, top, outlier_z, max_rate, max_accel, max_candidates, n_local)
        if best is None:
            return np.ones(n, dtype=bool)
        fit = None
    else:
        best, fit = trimmed  # the shortcut's own fit of its clicks: the refit below
    if best.sum() < 2:
        return np.ones(n, dtype=bool)
    # refit on the consensus set (the degree of fit_delays), scatter-inflated residual test
    if fit is None:
        fit = qr_fit(ps[best], ds[best])
    if fit is None:
        c, _, t_ref, _ = fit_delays(t[best], d[best], sig[best], max_degree=top)
        z = (d - ((t - t_ref)[:, None] ** np.arange(c.size)) @ c) / sig
    else:
        _, r, proj = fit
        deg = 0
        while deg < top and best.sum() >= deg + 3 and proj[deg + 1] ** 2 > _LRT_CHI2:
            deg += 1
        z = ds - ps[:, : deg + 1] @ np.linalg.solve(r[: deg + 1, : deg + 1], proj[: deg + 1])
    scale = max(1.0, 1.4826 * float(np.median(np.abs(z[best]))))
    keep = np.abs(z) <= outlier_z * scale
    return keep if keep.sum() >= 2 else best


def match_along_track(
    times_i: ArrayLike,
    times_j: ArrayLike,
    index_i: ArrayLike,
    index_j: ArrayLike,
    *,
    t_start_s: float,
    t_end_s: float,
    tolerance_s: float = 3e-4,
    max_degree: int = 2,
    n_iter: int = 3,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Extend seed click matches of a pair through a window along their delay track.

    Parameters
    ----------
    times_i, times_j : array_like, shape (n_i,), (n_j,)
        Click times on sensors ``i`` and ``j``, s.
    index_i, index_j : array_like of int, shape (m,)
        Seed matches: ``times_i[index_i[k]]`` and ``times_j[index_j[k]]`` are one emission (the
        SCM2 matches, :attr:`fusion.clicks.scm.Scm2.index_i`).
    t_start_s, t_end_s : float
        The window, on sensor ``i``'s clock, s.
    tolerance_s : float, optional
        Largest difference between a detected delay ``t_i - t_j`` and the track, s; default
        0.3 ms (detection time errors of tens of microseconds on both sensors plus the track's
        extrapolation error).
    max_degree : int, optional
        Highest degree of the track polynomial.
    n_iter : int, optional
        Fit-and-match rounds (the matched span grows from the seed outwards).

    Returns
    -------
    index_i, index_j : ndarray of int, shape (m2,)
        Matches through the window, in order of ``times_i``; each click used once. The seed
        matches are returned unchanged when fewer than 2 of them agree on a track.

    Notes
    -----
    Each round fits the detected delays of the current matches with :func:`consensus_inliers`
    and :func:`fit_delays` (sigma ``tolerance_s / 4``), then pairs every click of ``i`` in
    the window with the click of ``j`` nearest ``t_i - tau(t_i)``, within `tolerance_s`. The
    track's degree is capped at 1 while the matches span less than 3 s (a curvature is not
    measurable from detection times over a short span).
    """
    ti = np.asarray(times_i, dtype=float).ravel()
    tj = np.asarray(times_j, dtype=float).ravel()
    ii = np.asarray(index_i, dtype=np.int64).ravel()
    jj = np.asarray(index_j, dtype=np.int64).ravel()
    if ii.shape != jj.shape:
        raise ValueError("index_i and index_j must have one length")
    if ii.size < 2 or tj.size == 0:
        return ii, jj
    sig = tolerance_s / 4.0
    cand = np.flatnonzero((ti >= t_start_s) & (ti < t_end_s))
    order = np.argsort(tj)
    tjs = tj[order]
    for _ in range(n_iter):
        t, d = ti[ii], ti[ii] - tj[jj]
        deg = max_degree if np.ptp(t) >= 3.0 else min(max_degree, 1)
        s = np.full(t.size, sig)
        keep = consensus_inliers(t, d, s, max_degree=deg, outlier_z=4.0, max_rate=np.inf,
                                 max_accel=np.inf)
        if keep.sum() < 2:
            break
        coef, _, t_ref, _ = fit_delays(t[keep], d[keep], s[keep], max_degree=deg)
        want = ti[cand] - ((ti[cand] - t_ref)[:, None] ** np.arange(coef.size)) @ coef
        k = np.clip(np.searchsorted(tjs, want), 1, max(tjs.size - 1, 1))
        lo, hi = np.clip(k - 1, 0, tjs.size - 1), np.clip(k, 0, tjs.size - 1)
        pick = np.where(np.abs(tjs[hi] - want) < np.abs(tjs[lo] - want), hi, lo)
        dist = np.abs(tjs[pick] - want)
        ok = dist <= tolerance_s
        new_i, new_j, dist = cand[ok], order[pick[ok]], dist[ok]
        by_dist = np.argsort(dist, kind="stable")  # a j click shared: the closer i click keeps it
        _, first = np.unique(new_j[by_dist], return_index=True)
        sel = np.sort(by_dist[first])
        if sel.size < 2:
            break
        new_i, new_j = new_i[sel], new_j[sel]
        if np.array_equal(new_i, ii) and np.array_equal(new_j, jj):
            break
        ii, jj = new_i, new_j
    return ii, jj
