"""Constant-velocity (white-noise-acceleration) motion factors.

A state ``x = [p (d), v (d)]`` stored as a GTSAM ``Vector`` of length ``2 d`` moves between two
times ``dt`` apart as ``x_next = F(dt) x_prev + w`` with

.. math::

    F(dt) = \\begin{bmatrix} I_d & dt\\,I_d \\\\ 0 & I_d \\end{bmatrix},\\qquad
    Q(dt) = q \\begin{bmatrix} dt^3/3\\,I_d & dt^2/2\\,I_d \\\\ dt^2/2\\,I_d & dt\\,I_d
    \\end{bmatrix},

the continuous white-noise-acceleration model (acceleration power spectral density ``q``). For
``d = 1`` the state is a bearing track ``[bearing (rad), bearing rate (rad/s)]`` and the bearing
part of the residual goes through :func:`fusion.geometry.wrap_angle`, so a track may cross ±180°.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusion.geometry import wrap_angle

__all__ = ["constant_velocity_factor", "transition_matrix", "wna_covariance"]


def _check_dt(dt: float, *, allow_zero: bool) -> float:
    dt = float(dt)
    if not np.isfinite(dt) or dt < 0.0 or (dt == 0.0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"dt must be finite and {bound} seconds, got {dt!r}")
    return dt


def _check_d(d: int) -> int:
    if isinstance(d, bool) or int(d) != d or int(d) < 1:
        raise ValueError(f"d (spatial dimension) must be a positive integer, got {d!r}")
    return int(d)


def transition_matrix(dt: float, d: int) -> np.ndarray:
    """Constant-velocity transition matrix.

    Parameters
    ----------
    dt : float
        Time step, s (>= 0).
    d : int
        Number of position components (1 for a bearing track, 2 for a plane).

    Returns
    -------
    F : ndarray, shape (2 d, 2 d)
        ``[[I, dt I], [0, I]]``.
    """
    dt = _check_dt(dt, allow_zero=True)
    d = _check_d(d)
    eye = np.eye(d)
    return np.block([[eye, dt * eye], [np.zeros((d, d)), eye]])


def wna_covariance(dt: float, q: float, d: int) -> np.ndarray:
    """White-noise-acceleration process covariance for a state ``[p (d), v (d)]``.

    Parameters
    ----------
    dt : float
        Time step, s (> 0).
    q : float
        Acceleration power spectral density, (unit/s^2)^2 / Hz, i.e. unit^2 / s^3 (> 0). For a
        bearing track the unit is the radian.
    d : int
        Number of position components.

    Returns
    -------
    Q : ndarray, shape (2 d, 2 d)
        ``q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]]``, symmetric positive definite.

    Notes
    -----
    The discretisation of a continuous constant-velocity model driven by white acceleration noise
    (Bar-Shalom, Li and Kirubarajan, *Estimation with Applications to Tracking and Navigation*,
    sec. 6.2.2); the same matrix as ``filterpy.common.Q_continuous_white_noise(dim=2)``.

    Examples
    --------
    >>> wna_covariance(2.0, 1.0, 1)
    array([[2.66666667, 2.        ],
           [2.        , 2.        ]])
    """
    dt = _check_dt(dt, allow_zero=False)
    d = _check_d(d)
    q = float(q)
    if not np.isfinite(q) or q <= 0.0:
        raise ValueError(f"q (acceleration PSD) must be finite and > 0, got {q!r}")
    block = q * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
    return np.kron(block, np.eye(d))


def constant_velocity_factor(
    noise: gtsam.noiseModel.Base,
    key_prev: int,
    key_next: int,
    dt: float,
    *,
    wrap: bool | None = None,
) -> gtsam.CustomFactor:
    """Factor between two constant-velocity states ``dt`` seconds apart.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        Noise model of dimension ``2 d``, usually
        ``gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, q, d))``; ``d`` is inferred
        from ``noise.dim()``.
    key_prev, key_next : int
        Keys of the ``Vector(2 d)`` states at ``t`` and ``t + dt``.
    dt : float
        Time step, s (>= 0).
    wrap : bool or None, keyword-only
        Wrap the position part of the residual into [-pi, pi). ``None`` (default) wraps when
        ``d == 1`` (a bearing track ``[bearing, rate]``).

    Returns
    -------
    gtsam.CustomFactor
        Error ``e = x_next - F(dt) x_prev`` (units of the state), shape (2 d,); Jacobians
        ``-F`` with respect to ``x_prev`` and ``I`` with respect to ``x_next``.

    Examples
    --------
    >>> noise = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(1.0, 1e-6, 1))
    >>> f = constant_velocity_factor(noise, 0, 1, 1.0)
    >>> v = gtsam.Values(); v.insert(0, np.array([0.1, 0.01])); v.insert(1, np.array([0.11, 0.01]))
    >>> float(np.abs(f.unwhitenedError(v)).max()) < 1e-12
    True
    """
    dim = int(noise.dim())
    if dim < 2 or dim % 2:
        raise ValueError(f"noise model dimension must be even (2 d), got {dim}")
    d = dim // 2
    dt = _check_dt(dt, allow_zero=True)
    F = transition_matrix(dt, d)
    minus_F = -F
    eye = np.eye(dim)
    do_wrap = (d == 1) if wrap is None else bool(wrap)

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        k_prev, k_next = this.keys()[0], this.keys()[1]
        x_prev = values.atVector(k_prev)
        x_next = values.atVector(k_next)
        error = x_next - F @ x_prev  # e = x_{k+1} - F x_k
        if do_wrap:
            error[:d] = wrap_angle(error[:d])
        if jacobians is not None:
            jacobians[0] = minus_F
            jacobians[1] = eye
        return error

    return gtsam.CustomFactor(noise, [int(key_prev), int(key_next)], error_func)
