"""Confidence interval of a crossing time: Fieller's interval of the root of a fitted line.

The crossing time of two bearing tracks is the root of the difference of their window lines
(*Target Track Crossing Prediction/Detection*, equation (2)); with the lines' covariance
(:class:`fusion.passive.line_fit.LineStats`) the root gets Fieller's interval at a Student-t
quantile with Welch-Satterthwaite degrees of freedom. Importable from
:mod:`fusion.passive.crossing.pairs` too, which applies it to pairs of tracks.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["crossing_time_interval", "f_ratio_quantile", "t_quantile", "welch_dof"]

_MAX_DOF = 1000


@lru_cache(maxsize=8)
def _t_table(level: float) -> NDArray[np.float64]:
    """Two-sided Student-t quantiles at `level` for 0 .. _MAX_DOF degrees of freedom."""
    from scipy import stats as _stats  # imported when needed: ~0.8 s CPU (see curve._f_table)

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
    # fmax/fmin: NaN -> 1, like nan_to_num(nan=1) then clip, in two passes fewer
    d = np.fmin(np.fmax(np.floor(np.asarray(dof, dtype=float)), 1.0), float(_MAX_DOF))
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


def welch_dof(
    var_a: ArrayLike, var_b: ArrayLike, dof_a: ArrayLike, dof_b: ArrayLike
) -> NDArray[np.float64]:
    """Welch-Satterthwaite degrees of freedom of a sum of two variance estimates.

    Parameters
    ----------
    var_a, var_b : array_like, shape (p,)
        The two variance estimates (any unit, the same for both).
    dof_a, dof_b : array_like, shape (p,)
        Their degrees of freedom.

    Returns
    -------
    ndarray, shape (p,)
        ``(v_a + v_b)^2 / (v_a^2 / dof_a + v_b^2 / dof_b)``; ``min(dof_a, dof_b)`` where both
        variances are 0.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(var_a + var_b > 0,
                        (var_a + var_b) ** 2 / (var_a * var_a / dof_a + var_b * var_b / dof_b),
                        np.minimum(dof_a, dof_b))


def f_ratio_quantile(alpha: float, dof_num: ArrayLike, dof_den: ArrayLike) -> NDArray[np.float64]:
    """Upper `alpha` quantile of F(dof_num, dof_den) (the variance-ratio test), elementwise.

    Degrees of freedom are rounded down and clipped to 1 .. 1000 (so the quantile errs wide).
    """
    dn = np.clip(np.floor(np.nan_to_num(np.asarray(dof_num, dtype=float), nan=1.0)), 1, _MAX_DOF)
    dd = np.clip(np.floor(np.nan_to_num(np.asarray(dof_den, dtype=float), nan=1.0)), 1, _MAX_DOF)
    key = dn * (_MAX_DOF + 1) + dd
    uniq, inv = np.unique(key, return_inverse=True)
    from scipy import stats as _stats  # imported when needed (see _t_table)

    q = _stats.f.isf(alpha, uniq // (_MAX_DOF + 1), uniq % (_MAX_DOF + 1))
    return q[inv].reshape(dn.shape)
