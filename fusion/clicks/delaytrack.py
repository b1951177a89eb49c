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
    fit = _qr_fit(x, y)
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


def _subsets(n: int, k: int, limit: int) -> NDArray[np.int64]:
    """The rows of ``itertools.combinations(range(n), k)`` (lexicographic order), evenly thinned
    to `limit` rows (positions ``linspace(0, M - 1, limit)`` truncated) when there are more.

    Rows are computed from their positions (unranking), not enumerated.
    """
    total = comb(n, k)
    pos = (np.arange(total, dtype=np.int64) if total <= limit
           else np.linspace(0, total - 1, limit).astype(np.int64))
    out = np.empty((pos.size, k), dtype=np.int64)
    lo = np.zeros(pos.size, dtype=np.int64)  # smallest element still allowed
    for p in range(k):
        r = k - p  # elements left to choose, this one included
        # combinations of r elements of range(n) whose first element is below a
        first = np.concatenate([[0], np.cumsum([comb(n - 1 - a, r - 1) for a in range(n)])])
        q = pos + first[lo]  # position among all r-combinations of range(n)
        a = np.searchsorted(first, q, side="right") - 1
        out[:, p] = a
        pos, lo = q - first[a], a + 1
    return out


def _through(u: NDArray, d: NDArray, rows: NDArray, width: int) -> NDArray[np.float64]:
    """Coefficients (in powers of `u`, padded to `width`) of the polynomial through the clicks
    of each row of `rows` (1, 2 or 3 clicks: constant, line, parabola); rows whose clicks share
    a time are left out."""
    k = rows.shape[1]
    uu, dd = u[rows], d[rows]
    c = np.zeros((rows.shape[0], width))
    if k == 1:
        c[:, 0] = dd[:, 0]
        return c
    ok = np.all(np.diff(np.sort(uu, axis=1), axis=1) != 0, axis=1)
    uu, dd, c = uu[ok], dd[ok], c[ok]
    s01 = (dd[:, 1] - dd[:, 0]) / (uu[:, 1] - uu[:, 0])  # divided differences (Newton form)
    if k == 2:
        c[:, 1] = s01
        c[:, 0] = dd[:, 0] - s01 * uu[:, 0]
        return c
    s12 = (dd[:, 2] - dd[:, 1]) / (uu[:, 2] - uu[:, 1])
    s012 = (s12 - s01) / (uu[:, 2] - uu[:, 0])
    # d0 + s01 (u - u0) + s012 (u - u0)(u - u1) in powers of u
    c[:, 2] = s012
    c[:, 1] = s01 - s012 * (uu[:, 0] + uu[:, 1])
    c[:, 0] = dd[:, 0] - s01 * uu[:, 0] + s012 * uu[:, 0] * uu[:, 1]
    return c


