"""What a TMA estimate knows about range: noise-fitted covariance scale and range intervals.

:func:`noise_inflation` scales the graph's covariance to the bearing residuals actually seen (their
variance and their correlation from one bearing to the next), never below the given noise;
:func:`range_interval` turns a position covariance into a range interval along the line of sight,
symmetric in log-range so that it stays positive and widens upwards as bearings-only range
errors do.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import norm

__all__ = ["UNBOUNDED", "noise_inflation", "range_interval"]

#: Upper end of a range interval without an upper bound, m (the project's largest plausible
#: input value, so that every CSV reader takes it).
UNBOUNDED = 1e12


def noise_inflation(
    residuals: ArrayLike, sigma: float, *, n_params: int = 4
) -> tuple[float, float, float]:
    """Covariance scale from the bearing residuals at the solution.

    Parameters
    ----------
    residuals : array_like, shape (n,)
        Bearing residuals in time order, rad.
    sigma : float
        Bearing noise standard deviation the graph used, rad.
    n_params : int, keyword-only
        Parameters fitted (4 for one constant-velocity state).

    Returns
    -------
    scale : float
        ``max(1, (s^2 / sigma^2) (1 + rho) / (1 - rho))``, the factor on the covariance.
    rho : float
        Lag-one autocorrelation of the residuals, clipped to [0, 0.99].
    s : float
        Residual standard deviation ``sqrt(RSS / (n - n_params))``, rad.

    Notes
    -----
    Least squares with noise of unknown variance: the covariance ``sigma^2 (J^T J)^-1`` is
    rescaled by the residual variance ``s^2 = RSS / (n - p)`` (the usual estimate of the noise
    variance). Residuals correlated from one bearing to the next, as a camera's are (a detector
    box wanders for seconds), carry less information than their number says: for an AR(1)
    sequence of lag-one correlation ``rho`` the variance of a mean grows by ``(1 + rho) /
    (1 - rho)``, the inverse of the effective-sample-size ratio, and so does the covariance.
    The scale never shrinks the covariance below the one of the given noise.
    """
    r = np.asarray(residuals, float)
    n = r.size
    if n <= n_params + 1 or not sigma > 0:
        return 1.0, 0.0, float(sigma)
    s2 = float(np.sum(r * r) / (n - n_params))
    c = r - r.mean()
    den = float(np.sum(c * c))
    rho = float(np.sum(c[1:] * c[:-1]) / den) if den > 0 else 0.0
    rho = float(np.clip(rho, 0.0, 0.99))
    scale = max(1.0, s2 / sigma**2 * (1.0 + rho) / (1.0 - rho))
    return float(scale), rho, float(np.sqrt(s2))


def range_interval(
    states: ArrayLike, covariances: ArrayLike, own: ArrayLike, *, level: float = 0.95
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Range interval at each time from the position covariance along the line of sight.

    Parameters
    ----------
    states : array_like, shape (n, 4)
        Target ``[x, y, vx, vy]``, m and m/s.
    covariances : array_like, shape (n, 4, 4)
        State covariances (already scaled), m^2 ...
    own : array_like, shape (n, 2)
        Own-ship positions, m.
    level : float, keyword-only
        Two-sided coverage of the interval, in (0, 1).

    Returns
    -------
    low, high : ndarray, shape (n,)
        ``r exp(-/+ z s)``, m, with ``s = sigma_r / r`` and ``z`` the normal quantile of
        ``(1 + level) / 2``; ``high`` at most :data:`UNBOUNDED` (1e12 m: no upper bound);
        ``0`` and :data:`UNBOUNDED` when ``s`` is infinite or not a number.
    rel_sigma : ndarray, shape (n,)
        ``sigma_r / r``, ``sigma_r = sqrt(u^T P u)`` with ``u`` the unit line of sight and ``P``
        the position block.

    Notes
    -----
    First-order propagation: ``r = |p - o|`` has gradient ``u`` in the position, so ``var r =
    u^T P u``; to first order ``var ln r = var r / r^2``, and the interval is symmetric in
    ``ln r``.
    """
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    x = np.asarray(states, float)
    P = np.asarray(covariances, float)
    d = x[:, :2] - np.asarray(own, float)
    r = np.hypot(d[:, 0], d[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        u = d / r[:, None]
        var = np.einsum("ni,nij,nj->n", u, P[:, :2, :2], u)
        rel = np.sqrt(np.maximum(var, 0.0)) / r
    rel = np.where(np.isfinite(rel), rel, np.inf)
    z = float(norm.ppf(0.5 + level / 2.0))
    with np.errstate(over="ignore"):
        low = np.where(np.isfinite(rel), r * np.exp(-z * rel), 0.0)
        high = np.where(np.isfinite(rel), r * np.exp(np.minimum(z * rel, 60.0)), UNBOUNDED)
    return low, np.minimum(high, UNBOUNDED), rel
