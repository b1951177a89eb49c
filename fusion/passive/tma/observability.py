"""Observability of range in bearings-only TMA: own-ship manoeuvre and relative range sigma.

Range is unobservable when the own-ship keeps a constant velocity (the target's relative track
can be scaled without changing a single bearing). :func:`ownship_manoeuvre` measures the
own-ship's departure from a straight constant-speed track; :func:`range_rel_sigma` the relative
standard deviation of range that the bearings alone give (an ill-conditioned information matrix
in the range direction).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from factors.target import target_bearing_jacobian

__all__ = ["ownship_manoeuvre", "range_rel_sigma"]


def ownship_manoeuvre(times: ArrayLike, xy: ArrayLike) -> float:
    """Largest departure of a track from its least-squares constant-velocity fit.

    Parameters
    ----------
    times : array_like, shape (n,)
        Times, s.
    xy : array_like, shape (n, 2)
        Positions, m.

    Returns
    -------
    float
        ``max_k |xy_k - (a + b t_k)|``, m, with ``a, b`` (2-vectors) fitted by least squares.
        Zero for a constant-velocity track.
    """
    t = np.asarray(times, dtype=float)
    p = np.asarray(xy, dtype=float)
    A = np.column_stack([np.ones_like(t), t - t.mean()])
    coef, *_ = np.linalg.lstsq(A, p, rcond=None)
    return float(np.max(np.linalg.norm(p - A @ coef, axis=1)))


def range_rel_sigma(
    state: ArrayLike, own_ref: ArrayLike, dt: ArrayLike, own: ArrayLike, bearing_sigma: float
) -> float:
    """Relative range standard deviation that bearings alone give a constant-velocity target.

    Parameters
    ----------
    state : array_like, shape (4,)
        Target ``[x, y, vx, vy]`` at the reference time, m and m/s.
    own_ref : array_like, shape (2,)
        Own-ship position at the reference time, m.
    dt : array_like, shape (n,)
        Bearing times minus the reference time, s.
    own : array_like, shape (n, 2)
        Own-ship positions at the bearing times, m.
    bearing_sigma : float
        Bearing standard deviation, rad.

    Returns
    -------
    float
        ``sqrt(u^T P u) / r`` at the reference time, with ``u`` the unit line of sight, ``r`` the
        range and ``P`` the position block of the Cramér-Rao bound ``(J^T J)^-1`` of the
        whitened bearing Jacobian ``J`` (n, 4); ``inf`` when ``J`` is rank deficient (a
        constant-velocity own-ship: scaling the relative track leaves every bearing unchanged).

    Notes
    -----
    Uses no prior and no process noise, so it measures what the bearings themselves say about
    range: the "information matrix ill-conditioned in range" test.
    """
    s = np.asarray(state, dtype=float)
    o = np.asarray(own, dtype=float)
    J = target_bearing_jacobian(s, o, dt=np.asarray(dt, dtype=float)) / bearing_sigma
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    los = s[:2] - np.asarray(own_ref, dtype=float)
    r = float(np.hypot(*los))
    if sv.size < 4 or sv[-1] <= sv[0] * 1e-10 or r == 0.0:
        return float("inf")
    u = np.concatenate([los / r, [0.0, 0.0]])
    return float(np.linalg.norm((vt @ u) / sv)) / r  # sqrt(u^T V S^-2 V^T u) / r
