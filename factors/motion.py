"""Constant-velocity (white-noise-acceleration) motion factors.

A state ``x = [p (d), v (d)]`` stored as a GTSAM ``Vector`` of length ``2 d`` moves between two
times ``dt`` apart as ``x_next = F(dt) x_prev + w`` with

.. math::

    F(dt) = \\begin{bmatrix} I_d & dt\\,I_d \\\\ 0 & I_d \\end{bmatrix},\\qquad
    Q(dt) = q \\begin{bmatrix} dt^3/3\\,I_d & dt^2/2\\,I_d \\\\ dt^2/2\\,I_d & dt\\,I_d
    \\end{bmatrix},

the continuous white-noise-acceleration model (acceleration power spectral density ``q``). For
``d = 1`` the state is a bearing track ``[bearing (rad), bearing rate (rad/s)]`` and the bearing
part of the residual goes through :func:`factors.angles.wrap_angle`, so a track may cross ±180°.

The factor is :func:`linear_constant_velocity_factor` and, set up many at once,
:func:`constant_velocity_steps` (one step of many tracks) and :func:`constant_velocity_chain` (a
whole track): the model is linear, so the factor is a built-in ``JacobianFactor``
  ``[-R F, R] [dx_prev; dx_next] - b`` (``R`` the square-root information of ``Q``) held by a
  ``LinearContainerFactor`` at a linearisation point, evaluated and relinearised in C++.
  ``BetweenFactorVector`` cannot express it (it models ``x_next - x_prev``, not
  ``x_next - F x_prev``). The wrap of the position part is handled when the factor is built:
  ``b = -R wrap(x_next - F x_prev)`` at the linearisation point, which equals the wrapped
  residual as long as the estimate stays within pi of that point.
"""

from __future__ import annotations

import gtsam
import numpy as np

from factors.angles import wrap_angle

__all__ = [
    "constant_velocity_chain",
    "constant_velocity_steps",
    "linear_constant_velocity_factor",
    "transition_matrix",
    "wna_covariance",
    "wna_sqrt_information",
]


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
    if d == 1:  # the bearing tracks' case, called per state: no np.block
        return np.array([[1.0, dt], [0.0, 1.0]])
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
    return block if d == 1 else np.kron(block, np.eye(d))


def wna_sqrt_information(dt: np.ndarray | float, q: float, d: int) -> np.ndarray:
    """Square-root information of the white-noise-acceleration covariance (vectorised over dt).

    Parameters
    ----------
    dt : float or ndarray, shape (...)
        Time steps, s (> 0).
    q : float
        Acceleration power spectral density, unit^2 / s^3 (> 0).
    d : int
        Number of position components.

    Returns
    -------
    R : ndarray, shape (..., 2 d, 2 d)
        Lower block-triangular, ``R^T R = Q(dt)^-1`` (:func:`wna_covariance`): per axis
        ``q^(-1/2) [[sqrt(3) dt^(-3/2), 0], [-3 dt^(-3/2), 2 dt^(-1/2)]]``, the inverse of the
        Cholesky factor of ``Q``.

    Examples
    --------
    >>> R = wna_sqrt_information(2.0, 0.5, 1)
    >>> bool(np.allclose(R.T @ R, np.linalg.inv(wna_covariance(2.0, 0.5, 1))))
    True
    """
    dt_arr = np.asarray(dt, dtype=float)
    if not (np.isfinite(dt_arr).all() and (dt_arr > 0.0).all()):
        raise ValueError("dt must be finite and > 0 seconds")
    d = _check_d(d)
    q = float(q)
    if not np.isfinite(q) or q <= 0.0:
        raise ValueError(f"q (acceleration PSD) must be finite and > 0, got {q!r}")
    s = 1.0 / np.sqrt(q)
    a = s * dt_arr**-1.5
    block = np.zeros(dt_arr.shape + (2, 2))
    block[..., 0, 0] = np.sqrt(3.0) * a  # 1 / L11
    block[..., 1, 0] = -3.0 * a  # -L21 / (L11 L22)
    block[..., 1, 1] = 2.0 * s / np.sqrt(dt_arr)  # 1 / L22
    return _kron_eye(block, d)


def _kron_eye(block: np.ndarray, d: int) -> np.ndarray:
    """``kron(block, I_d)`` over the last two axes of a stack of 2 x 2 blocks."""
    if d == 1:
        return block
    out = block[..., :, None, :, None] * np.eye(d)[:, None, :]
    return out.reshape(block.shape[:-2] + (2 * d, 2 * d))


def _linear_cv(
    key_prev: int, key_next: int, F: np.ndarray, R: np.ndarray, x_prev: np.ndarray,
    x_next: np.ndarray, unit: gtsam.noiseModel.Base, residual: np.ndarray,
) -> gtsam.LinearContainerFactor:
    point = gtsam.Values()
    point.insert(key_prev, x_prev)
    point.insert(key_next, x_next)
    # whitened: R (x_next - F x_prev) = [-R F, R] [x_prev; x_next]; at the point, -b = R e_0
    jf = gtsam.JacobianFactor(key_prev, -R @ F, key_next, R, -R @ residual, unit)
    return gtsam.LinearContainerFactor(jf, point)


