"""Bearing measurement factor on a bearing-track state.

The state is a GTSAM ``Vector`` whose first component is the bearing (rad), e.g. the
``[bearing, bearing rate]`` state of a bearing-time track. A measured bearing ``z`` gives the
residual ``e = wrap(x[0] - z)`` (rad), wrapped into [-pi, pi) by
:func:`fusion.geometry.wrap_angle` so that a track and its measurement on either side of ±180°
are a small residual apart. The Jacobian is the row ``[1, 0, ..., 0]``.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusion.geometry import wrap_angle

__all__ = ["bearing_factor"]


def bearing_factor(noise: gtsam.noiseModel.Base, key: int, bearing: float) -> gtsam.CustomFactor:
    """Factor tying the first component of a ``Vector`` state to a measured bearing.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        One-dimensional noise model, rad (e.g. ``Isotropic.Sigma(1, sigma)`` or a
        ``noiseModel.Robust`` around it for outlier bearings).
    key : int
        Key of the ``Vector(n)`` state, ``n >= 1``, whose component 0 is the bearing, rad.
    bearing : float
        Measured bearing, rad (any branch; it is wrapped).

    Returns
    -------
    gtsam.CustomFactor
        Error ``wrap(x[0] - bearing)``, shape (1,), rad; Jacobian ``[[1, 0, ..., 0]]``, shape
        (1, n).

    Notes
    -----
    The bearing measurement factor of the project's bearing-rate graph (design notes, "Factor
    graphs": bearing measurement factors, wrap angles).

    Examples
    --------
    >>> f = bearing_factor(gtsam.noiseModel.Isotropic.Sigma(1, 0.01), 0, np.pi - 0.01)
    >>> v = gtsam.Values(); v.insert(0, np.array([-np.pi + 0.01, 0.0]))
    >>> round(float(f.unwhitenedError(v)[0]), 6)
    0.02
    """
    if int(noise.dim()) != 1:
        raise ValueError(f"bearing noise model must be 1-dimensional, got dimension {noise.dim()}")
    z = float(bearing)
    if not np.isfinite(z):
        raise ValueError(f"bearing must be finite, got {bearing!r}")

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        x = values.atVector(this.keys()[0])
        error = np.array([wrap_angle(x[0] - z)])  # e = wrap(theta - z), rad
        if jacobians is not None:
            H = np.zeros((1, x.shape[0]))
            H[0, 0] = 1.0
            jacobians[0] = H
        return error

    return gtsam.CustomFactor(noise, [int(key)], error_func)
