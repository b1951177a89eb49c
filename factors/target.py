"""Bearing from a known platform position to an unknown constant-velocity target.

The target state is a GTSAM ``Vector4`` ``s = [x, y, vx, vy]`` (m, m/s; x east, y north). A
platform (own-ship) at the known position ``o = (x_o, y_o)`` measures the true bearing of the
target, clockwise from north::

    beta(s) = atan2(x + vx dt - x_o, y + vy dt - y_o)

where ``dt`` (s, default 0) lets one state at a reference time serve a bearing taken ``dt``
seconds later (the classical single-state target motion analysis). With ``(dx, dy)`` the target
position relative to the platform at the bearing time and ``r^2 = dx^2 + dy^2``::

    d beta / d(x, y)   = [dy, -dx] / r^2
    d beta / d(vx, vy) = dt [dy, -dx] / r^2

This is the bearing factor of the project's design notes ("Factor graphs", bearings-only target
motion analysis). The residual is wrapped by :func:`factors.angles.wrap_angle`, so bearings near
±180° (a target due south) are handled. :func:`target_bearing_batch_factor` is one
``CustomFactor`` with one vector residual for a batch of bearings (one Python callback per
evaluation, whatever the number of bearings; a batch of one is the scalar factor).
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.angles import wrap_angle

__all__ = [
    "target_bearing",
    "target_bearing_batch_factor",
    "target_bearing_jacobian",
]

#: Smallest squared range (m^2) used in the Jacobian, guarding a target on top of the platform.
MIN_RANGE_SQ = 1e-12


def _relative(
    states: NDArray[np.float64], platform_xy: NDArray[np.float64], dt: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    dx = states[..., 0] + states[..., 2] * dt - platform_xy[..., 0]
    dy = states[..., 1] + states[..., 3] * dt - platform_xy[..., 1]
    return dx, dy


def target_bearing(
    states: ArrayLike, platform_xy: ArrayLike, *, dt: ArrayLike = 0.0
) -> NDArray[np.float64]:
    """True bearing of target states from platform positions (vectorised).

    Parameters
    ----------
    states : array_like, shape (..., 4)
        Target states ``[x, y, vx, vy]``, m and m/s.
    platform_xy : array_like, shape (..., 2)
        Platform positions ``[x, y]``, m, broadcast against `states`.
    dt : float or array_like, shape (...), keyword-only
        Time from the state's epoch to the bearing time, s.

    Returns
    -------
    ndarray, shape (...)
        Bearing, rad, clockwise from north, in ``[-pi, pi)``.

    Examples
    --------
    >>> float(np.degrees(target_bearing([100.0, 0.0, 0.0, 0.0], [0.0, 0.0])))
    90.0
    """
    s = np.asarray(states, dtype=float)
    o = np.asarray(platform_xy, dtype=float)
    dx, dy = _relative(s, o, np.asarray(dt, dtype=float))
    return np.asarray(wrap_angle(np.arctan2(dx, dy)), dtype=float)  # beta = atan2(dx, dy)


def target_bearing_jacobian(
    states: ArrayLike, platform_xy: ArrayLike, *, dt: ArrayLike = 0.0
) -> NDArray[np.float64]:
    """Derivative of :func:`target_bearing` with respect to the state (vectorised).

    `states`, `platform_xy` and `dt` as in :func:`target_bearing`.

    Returns
    -------
    ndarray, shape (..., 4)
        ``d beta / d s``, rad/m and rad/(m/s).
    """
    s = np.asarray(states, dtype=float)
    o = np.asarray(platform_xy, dtype=float)
    dt_arr = np.asarray(dt, dtype=float)
    dx, dy = _relative(s, o, dt_arr)
    r2 = np.maximum(dx * dx + dy * dy, MIN_RANGE_SQ)
    d_dx = dy / r2  # d atan2(dx, dy) / d dx
    d_dy = -dx / r2  # d atan2(dx, dy) / d dy
    dt_b = np.broadcast_to(dt_arr, d_dx.shape)
    return np.stack([d_dx, d_dy, d_dx * dt_b, d_dy * dt_b], axis=-1)


def target_bearing_batch_factor(
    noise: gtsam.noiseModel.Base,
    keys: int | Sequence[int],
    platform_xy: ArrayLike,
    bearings: ArrayLike,
    *,
    dt: ArrayLike = 0.0,
) -> gtsam.CustomFactor:
    """One factor for a batch of true bearings of a target: one vector residual.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        Noise model of dimension ``m`` (the number of bearings), rad, e.g.
        ``gtsam.noiseModel.Isotropic.Sigma(m, sigma)``. For a robust loss per bearing wrap it in
        ``gtsam.noiseModel.Robust`` with an m-estimator created with ``ReweightScheme.Scalar``
        (the default ``Block`` scheme weights the whole vector by its norm).
    keys : int or sequence of int
        Key of the ``Vector4`` target state ``[x, y, vx, vy]`` of every bearing (one key, the
        classical single-state problem) or one key per bearing (length m, keys may repeat).
    platform_xy : array_like, shape (m, 2)
        Platform (own-ship) position at each bearing time, m.
    bearings : array_like, shape (m,)
        Measured true bearings, rad, clockwise from north.
    dt : float or array_like, shape (m,), keyword-only
        Bearing time minus the epoch of the bearing's state, s.

    Returns
    -------
    gtsam.CustomFactor
        Error ``e_j = wrap(beta_j(s) - bearings[j])``, rad, shape (m,); the Jacobian for a key
        is (m, 4) with the rows :func:`target_bearing_jacobian` of its bearings (zeros on the
        rows of other keys).

    Raises
    ------
    ValueError
        If the noise dimension is not m or an input has the wrong shape or is not finite.

    Notes
    -----
    The same cost as ``m`` one-bearing factors with the same 1-D noise (diagonal, or robust
    with scalar reweighting), evaluated in one Python callback; the bearing and its Jacobian are
    those of the module docstring, computed for all bearings at once.

    Examples
    --------
    >>> noise = gtsam.noiseModel.Isotropic.Sigma(2, 0.01)
    >>> f = target_bearing_batch_factor(noise, 0, [[0.0, 0.0], [0.0, 200.0]],
    ...                                 [np.pi / 2, 3 * np.pi / 4], dt=[0.0, 100.0])
    >>> v = gtsam.Values(); v.insert(0, np.array([100.0, 0.0, 0.0, 1.0]))
    >>> bool(np.all(np.abs(f.unwhitenedError(v)) < 1e-12))
    True
    """
    z = np.asarray(bearings, dtype=float)
    if z.ndim != 1 or z.size == 0 or not np.all(np.isfinite(z)):
        raise ValueError(f"bearings must be a non-empty 1-D array of finite values (rad), "
                         f"got shape {z.shape}")
    m = z.size
    if int(noise.dim()) != m:
        raise ValueError(f"noise model dimension {noise.dim()} differs from the {m} bearings")
    o = np.asarray(platform_xy, dtype=float)
    if o.shape != (m, 2) or not np.all(np.isfinite(o)):
        raise ValueError(f"platform_xy must be finite with shape ({m}, 2) (m), got {o.shape}")
    dt_arr = np.broadcast_to(np.asarray(dt, dtype=float), (m,)).copy()
    if not np.all(np.isfinite(dt_arr)):
        raise ValueError("dt must be finite (s)")
    if np.ndim(keys) == 0:
        key_list = [int(keys)] * m
    else:
        key_list = [int(k) for k in keys]
        if len(key_list) != m:
            raise ValueError(f"{len(key_list)} keys for {m} bearings: give one key or one per "
                             f"bearing")
    unique = list(dict.fromkeys(key_list))
    slot = {k: i for i, k in enumerate(unique)}
    which = np.array([slot[k] for k in key_list])
    single = len(unique) == 1
    rows = [np.flatnonzero(which == i) for i in range(len(unique))]

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        if single:
            s = values.atVector(unique[0])
            dx = s[0] + s[2] * dt_arr - o[:, 0]
            dy = s[1] + s[3] * dt_arr - o[:, 1]
        else:
            s = np.array([values.atVector(k) for k in unique])[which]  # state of each bearing
            dx = s[:, 0] + s[:, 2] * dt_arr - o[:, 0]
            dy = s[:, 1] + s[:, 3] * dt_arr - o[:, 1]
        error = np.asarray(wrap_angle(np.arctan2(dx, dy) - z))  # e = wrap(beta(s) - z)
        if jacobians is not None:
            r2 = np.maximum(dx * dx + dy * dy, MIN_RANGE_SQ)
            gx, gy = dy / r2, -dx / r2  # d beta / d (x, y)
            H = np.column_stack([gx, gy, gx * dt_arr, gy * dt_arr])
            if single:
                jacobians[0] = H
            else:
                for i, r in enumerate(rows):
                    Hi = np.zeros((m, 4))
                    Hi[r] = H[r]
                    jacobians[i] = Hi
        return error

    return gtsam.CustomFactor(noise, unique, error_func)