def linear_constant_velocity_factor(
    noise: gtsam.noiseModel.Base,
    key_prev: int,
    key_next: int,
    dt: float,
    *,
    estimate_prev: np.ndarray,
    estimate_next: np.ndarray,
    wrap: bool | None = None,
) -> gtsam.LinearContainerFactor:
    """Constant-velocity factor as a built-in linear factor (no Python callback).

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        Gaussian (not robust) noise model of dimension ``2 d``, usually
        ``gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, q, d))``; its square-root
        information ``R`` whitens the factor.
    key_prev, key_next : int
        Keys of the ``Vector(2 d)`` states at ``t`` and ``t + dt``.
    dt : float
        Time step, s (>= 0).
    estimate_prev, estimate_next : ndarray, shape (2 d,), keyword-only
        Linearisation point (current estimates of the two states).
    wrap : bool or None, keyword-only
        Wrap the position part of the residual at the linearisation point into [-pi, pi).
        ``None`` (default) wraps when ``d == 1``.

    Returns
    -------
    gtsam.LinearContainerFactor
        Whitened error ``R (e(x) - e(x_0) + wrap(e(x_0)))`` with ``e(x) = x_next - F x_prev``
        and ``x_0`` the linearisation point: ``R wrap(x_next - F x_prev)`` while the estimate
        stays within pi of ``x_0``.

    Examples
    --------
    >>> noise = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(1.0, 1e-6, 1))
    >>> x0, x1 = np.array([0.1, 0.01]), np.array([0.11, 0.01])
    >>> f = linear_constant_velocity_factor(noise, 0, 1, 1.0, estimate_prev=x0, estimate_next=x1)
    >>> v = gtsam.Values(); v.insert(0, x0); v.insert(1, x1)
    >>> f.error(v) < 1e-20
    True
    """
    if isinstance(noise, gtsam.noiseModel.Robust) or not isinstance(
        noise, gtsam.noiseModel.Gaussian
    ):
        raise ValueError("noise model of a linear factor must be Gaussian (not robust)")
    dim = int(noise.dim())
    if dim < 2 or dim % 2:
        raise ValueError(f"noise model dimension must be even (2 d), got {dim}")
    if int(key_prev) == int(key_next):
        raise ValueError("key_prev and key_next must differ")
    d = dim // 2
    dt = _check_dt(dt, allow_zero=True)
    x_prev = np.asarray(estimate_prev, dtype=float)
    x_next = np.asarray(estimate_next, dtype=float)
    if x_prev.shape != (dim,) or x_next.shape != (dim,):
        raise ValueError(f"estimates must have shape ({dim},), got {x_prev.shape}, {x_next.shape}")
    F = transition_matrix(dt, d)
    residual = x_next - F @ x_prev  # e_0 = x_{k+1} - F x_k at the linearisation point
    if (d == 1) if wrap is None else bool(wrap):
        residual[:d] = wrap_angle(residual[:d])
    return _linear_cv(int(key_prev), int(key_next), F, np.asarray(noise.R()), x_prev, x_next,
                      gtsam.noiseModel.Unit.Create(dim), residual)


