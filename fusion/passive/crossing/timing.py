"""Equation (2) of *Target Track Crossing Prediction/Detection*: when two bearing lines cross.

Two tracks with bearings ``B0_a``, ``B0_b`` (rad) at a common reference time and bearing rates
``B'_a``, ``B'_b`` (rad/s) follow straight lines in bearing and time; they meet after

    t_c = (B0_b - B0_a) / (B'_a - B'_b)

seconds (equation (2); a negative ``t_c`` is a crossing already past). The bearing difference is
taken on the circle, wrapped to ``[-pi, pi)``, so that tracks on either side of the +-180 deg
(or 0/360 deg) wrap cross where they meet and tracks on opposite bearings get a distant ``t_c``.
This module is the one home of that equation: the bearing trackers and smoothers of
:mod:`fusion.passive.smoothing` use it, and the crossing detector's screening of all pairs at once
and its intervals (:func:`fusion.passive.crossing.pairs.pairs_in_reach`,
:func:`~fusion.passive.crossing.pairs.pair_intervals`) evaluate its terms.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import wrap_angle

__all__ = ["crossing_time", "crossing_time_terms"]

_TWO_PI = 2.0 * np.pi


def crossing_time_terms(
    bearing_a: ArrayLike, rate_a: ArrayLike, bearing_b: ArrayLike, rate_b: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator of equation (2) for bearings already in ``[-pi, pi]``.

    Parameters
    ----------
    bearing_a, bearing_b : float or array_like
        Bearings at the reference time, rad, each in ``[-pi, pi]`` (e.g. from
        :func:`fusion.geometry.wrap_angle`).
    rate_a, rate_b : float or array_like
        Bearing rates, rad/s.

    Returns
    -------
    num : ndarray
        ``wrap(B0_b - B0_a)``, rad, in ``[-pi, pi)``.
    den : ndarray
        ``B'_a - B'_b``, rad/s.

    Notes
    -----
    With both bearings in ``[-pi, pi]`` their difference lies in ``[-2 pi, 2 pi]``, so adding or
    taking away one turn wraps it; a caller that screens many pairs can test
    ``|num| <= horizon |den|`` before dividing.

    Examples
    --------
    >>> num, den = crossing_time_terms(3.0, 0.0, -3.0, -0.01)
    >>> round(float(num), 6), float(den)
    (0.283185, 0.01)
    """
    num = np.asarray(bearing_b, dtype=float) - np.asarray(bearing_a, dtype=float)  # B0_b - B0_a
    num = num - _TWO_PI * (num >= np.pi)
    num = num + _TWO_PI * (num < -np.pi)  # now in [-pi, pi)
    return num, np.asarray(rate_a, dtype=float) - np.asarray(rate_b, dtype=float)  # B'_a - B'_b


def crossing_time(
    bearing_a: ArrayLike, rate_a: ArrayLike, bearing_b: ArrayLike, rate_b: ArrayLike
) -> NDArray[np.float64] | float:
    """Time until two straight bearing tracks cross, s, relative to the time of the bearings.

    Parameters
    ----------
    bearing_a, bearing_b : float or array_like
        Bearings at a common reference time, rad, any branch (the intercepts ``B0`` of
        equation (1)).
    rate_a, rate_b : float or array_like
        Bearing rates, rad/s (``B'``).

    Returns
    -------
    float or ndarray
        ``t_c`` of equation (2), s, broadcast over the inputs (a float for scalar inputs);
        ``inf`` for parallel tracks.

    Notes
    -----
    "Target Track Crossing Prediction/Detection", equation (2), with the bearing difference
    wrapped (:func:`crossing_time_terms`). Inequalities (3) (``0 < t_c <= J K``, predicted) and
    (4) (``-J K <= t_c <= 0``, detected) are the callers' tests.

    Examples
    --------
    >>> round(crossing_time(0.0, 0.01, 0.1, 0.0), 9)
    10.0
    >>> round(crossing_time(np.pi - 0.05, 0.01, -np.pi + 0.05, 0.0), 9)  # across the wrap
    10.0
    >>> crossing_time(0.0, 0.01, 0.1, 0.01)
    inf
    """
    num, den = crossing_time_terms(wrap_angle(bearing_a), rate_a, wrap_angle(bearing_b), rate_b)
    with np.errstate(divide="ignore", invalid="ignore"):
        tc = np.where(den != 0.0, num / np.where(den != 0.0, den, 1.0), np.inf)  # equation (2)
    return float(tc) if tc.ndim == 0 else tc