def _deletion_certified(q: NDArray, e: NDArray, thr: float) -> bool:
    """Whether dropping any set ``E`` of points lowers a least-squares fit's chi-square by less
    than ``thr |E|``, from the orthonormal factor `q` of its whitened design and its whitened
    residuals `e`.

    The decrease is ``e_E^T (I - H_EE)^-1 e_E`` (``H = q q^T``, the hat matrix): exact for
    single points and pairs; for larger sets bounded by ``|e_E|^2 / (1 - tr H_EE)`` with the
    largest residuals and leverages, and by chi-square itself (no set lowers it by more).
    False when that does not decide.
    """
    h = np.einsum("ij,ij->i", q, q)  # leverages
    e2 = e * e
    if np.max(h) >= 1.0 or np.any(e2 >= thr * (1.0 - h)):
        return False
    if np.any(np.abs(e) > np.sqrt(thr) * (1.0 - h)):
        return False  # a click the fit through the others would call an outlier
    k_max = int(float(e2.sum()) // thr)  # larger sets cannot lower chi-square by thr |E|
    if k_max >= 2:
        # a pair lowers chi-square by at most (e_i^2 + e_k^2) / (1 - h_i - h_k), so only pairs
        # with a click of e^2 >= thr (1 - the two largest leverages) need the exact test
        cand = np.flatnonzero(e2 >= thr * (1.0 - np.sum(np.sort(h)[-2:])))
        if cand.size:
            hik = q[cand] @ q.T  # (c, n) off-diagonal hat matrix entries
            a = 1.0 - h
            den = a[cand, None] * a[None, :] - hik * hik
            num = (a[None, :] * e2[cand, None] + 2.0 * hik * (e[cand, None] * e[None, :])
                   + a[cand, None] * e2[None, :])
            rows = np.arange(cand.size)
            den[rows, cand] = 1.0
            num[rows, cand] = 0.0
            if np.any(den <= 0.0) or np.any(num >= 2.0 * thr * den):
                return False
    if k_max >= 3:
        e_top = np.cumsum(np.sort(e2)[::-1])
        h_top = np.cumsum(np.sort(h)[::-1])
        for k in range(3, k_max + 1):
            den_k = 1.0 - h_top[k - 1]
            if den_k <= 0.0 or e_top[k - 1] >= thr * k * den_k:
                return False
    return True


def _qr_fit(x: NDArray, y: NDArray) -> tuple[NDArray, NDArray, NDArray] | None:
    """Thin QR factors of a small design (Gram-Schmidt with one re-orthogonalisation, as
    accurate as Householder here and without LAPACK's call overhead) and the projections
    ``q^T y``; None when the design is (nearly) rank deficient."""
    n, p = x.shape
    q = np.empty((n, p))
    r = np.zeros((p, p))
    for j in range(p):
        v = x[:, j].copy()
        if j:
            for _ in range(2):
                c = q[:, :j].T @ v
                v -= q[:, :j] @ c
                r[:j, j] += c
        nrm = float(np.sqrt(v @ v))
        if not nrm > 1e-12 * float(np.sqrt(x[:, j] @ x[:, j])):
            return None
        r[j, j] = nrm
        q[:, j] = v / nrm
    return q, r, q.T @ y


def _trimmed(ps: NDArray, ds: NDArray, z_max: float, max_rate: float, max_accel: float,
             max_drop: int) -> NDArray[np.bool_] | None:
    """The clicks of the minimum of the truncated cost when it is a least-squares fit with at
    most `max_drop` clicks left out and that can be certified; None otherwise.

    Least squares on all clicks, dropping the click of largest deleted residual while the
    deletion test (:func:`_deletion_certified`) fails; the result is accepted when its fit is
    within the rate and curvature limits, keeps its clicks within `z_max`, and every dropped
    click lies beyond `z_max` and would raise chi-square by more than ``z_max^2`` if added back
    (``e_o^2 / (1 + h_o)``).
    """
    n, p = ps.shape
    thr = z_max * z_max
    keep = np.ones(n, dtype=bool)
    for _ in range(max_drop + 1):
        fit = _qr_fit(ps[keep], ds[keep])
        if fit is None:
            return None
        q, r, proj = fit
        e = ds[keep] - q @ proj
        if np.max(np.abs(e)) <= z_max and _deletion_certified(q, e, thr):
            break
        if not keep.sum() > p + 2:
            return None
        h = np.einsum("ij,ij->i", q, q)  # leverages
        worst = np.argmax(e * e / np.maximum(1.0 - h, 1e-300))
        keep[np.flatnonzero(keep)[worst]] = False
    else:
        return None
    coef = np.linalg.solve(r, proj)
    if p >= 2 and abs(coef[1]) > max_rate:
        return None
    if p >= 3 and 2.0 * abs(coef[2]) > max_accel:
        return None
    out = ~keep
    if out.any():
        xo = ps[out]
        eo = ds[out] - xo @ coef
        ho = np.sum(np.linalg.solve(r.T, xo.T) ** 2, axis=0)  # x_o^T (X^T X)^-1 x_o
        if np.any(np.abs(eo) <= z_max) or np.any(eo * eo <= thr * (1.0 + ho)):
            return None
    return keep


def _msac(u: NDArray, d: NDArray, sig: NDArray, top: int, z_max: float, max_rate: float,
          max_accel: float, max_candidates: int, n_local: int) -> NDArray[np.bool_] | None:
    """Inliers of the best candidate polynomial (see :func:`consensus_inliers`); None when the
    rate and curvature limits leave no candidate."""
    n = u.size
    coef = np.concatenate([_through(u, d, _subsets(n, deg + 1, max_candidates), top + 1)
                           for deg in range(top + 1)])
    if top >= 1:
        coef = coef[np.abs(coef[:, 1]) <= max_rate]
    if top >= 2:
        coef = coef[2.0 * np.abs(coef[:, 2]) <= max_accel]
    if coef.shape[0] == 0:
        return None
    ps = u[:, None] ** np.arange(top + 1) / sig[:, None]
    ds = d / sig
    thr = z_max * z_max
    z = ds - coef @ ps.T
    z *= z
    costs = np.minimum(z, thr, out=z).sum(axis=1)  # MSAC: truncated quadratic cost
    order = np.argsort(costs)[:n_local]
    inl = np.abs(ds - coef[order] @ ps.T) <= z_max  # (n_local, n)
    best_cost, best = costs[order[0]], inl[0]
    # local optimisation: refit each good candidate to its own inliers
    cnt = inl.sum(axis=1)
    refit = np.zeros((order.size, top + 1))
    tried = np.zeros(order.size, dtype=bool)
    for deg in range(top + 1):
        sel = np.flatnonzero((cnt >= 2) & (np.minimum(top, cnt - 1) == deg))
        if sel.size == 0:
            continue
        m = inl[sel].astype(float)
        x = ps[:, : deg + 1]
        g = np.einsum("ki,ij,il->kjl", m, x, x)
        b = np.einsum("ki,ij,i->kj", m, x, ds)
        try:
            refit[sel, : deg + 1] = np.linalg.solve(g, b[..., None])[..., 0]
        except np.linalg.LinAlgError:  # coincident click times: least squares one by one
            for k in sel:
                mk = inl[k]
                refit[k, : deg + 1] = np.linalg.lstsq(x[mk], ds[mk], rcond=None)[0]
        tried[sel] = True
    z = ds - refit @ ps.T
    z2 = np.minimum(z * z, thr).sum(axis=1)
    for k in np.flatnonzero(tried):
        if z2[k] < best_cost:
            best_cost, best = z2[k], np.abs(z[k]) <= z_max
    return best


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
    best = _trimmed(ps, ds, outlier_z, max_rate, max_accel, max(1, n // 5))
    if best is None:
        best = _msac(u, d, sig, top, outlier_z, max_rate, max_accel, max_candidates, n_local)
        if best is None:
            return np.ones(n, dtype=bool)
    if best.sum() < 2:
        return np.ones(n, dtype=bool)
    # refit on the consensus set (the degree of fit_delays), scatter-inflated residual test
    fit = _qr_fit(ps[best], ds[best])
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
