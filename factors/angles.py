"""Angle wrapping for the factors: one rule for every angular residual.

Angles inside the factors are radians. A residual between two angles is wrapped into the
half-open interval ``[-pi, pi)`` by :func:`wrap_angle`, so that a bearing just west of south and
one just east of it are a small residual apart. The linear factor forms do not wrap at every
evaluation; they move a measured angle onto the branch nearest the current estimate when the
factor is built (:func:`nearest_branch`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["nearest_branch", "wrap_angle"]

_TWO_PI = 2.0 * np.pi


def wrap_angle(a: ArrayLike) -> NDArray[np.float64] | float:
    """Wrap angles to the half-open interval ``[-pi, pi)``.

    Parameters
    ----------
    a : float or array_like
        Angle(s), rad, any branch.

    Returns
    -------
    float or ndarray
        Same shape as `a`, rad, in ``[-pi, pi)``; a float for scalar input.

    Notes
    -----
    ``mod(a + pi, 2 pi) - pi`` alone can return ``+pi``: for ``a`` just below ``-pi`` the sum
    ``a + pi`` is a tiny negative number and ``mod`` rounds ``2 pi - tiny`` up to ``2 pi``.
    Such results are moved to ``-pi``, the other end of the same rounding interval.

    Examples
    --------
    >>> wrap_angle(3 * np.pi / 2)
    -1.5707963267948966
    >>> wrap_angle(np.pi)
    -3.141592653589793
    >>> wrap_angle(np.nextafter(-np.pi, -4.0))
    -3.141592653589793
    """
    if type(a) is float or type(a) is np.float64:  # one angle: the same arithmetic on a float
        w = (a + np.pi) % _TWO_PI - np.pi  # Python's float % rounds as np.mod does
        return float(w - _TWO_PI if w >= np.pi else w)
    out = np.mod(np.asarray(a, dtype=float) + np.pi, _TWO_PI) - np.pi
    out = np.where(out >= np.pi, out - _TWO_PI, out)  # mod rounded up to 2 pi: -pi, not +pi
    return float(out) if out.ndim == 0 else out


def nearest_branch(angle: ArrayLike, reference: ArrayLike) -> NDArray[np.float64] | float:
    """Angle(s) moved by whole turns onto the branch nearest `reference`.

    Parameters
    ----------
    angle : float or array_like
        Angle(s), rad, any branch.
    reference : float or array_like
        Reference angle(s), rad, broadcast against `angle` (e.g. the current estimate).

    Returns
    -------
    float or ndarray
        ``reference + wrap_angle(angle - reference)``, rad: the same direction as `angle`,
        within ``[-pi, pi)`` of `reference`.

    Examples
    --------
    >>> round(nearest_branch(-np.pi + 0.1, np.pi - 0.1), 12)
    3.24159265359
    """
    ref = np.asarray(reference, dtype=float)
    out = ref + wrap_angle(np.asarray(angle, dtype=float) - ref)
    return float(out) if np.ndim(out) == 0 else out
