"""Scores of position estimates: fixes matched to true sources, and the NEES of covariances.

:func:`match_fixes` counts, for one processing window, the true sources with a reported fix
within a distance and the reported fixes farther than that from every true source (false); the
localization benchmarks sum them over windows.

A consistent estimator's NEES ``e^T P^-1 e`` is chi-square distributed with as many degrees of
freedom as the state has components; :func:`nees_interval` gives the two-sided interval that a
consistent estimator's NEES (or its mean over runs) falls in with the stated probability.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

__all__ = ["FixMatch", "match_fixes", "nees", "nees_interval", "true_positions", "true_tdoas"]


class FixMatch(NamedTuple):
    """One window's fixes against its true sources (:func:`match_fixes`)."""

    found: int
    """True sources with a fix within the distance."""
    false: int
    """Fixes farther than the distance from every true source."""
    errors_m: tuple[float, ...]
    """Distance of each fix to its nearest true source, for fixes nearer than `near_m`."""


def match_fixes(truth: ArrayLike, fixes: ArrayLike, *, within_m: float = 10.0,
                near_m: float = 50.0) -> FixMatch:
    """Match a window's reported fixes to its true source positions.

    Parameters
    ----------
    truth : array_like, shape (n, 3)
        True positions, m.
    fixes : array_like, shape (k, 3)
        Reported positions, m (k may be 0).
    within_m : float, optional
        A true source is found, and a fix is not false, within this distance.
    near_m : float, optional
        Fixes nearer than this to a true source give an error.

    Examples
    --------
    >>> match_fixes([[0, 0, -900], [100, 0, -900]], [[3, 4, -900], [500, 0, -900]])
    FixMatch(found=1, false=1, errors_m=(5.0,))
    """
    t = np.asarray(truth, dtype=float).reshape(-1, 3)
    f = np.asarray(fixes, dtype=float).reshape(-1, 3)
    if not t.size or not f.size:
        return FixMatch(0, int(f.shape[0]) if not t.size else 0, ())
    d = np.linalg.norm(t[:, None, :] - f[None, :, :], axis=2)  # (n, k)
    nearest = d.min(axis=0)
    return FixMatch(int(np.sum(d.min(axis=1) < within_m)), int(np.sum(nearest > within_m)),
                    tuple(float(v) for v in nearest[nearest < near_m]))


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


def true_positions(truth: dict, t_mid: float) -> NDArray[np.float64]:
    """Each whale of a ``fusion simulate clicks`` truth where it emitted the click whose mean
    arrival over the sensors is at `t_mid` (interpolated between its emissions), (n, 3) m."""
    out = []
    for s in truth["sources"]:
        mean = np.asarray(s["arrival_times"], dtype=float).mean(axis=1)
        pos = np.asarray(s["positions"], dtype=float)
        order = np.argsort(mean)
        out.append([np.interp(t_mid, mean[order], pos[order, k]) for k in range(3)])
    return np.array(out, dtype=float).reshape(-1, 3)


def true_tdoas(truth: dict, i: int, j: int, t: float) -> NDArray[np.float64]:
    """Each whale's direct-path ``t_i - t_j`` with its arrival at sensor i at time `t`, s."""
    out = []
    for s in truth["sources"]:
        arr = np.asarray(s["arrival_times"], dtype=float)
        o = np.argsort(arr[:, i])
        out.append(np.interp(t, arr[o, i], arr[o, i] - arr[o, j]))
    return np.array(out, dtype=float)
