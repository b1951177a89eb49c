"""Internals of the consensus fit of a delay track (:func:`fusion.clicks.delaytrack.consensus_inliers`).

The candidate polynomials of the MSAC search (constants, lines and parabolas through subsets of
clicks, subsets taken by rank in lexicographic order), the search itself, and the certificate
that lets it be skipped: a least-squares fit that no set of clicks would be worth dropping from
(regression deletion diagnostics; Cook and Weisberg, *Residuals and Influence in Regression*,
1982, ch. 2), with the clicks it leaves out beyond reach.
"""

from __future__ import annotations

from math import comb

import numpy as np
from numpy.typing import NDArray

__all__ = ["deletion_certified", "msac_consensus", "qr_fit", "subsets", "through",
           "trimmed_consensus"]


def subsets(n: int, k: int, limit: int) -> NDArray[np.int64]:
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


def through(u: NDArray, d: NDArray, rows: NDArray, width: int) -> NDArray[np.float64]:
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


def deletion_certified(q: NDArray, e: NDArray, thr: float) -> bool:
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


def qr_fit(x: NDArray, y: NDArray) -> tuple[NDArray, NDArray, NDArray] | None:
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


def trimmed_consensus(ps: NDArray, ds: NDArray, z_max: float, max_rate: float, max_accel: float,
             max_drop: int) -> tuple[NDArray[np.bool_], tuple[NDArray, NDArray, NDArray]] | None:
    """The clicks of the minimum of the truncated cost when it is a least-squares fit with at
    most `max_drop` clicks left out and that can be certified, with :func:`qr_fit` of those
    clicks (``qr_fit(ps[keep], ds[keep])``, for the caller's refit); None otherwise.

    Least squares on all clicks, dropping the click of largest deleted residual while the
    deletion test (:func:`deletion_certified`) fails; the result is accepted when its fit is
    within the rate and curvature limits, keeps its clicks within `z_max`, and every dropped
    click lies beyond `z_max` and would raise chi-square by more than ``z_max^2`` if added back
    (``e_o^2 / (1 + h_o)``).
    """
    n, p = ps.shape
    thr = z_max * z_max
    keep = np.ones(n, dtype=bool)
    for _ in range(max_drop + 1):
        fit = qr_fit(ps[keep], ds[keep])
        if fit is None:
            return None
        q, r, proj = fit
        e = ds[keep] - q @ proj
        if np.max(np.abs(e)) <= z_max and deletion_certified(q, e, thr):
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
    return keep, fit


def msac_consensus(u: NDArray, d: NDArray, sig: NDArray, top: int, z_max: float, max_rate: float,
          max_accel: float, max_candidates: int, n_local: int) -> NDArray[np.bool_] | None:
    """Inliers of the best candidate polynomial (see :func:`consensus_inliers`); None when the
    rate and curvature limits leave no candidate."""
    n = u.size
    coef = np.concatenate([through(u, d, subsets(n, deg + 1, max_candidates), top + 1)
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
