"""Candidates made of another candidate's clicks heard late: the echo-ghost test.

On hydrophones standing a few metres above the sea floor each click also arrives along the
bottom-reflected path, ``l_i`` later at sensor ``i`` (0.2-30 ms, the same for every click of a
whale over a window). A delay measured between the echo at sensor ``i`` and the direct click
at ``j`` is the whale's direct delay plus ``l_i``; between the direct click at ``i`` and the
echo at ``j``, minus ``l_j``; between two echoes, plus ``l_i - l_j``. A set of such delays can
fit a position of its own: a second source a few tens to hundreds of metres from the whale.

The test asks whether a candidate ``G``'s held delays are those of another candidate ``S``
moved by echo lags: every residual ``tau_m - d_m(S)`` is, within its tolerance, ``0``, ``l_i``,
``-l_j`` or ``l_i - l_j`` with lags ``0 < l <= max_lag_s`` on at most ``max_lags`` sensors.
Two lags are fewer parameters than the three of a new source's position, so the echo reading
is the simpler explanation; a distinct whale's residuals are ``delta_i - delta_j`` with a
``delta`` on every sensor it is heard on (at least four for a fix), which two lags explain
only when its range differences to the other sensors equal ``S``'s to within the tolerance.
The lags are positive (an echo arrives after its click), so the test has a direction: the
echoes' candidate is the ghost, whichever holds more TDOAs. A candidate whose residuals are
all zero duplicates ``S`` and is dropped only when it holds less.

Notes
-----
*Localization of Short Duration Periodic Signals*, step 32 and paragraph [0028]: reflected
arrivals are told from source arrivals by their delay after a stronger arrival (the text's
"threshold time"); here the same reading is applied to delays a candidate holds.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import surface_image

__all__ = ["echo_explained", "echo_ghosts", "echo_only_sensors", "surface_alternatives"]


def _candidate_lags(r: NDArray, pairs: NDArray, max_lag_s: float, tol: NDArray,
                    signed: NDArray[np.bool_] | None = None) -> list[tuple[int, float]]:
    """(sensor, lag) values a single echo would give: ``r = l_i`` or ``r = -l_j``.

    `r`, `tol`: (k, A); `pairs`: (k, A, 2), one column per reading of each delay. A sensor
    index with ``signed[index]`` takes a lag of either sign.
    """
    out: set[tuple[int, float]] = set()
    for rm, pm, tm in zip(r.reshape(-1), pairs.reshape(-1, 2), tol.reshape(-1), strict=True):
        for key, lag in ((int(pm[0]), float(rm)), (int(pm[1]), float(-rm))):
            free = signed is not None and key < signed.size and bool(signed[key])
            if tm < (abs(lag) if free else lag) <= max_lag_s:
                out.add((key, lag))
    return sorted(out)


def _explains(r: NDArray, pairs: NDArray, tol: NDArray, lags: dict[int, float]) -> bool:
    """Whether every delay has a reading (column of `r`) that the lags explain."""
    li = np.vectorize(lambda i: lags.get(int(i), 0.0), otypes=[float])(pairs[..., 0])
    lj = np.vectorize(lambda j: lags.get(int(j), 0.0), otypes=[float])(pairs[..., 1])
    hyp = np.stack([np.zeros_like(r), li, -lj, li - lj])  # dd, echo at i, echo at j, both
    ok = np.min(np.abs(hyp - r[None]), axis=0) <= tol  # (k, A)
    return bool(np.all(np.any(ok, axis=1)))


def echo_explained(residuals: ArrayLike, pairs: ArrayLike, tolerances: ArrayLike, *,
                   max_lag_s: float, max_lags: int = 2,
                   signed: ArrayLike | None = None) -> tuple[bool, int]:
    """Whether residuals ``tau_m - d_m(S)`` of a candidate's delays are echo lags of ``S``.

    Parameters
    ----------
    residuals : array_like, shape (k,) or (k, A)
        Measured delay minus the other candidate's predicted delay, s; with ``A`` columns,
        one per reading of the delay (the direct paths, a surface path, ...): a delay is
        explained when one of its readings is.
    pairs : array_like of int, shape (k, 2) or (k, A, 2)
        Sensor pair ``(i, j)`` of each reading (``tau = t_i - t_j``); one lag per index (a
        surface image has its own index, its own lag).
    tolerances : array_like, shape (k,) or (k, A)
        Largest |misfit| of each reading, s.
    max_lag_s : float, keyword-only
        Longest echo lag, s.
    max_lags : int, keyword-only
        Most sensors with an echo lag (default 2, fewer than a position's three unknowns).
    signed : array_like of bool, optional, keyword-only
        Per sensor index: its lag may have either sign (a surface image: the delay along a
        reflected path is predicted with the direct path's sound speed, and the effective
        speed along the longer path through the upper water differs by up to about 1 %).

    Returns
    -------
    (bool, int)
        Explained, and the number of lags used (0: the delays are the other's own).

    Examples
    --------
    >>> pairs = [(0, 1), (0, 3), (1, 2), (2, 3)]
    >>> echo_explained([4e-3, 4e-3, -2e-3, 2e-3], pairs, [1e-6] * 4, max_lag_s=0.03)
    (True, 2)
    >>> echo_explained([4e-3, 1e-3, -2e-3, 2e-3], pairs, [1e-6] * 4, max_lag_s=0.03)
    (False, 0)
    """
    r = np.asarray(residuals, dtype=float)
    r = r[:, None] if r.ndim == 1 else r
    k, n_alt = r.shape
    p = np.asarray(pairs, dtype=np.intp).reshape(k, -1, 2)
    if p.shape[1] != n_alt:
        p = np.broadcast_to(p, (k, n_alt, 2))
    tol = np.broadcast_to(np.asarray(tolerances, dtype=float).reshape(k, -1), (k, n_alt))
    if k == 0:
        return False, 0
    if _explains(r, p, tol, {}):
        return True, 0
    cands = _candidate_lags(r, p, float(max_lag_s), tol,
                            None if signed is None else np.asarray(signed, dtype=bool))
    for n in range(1, int(max_lags) + 1):
        for combo in combinations(cands, n):
            if len({s for s, _ in combo}) < n:
                continue
            if _explains(r, p, tol, dict(combo)):
                return True, n
    return False, 0


def echo_ghosts(taus: ArrayLike, sigmas: ArrayLike, pairs: ArrayLike, predicted: ArrayLike,
                held: ArrayLike, *, max_lag_s: float, n_sigmas: float = 3.0,
                max_lags: int = 2, reflected: ArrayLike | None = None,
                reflected_pairs: ArrayLike | None = None, inverted: ArrayLike | None = None,
                slip_s: float = 0.0, image_keys: ArrayLike | None = None) -> NDArray[np.bool_]:
    """Which candidates are echo ghosts (or duplicates) of another candidate.

    Parameters
    ----------
    taus, sigmas : array_like, shape (M,)
        The window's delays and their sigmas, s.
    pairs : array_like of int, shape (M, 2)
        Their sensor pairs.
    predicted : array_like, shape (K, M)
        Each candidate's predicted delays, s.
    held : array_like of bool, shape (K, M)
        The delays each candidate holds (weight > 0.5).
    max_lag_s : float, keyword-only
        Longest echo lag, s.
    n_sigmas : float, keyword-only
        Tolerance in sigmas of ``hypot(sigma_m, rms)``, ``rms`` the other candidate's own
        residual RMS over the delays it holds (its model error: sound speed, positions).
    max_lags : int, keyword-only
        See :func:`echo_explained`.
    reflected : array_like, shape (K, M, A), optional, keyword-only
        Each candidate's delays along ``A`` readings of each column (as it stands and with a
        surface reflection, :func:`surface_alternatives`); a delay is explained when one of
        its readings is, with or without echo lags.
    reflected_pairs : array_like of int, shape (M, A, 2), optional, keyword-only
        The sensor pair of each reading (an image sensor has its own index: its own lag).
    inverted : array_like of bool, shape (M, A), optional, keyword-only
        Path pairs with one surface reflection: the echo is sign-inverted, and a delay
        measured on the largest positive correlation lies half a carrier period off the
        path's delay; their tolerance grows by `slip_s`.
    slip_s : float, keyword-only
        Half a carrier period of the lowest click frequency, s.
    image_keys : array_like of bool, optional, keyword-only
        Per sensor index of `reflected_pairs`: a surface image (its lag may have either sign,
        see :func:`echo_explained`).

    Returns
    -------
    ndarray of bool, shape (K,)
        True for a candidate explained by another one that is not itself a ghost.
    """
    tau = np.asarray(taus, dtype=float)
    sig = np.asarray(sigmas, dtype=float)
    p = np.asarray(pairs, dtype=np.intp)
    d = np.atleast_2d(np.asarray(predicted, dtype=float))
    h = np.atleast_2d(np.asarray(held, dtype=bool))
    k = d.shape[0]
    count = h.sum(axis=1)
    rms = np.array([float(np.sqrt(np.mean((d[s, h[s]] - tau[h[s]]) ** 2))) if count[s] else 0.0
                    for s in range(k)])
    ghost = np.zeros(k, dtype=bool)
    for g in np.argsort(count, kind="stable"):  # weakest first: a ghost explains nothing
        for s in range(k):
            if s == g or ghost[s] or count[s] == 0 or count[g] == 0:
                continue
            cols = h[g]
            tol = n_sigmas * np.hypot(sig[cols], rms[s])
            if reflected is None or reflected_pairs is None:
                r, rp, rt = tau[cols] - d[s, cols], p[cols], tol
            else:
                r = tau[cols, None] - np.asarray(reflected, dtype=float)[s][cols]  # (k, A)
                rp = np.asarray(reflected_pairs, dtype=np.intp)[cols]
                extra = (slip_s * np.asarray(inverted, dtype=bool)[cols]
                         if inverted is not None else 0.0)
                rt = tol[:, None] + extra
            star = np.bincount(p[cols].reshape(-1)).max(initial=0) == int(cols.sum())
            if star:  # one sensor's delays shifted alike: its timing (speed, position), left
                continue  # to the speed estimate (section 16), not an echo
            ok, n_lags = echo_explained(r, rp, rt, max_lag_s=max_lag_s, max_lags=max_lags,
                                        signed=image_keys)
            if ok and (n_lags > 0 or count[g] < count[s]):
                ghost[g] = True
                break
    return ghost


def surface_alternatives(positions: ArrayLike, sensors: ArrayLike, pairs: ArrayLike, c: float,
                         surface_z: float
                         ) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.bool_],
                                    NDArray[np.bool_]]:
    """Each position's delays of each column as it stands and with one of its two sensors
    swapped for its surface image (``z -> 2 z_s - z``; an image sensor's image is the real one).

    Returns
    -------
    (ndarray, ndarray, ndarray, ndarray)
        Delays ``(K, M, 3)``, s (as it stands, first sensor swapped, second swapped); their
        pairs ``(M, 3, 2)``, a swapped sensor ``k`` numbered ``N + k``; ``(M, 3)`` whether
        that pair has exactly one sensor above the surface (one reflection: the echo is
        sign-inverted); and ``(2 N,)`` whether each sensor index is above the surface.
    """
    x = np.atleast_2d(np.asarray(positions, dtype=float))
    s = np.asarray(sensors, dtype=float)
    i, j = np.asarray(pairs, dtype=np.intp).T
    image = surface_image(s, surface_z)
    r = np.linalg.norm(x[:, None, :] - s[None, :, :], axis=2) / c  # (K, n)
    ri = np.linalg.norm(x[:, None, :] - image[None, :, :], axis=2) / c
    out = np.stack([r[:, i] - r[:, j], ri[:, i] - r[:, j], r[:, i] - ri[:, j]], axis=2)
    up = s[:, 2] > surface_z  # image sensors
    mixed = np.stack([up[i] != up[j], (~up[i]) != up[j], up[i] != (~up[j])], axis=1)
    n = s.shape[0]
    alt_pairs = np.stack([np.column_stack([i, j]), np.column_stack([i + n, j]),
                          np.column_stack([i, j + n])], axis=1)
    return out, alt_pairs, mixed, np.concatenate([up, ~up])


def echo_only_sensors(sensors: ArrayLike, pairs: ArrayLike, held: ArrayLike,
                      surface_z: float) -> NDArray[np.bool_]:
    """Which candidates hear some sensor only through its surface echo.

    A click's surface echo at a sensor follows the direct click there, weaker (a reflection
    coefficient of magnitude at most one, a longer path): where a whale's echo made a delay,
    its direct click did too. A candidate that reads a sensor on its surface image in every
    delay it holds and never on the sensor itself contradicts that; it is the alias of a
    source whose direct delays are read with some sensors swapped for their images
    (``(0, 1)`` as direct-surface, ``(1, 2)`` as surface-direct, ...), which on a
    near-planar array fits the direct delays of a whale hundreds of metres away.

    Parameters
    ----------
    sensors : array_like, shape (N, 3)
        The columns' sensors: the real ones below the surface, their images above it.
    pairs : array_like of int, shape (M, 2)
        Each column's sensor pair (indices into `sensors`).
    held : array_like of bool, shape (K, M)
        The columns each candidate holds.
    surface_z : float
        Height of the sea surface, m.

    Returns
    -------
    ndarray of bool, shape (K,)

    Examples
    --------
    >>> s = np.array([[0.0, 0, -1000], [1000, 0, -1000], [0, 0, 1000], [1000, 0, 1000]])
    >>> pairs = np.array([[0, 1], [0, 3], [2, 1]])  # direct, direct-surface, surface-direct
    >>> echo_only_sensors(s, pairs, [[True, True, False], [False, True, False]], 0.0).tolist()
    [False, True]
    """
    s = np.asarray(sensors, dtype=float)
    p = np.asarray(pairs, dtype=np.intp)
    h = np.atleast_2d(np.asarray(held, dtype=bool))
    up = s[:, 2] > surface_z
    real = np.flatnonzero(~up)
    image = np.flatnonzero(up)
    if image.size == 0:
        return np.zeros(h.shape[0], dtype=bool)
    # the real sensor of each image: the real one at its mirror position
    mirror = surface_image(s[image], surface_z)
    twin = real[np.argmin(np.linalg.norm(mirror[:, None, :] - s[real][None, :, :], axis=2),
                          axis=1)]
    owner = np.arange(s.shape[0])
    owner[image] = twin
    out = np.zeros(h.shape[0], dtype=bool)
    for k in range(h.shape[0]):
        used = p[h[k]].reshape(-1)
        direct = set(owner[used[~up[used]]].tolist())
        echoed = set(owner[used[up[used]]].tolist())
        out[k] = bool(echoed - direct)
    return out
