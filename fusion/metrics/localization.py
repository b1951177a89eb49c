"""Scores of position estimates with covariances: normalised estimation error squared (NEES).

A consistent estimator's NEES ``e^T P^-1 e`` is chi-square distributed with as many degrees of
freedom as the state has components; :func:`nees_interval` gives the two-sided interval that a
consistent estimator's NEES (or its mean over runs) falls in with the stated probability.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

__all__ = ["nees", "nees_interval"]


def nees(error: ArrayLike, covariance: ArrayLike) -> NDArray[np.float64] | float:
    """Normalised estimation error squared ``e^T P^-1 e``.

    Parameters
    ----------
    error : array_like, shape (..., d)
        Estimate minus truth (any consistent units).
    covariance : array_like, shape (..., d, d)
        The estimate's covariance, symmetric positive definite, in the squares of those units.

    Returns
    -------
    float or ndarray, shape (...)
        One value per error vector; a float for a single vector.

    Examples
    --------
    >>> nees([2.0, 0.0], [[4.0, 0.0], [0.0, 1.0]])
    1.0
    """
    e = np.asarray(error, dtype=float)
    p = np.asarray(covariance, dtype=float)
    if e.ndim < 1 or p.shape != e.shape + e.shape[-1:]:
        raise ValueError(f"covariance must have shape {e.shape + e.shape[-1:]}, got {p.shape}")
    x = np.linalg.solve(p, e[..., None])[..., 0]
    out = np.sum(e * x, axis=-1)
    return float(out) if out.ndim == 0 else out


def nees_interval(dof: int, *, level: float = 0.95, n_runs: int = 1) -> tuple[float, float]:
    """Two-sided interval of the mean NEES of `n_runs` runs of a consistent estimator.

    Parameters
    ----------
    dof : int
        Components of the error vector (degrees of freedom of one NEES).
    level : float, keyword-only
        Probability of the interval, in (0, 1).
    n_runs : int, keyword-only
        Runs averaged.

    Returns
    -------
    (low, high) : tuple of float
        ``chi2.ppf((1 -+ level)/2, n_runs dof) / n_runs``.

    Examples
    --------
    >>> [round(v, 3) for v in nees_interval(2)]
    [0.051, 7.378]
    """
    if int(dof) != dof or dof < 1 or int(n_runs) != n_runs or n_runs < 1:
        raise ValueError(f"dof and n_runs must be whole numbers >= 1, got {dof!r}, {n_runs!r}")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level!r}")
    lo, hi = chi2.ppf([(1.0 - level) / 2.0, (1.0 + level) / 2.0], int(n_runs) * int(dof))
    return float(lo) / n_runs, float(hi) / n_runs