def constant_velocity_steps(
    keys_prev: np.ndarray | list[int],
    keys_next: np.ndarray | list[int],
    dt: np.ndarray | float,
    q: float,
    *,
    estimates_prev: np.ndarray,
    estimates_next: np.ndarray,
    wrap: bool | None = None,
) -> gtsam.NonlinearFactorGraph:
    """Many linear constant-velocity factors set up at once (vectorised).

    Parameters
    ----------
    keys_prev, keys_next : array_like of int, shape (m,)
        Keys of the ``Vector(2 d)`` states of each step, at ``t`` and ``t + dt``.
    dt : float or array_like, shape (m,)
        Time step of each factor, s (> 0).
    q : float
        Acceleration power spectral density, unit^2 / s^3 (> 0); the noise of factor ``i`` is
        ``wna_covariance(dt[i], q, d)``.
    estimates_prev, estimates_next : array_like, shape (m, 2 d), keyword-only
        Linearisation point of each factor (estimates of a key that appears twice must agree).
    wrap : bool or None, keyword-only
        As in :func:`linear_constant_velocity_factor`.

    Returns
    -------
    gtsam.NonlinearFactorGraph
        ``m`` ``LinearContainerFactor`` s (add them with ``graph.push_back``): the factors of
        :func:`linear_constant_velocity_factor` with ``Gaussian.Covariance(wna_covariance(...))``
        noise, with ``F`` and ``R`` computed for all steps at once and the containers made in
        C++ (``LinearContainerFactor.ConvertLinearGraph``). Used for a whole track
        (:func:`constant_velocity_chain`) and for one step of many tracks.
    """
    kp = [int(k) for k in np.atleast_1d(keys_prev)]
    kn = [int(k) for k in np.atleast_1d(keys_next)]
    x0 = np.asarray(estimates_prev, dtype=float)
    x1 = np.asarray(estimates_next, dtype=float)
    m = len(kp)
    if len(kn) != m or x0.ndim != 2 or x0.shape[0] != m or x1.shape != x0.shape:
        raise ValueError(f"{m} previous keys, {len(kn)} next keys, estimates of shapes "
                         f"{x0.shape} and {x1.shape}: give one key pair and estimate pair per step")
    if x0.shape[1] < 2 or x0.shape[1] % 2:
        raise ValueError(f"estimates must have shape (m, 2 d), got {x0.shape}")
    if not (np.all(np.isfinite(x0)) and np.all(np.isfinite(x1))):
        raise ValueError("estimates must be finite")
    step = np.broadcast_to(np.asarray(dt, dtype=float), (m,))
    d = x0.shape[1] // 2
    R = wna_sqrt_information(step, q, d)  # (m, 2d, 2d); checks dt > 0 and q > 0
    fb = np.zeros((m, 2, 2))
    fb[:, 0, 0] = fb[:, 1, 1] = 1.0
    fb[:, 0, 1] = step
    F = _kron_eye(fb, d)  # (m, 2d, 2d)
    residual = x1 - (F @ x0[:, :, None])[:, :, 0]  # e_0 = x_{k+1} - F x_k
    if ((d == 1) if wrap is None else bool(wrap)) and not (np.abs(residual[:, :d]) < np.pi).all():
        residual[:, :d] = wrap_angle(residual[:, :d])
    A_prev = -(R @ F)
    b = -(R @ residual[:, :, None])[:, :, 0]
    unit = gtsam.noiseModel.Unit.Create(2 * d)
    linear = gtsam.GaussianFactorGraph()
    point = gtsam.Values()
    first: dict[int, np.ndarray] = {}  # each key's linearisation point: its first estimate
    for i in range(m):
        linear.push_back(gtsam.JacobianFactor(kp[i], A_prev[i], kn[i], R[i], b[i], unit))
        first.setdefault(kp[i], x0[i])
        first.setdefault(kn[i], x1[i])
    for key, x in first.items():
        point.insert(key, x)
    # one LinearContainerFactor per JacobianFactor, each holding its keys' linearisation point
    return gtsam.LinearContainerFactor.ConvertLinearGraph(linear, point)


def constant_velocity_chain(
    keys: np.ndarray | list[int],
    times: np.ndarray,
    q: float,
    *,
    estimates: np.ndarray,
    wrap: bool | None = None,
) -> gtsam.NonlinearFactorGraph:
    """Linear constant-velocity factors along a whole track (vectorised set-up).

    Parameters
    ----------
    keys : array_like of int, shape (n,)
        Keys of the ``Vector(2 d)`` states, in time order.
    times : array_like, shape (n,)
        State times, s, strictly increasing.
    q : float
        Acceleration power spectral density, unit^2 / s^3 (> 0); the noise of step ``k`` is
        ``wna_covariance(times[k+1] - times[k], q, d)``.
    estimates : array_like, shape (n, 2 d), keyword-only
        Current state estimates (the linearisation points).
    wrap : bool or None, keyword-only
        As in :func:`linear_constant_velocity_factor`.

    Returns
    -------
    gtsam.NonlinearFactorGraph
        ``n - 1`` ``LinearContainerFactor`` s (:func:`constant_velocity_steps`); factor ``k``
        ties states ``k`` and ``k + 1``.

    Examples
    --------
    >>> x = np.array([[0.1, 0.01], [0.11, 0.01], [0.12, 0.01]])
    >>> chain = constant_velocity_chain([0, 1, 2], [0.0, 1.0, 2.0], 1e-6, estimates=x)
    >>> v = gtsam.Values()
    >>> for k in range(3):
    ...     v.insert(k, x[k])
    >>> chain.size(), chain.error(v) < 1e-20
    (2, True)
    """
    key_arr = np.asarray(keys)
    t = np.asarray(times, dtype=float)
    x = np.asarray(estimates, dtype=float)
    if t.ndim != 1 or key_arr.shape != t.shape:
        raise ValueError(f"keys and times must be 1-D of equal length, got {key_arr.shape}, {t.shape}")
    if x.ndim != 2 or x.shape[0] != t.size or x.shape[1] < 2 or x.shape[1] % 2:
        raise ValueError(f"estimates must have shape ({t.size}, 2 d), got {x.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("times must be finite")
    if t.size < 2:
        return gtsam.NonlinearFactorGraph()
    dt = np.diff(t)
    if np.any(dt <= 0.0):
        raise ValueError("times must be strictly increasing")
    return constant_velocity_steps(key_arr[:-1], key_arr[1:], dt, q, estimates_prev=x[:-1],
                                   estimates_next=x[1:], wrap=wrap)
