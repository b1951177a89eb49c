"""Bearing measurement factors on a bearing-track state.

The state is a GTSAM ``Vector`` whose first component is the bearing (rad), e.g. the
``[bearing, bearing rate]`` state of a bearing-time track. A measured bearing ``z`` gives the
residual ``e = wrap(x[0] - z)`` (rad), wrapped into [-pi, pi) by
:func:`factors.angles.wrap_angle` so that a track and its measurement on either side of ±180°
are a small residual apart. The Jacobian is the row ``[1, 0, ..., 0]``. Three forms:

- :func:`bearing_factor` -- one ``CustomFactor`` per bearing (the reference form; a Python
  callback per bearing and evaluation).
- :func:`bearing_batch_factor` -- one ``CustomFactor`` for a batch of bearings of one track's
  states, one vector residual (one callback per batch).
- :func:`linear_bearing_factors` -- built-in ``PriorFactorVector`` factors, evaluated and
  linearised in C++: apart from the wrap the model is linear. The wrap is handled by moving each
  measurement onto the branch nearest the estimate the factor is built at
  (:func:`factors.angles.nearest_branch`); the caller rebuilds (re-centres) the factors if the
  solution moves a residual out of [-pi, pi).
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.angles import nearest_branch, wrap_angle

__all__ = [
    "bearing_batch_factor",
    "bearing_factor",
    "linear_bearing_factor",
    "linear_bearing_factors",
    "state_bearing_noise",
]


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


def _check_bearings(keys: Sequence[int], bearings: ArrayLike) -> tuple[list[int], NDArray]:
    z = np.asarray(bearings, dtype=float)
    if z.ndim != 1 or z.size == 0:
        raise ValueError(f"bearings must be a non-empty 1-D array, got shape {z.shape}")
    if not np.all(np.isfinite(z)):
        raise ValueError("bearings must be finite")
    key_list = [int(k) for k in keys]
    if len(key_list) != z.size:
        raise ValueError(f"{len(key_list)} keys for {z.size} bearings: give one key per bearing")
    return key_list, z


def bearing_batch_factor(
    noise: gtsam.noiseModel.Base, keys: Sequence[int], bearings: ArrayLike
) -> gtsam.CustomFactor:
    """One factor for a batch of bearings of one track's states: one vector residual.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        Noise model of dimension ``m`` (the number of bearings), rad: e.g.
        ``Isotropic.Sigma(m, sigma)``. For a robust loss per bearing use ``noiseModel.Robust``
        with an m-estimator created with ``ReweightScheme.Scalar`` (the default ``Block``
        scheme weights the whole vector by its norm, a different model).
    keys : sequence of int, length m
        Key of the state each bearing belongs to (``Vector(n)`` states, component 0 the
        bearing, rad); keys may repeat (several bearings of one state). The factor's keys are
        the distinct keys in order of first appearance.
    bearings : array_like, shape (m,)
        Measured bearings, rad (any branch; residuals are wrapped).

    Returns
    -------
    gtsam.CustomFactor
        Error ``e_j = wrap(x_{keys[j]}[0] - bearings[j])``, shape (m,), rad; the Jacobian for a
        key has a 1 in column 0 of the rows of its bearings, zeros elsewhere.

    Notes
    -----
    The same cost as ``m`` :func:`bearing_factor` factors with the same 1-D noise (with a
    diagonal noise model, or a robust one with scalar reweighting), evaluated in one Python
    callback instead of ``m``. Keep a batch to a few neighbouring states: a factor couples all
    its keys in the elimination.

    Examples
    --------
    >>> f = bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(3, 0.01), [0, 0, 1],
    ...                          [0.1, 0.12, np.pi - 0.01])
    >>> v = gtsam.Values(); v.insert(0, np.array([0.11, 0.0])); v.insert(1, np.array([-np.pi, 0.0]))
    >>> np.round(f.unwhitenedError(v), 6)
    array([ 0.01, -0.01,  0.01])
    """
    key_list, z = _check_bearings(keys, bearings)
    m = z.size
    if int(noise.dim()) != m:
        raise ValueError(f"noise model dimension {noise.dim()} differs from the {m} bearings")
    unique = list(dict.fromkeys(key_list))
    slot = {k: i for i, k in enumerate(unique)}
    which = np.array([slot[k] for k in key_list])  # distinct-key index of each bearing
    rows = [np.flatnonzero(which == i) for i in range(len(unique))]

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        states = [values.atVector(k) for k in unique]
        theta = np.array([s[0] for s in states])[which]
        error = np.asarray(wrap_angle(theta - z))  # e_j = wrap(theta_{k_j} - z_j), rad
        if jacobians is not None:
            for i, s in enumerate(states):
                H = np.zeros((m, s.shape[0]))
                H[rows[i], 0] = 1.0  # d e_j / d x_k = [1, 0, ...] on the rows of key k
                jacobians[i] = H
        return error

    return gtsam.CustomFactor(noise, unique, error_func)


def state_bearing_noise(noise: gtsam.noiseModel.Base, dim: int) -> gtsam.noiseModel.Base:
    """The ``dim``-dimensional noise model of a bearing on component 0 of a ``Vector(dim)``.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        One-dimensional bearing noise model, rad: a Gaussian model (``Isotropic``, ``Diagonal``,
        ``Gaussian`` of dimension 1) or a ``noiseModel.Robust`` around one.
    dim : int
        Dimension of the state (>= 1).

    Returns
    -------
    gtsam.noiseModel.Base
        ``Diagonal.Precisions([1 / sigma^2, 0, ..., 0])``, robust with the same m-estimator
        when `noise` is robust: the whitened error of a ``PriorFactorVector`` is then
        ``[(x[0] - z) / sigma, 0, ..., 0]``, whatever the other components of its mean.
    """
    if int(noise.dim()) != 1:
        raise ValueError(f"bearing noise model must be 1-dimensional, got dimension {noise.dim()}")
    dim = int(dim)
    if dim < 1:
        raise ValueError(f"state dimension must be >= 1, got {dim}")
    robust = isinstance(noise, gtsam.noiseModel.Robust)
    base = noise.noise() if robust else noise
    if not isinstance(base, gtsam.noiseModel.Gaussian):
        raise ValueError("bearing noise model must be Gaussian or Robust around a Gaussian one")
    sigma = float(base.sigmas()[0])
    if not (np.isfinite(sigma) and sigma > 0.0):
        raise ValueError(f"bearing sigma must be finite and > 0 rad, got {sigma!r}")
    precisions = np.zeros(dim)
    precisions[0] = 1.0 / sigma**2  # only the bearing component is measured
    out = gtsam.noiseModel.Diagonal.Precisions(precisions)
    return gtsam.noiseModel.Robust.Create(noise.robust(), out) if robust else out


def linear_bearing_factors(
    noise: gtsam.noiseModel.Base,
    keys: Sequence[int],
    bearings: ArrayLike,
    *,
    estimates: ArrayLike,
) -> list[gtsam.PriorFactorVector]:
    """Built-in linear bearing factors, each bearing re-centred on the current estimate.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        One-dimensional bearing noise model, rad (Gaussian, or ``noiseModel.Robust`` around a
        Gaussian one: the robust loss acts on each bearing alone); or, for many calls, the
        ``n``-dimensional model :func:`state_bearing_noise` made from it once.
    keys : sequence of int, length m
        Key of the ``Vector(n)`` state of each bearing (component 0 the bearing, rad).
    bearings : array_like, shape (m,)
        Measured bearings, rad, any branch.
    estimates : array_like, shape (m, n)
        Current estimate of each bearing's state (rows may repeat); sets the branch of the
        bearing and fills the unmeasured components of the factor's mean.

    Returns
    -------
    list of gtsam.PriorFactorVector, length m
        Factor ``j`` has mean ``[z'_j, estimates[j, 1:]]`` with
        ``z'_j = nearest_branch(z_j, estimates[j, 0])`` and noise
        ``state_bearing_noise(noise, n)``; its whitened error is
        ``[(x[0] - z'_j) / sigma, 0, ..., 0]``.

    Notes
    -----
    ``x[0] - z'_j`` equals the wrapped residual ``wrap(x[0] - z_j)`` of :func:`bearing_factor`
    as long as the estimate stays within pi of the branch chosen here; the factor is then the
    same factor, evaluated and linearised in C++ (no Python callback). A caller whose solution
    moves a residual outside ``[-pi, pi)`` rebuilds the factors at that solution.

    Examples
    --------
    >>> fs = linear_bearing_factors(gtsam.noiseModel.Isotropic.Sigma(1, 0.01), [0],
    ...                             [np.pi - 0.01], estimates=[[-np.pi + 0.01, 0.0]])
    >>> v = gtsam.Values(); v.insert(0, np.array([-np.pi + 0.01, 0.0]))
    >>> round(float(fs[0].whitenedError(v)[0]), 6)
    2.0
    """
    key_list, z = _check_bearings(keys, bearings)
    x = np.asarray(estimates, dtype=float)
    if x.ndim != 2 or x.shape[0] != z.size or x.shape[1] < 1 or not np.isfinite(x).all():
        raise ValueError(f"estimates must be finite with shape ({z.size}, n), got {x.shape}")
    n = x.shape[1]
    state_noise = noise if n > 1 and int(noise.dim()) == n else state_bearing_noise(noise, n)
    means = x.copy()
    means[:, 0] = nearest_branch(z, x[:, 0])  # z' = theta_hat + wrap(z - theta_hat)
    return [gtsam.PriorFactorVector(k, mu, state_noise)
            for k, mu in zip(key_list, means, strict=True)]


def linear_bearing_factor(
    noise: gtsam.noiseModel.Base, key: int, bearing: float, *, estimate: ArrayLike
) -> gtsam.PriorFactorVector:
    """One built-in linear bearing factor (see :func:`linear_bearing_factors`).

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        One-dimensional bearing noise model, rad.
    key : int
        Key of the ``Vector(n)`` state.
    bearing : float
        Measured bearing, rad.
    estimate : array_like, shape (n,)
        Current estimate of the state.

    Returns
    -------
    gtsam.PriorFactorVector
    """
    x = np.asarray(estimate, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"estimate must be 1-D (one state), got shape {x.shape}")
    return linear_bearing_factors(noise, [key], [bearing], estimates=x[None, :])[0]
