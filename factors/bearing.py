"""Bearing measurement factors on a bearing-track state.

The state is a GTSAM ``Vector`` whose first component is the bearing (rad), e.g. the
``[bearing, bearing rate]`` state of a bearing-time track. A measured bearing ``z`` gives the
residual ``e = wrap(x[0] - z)`` (rad), wrapped into [-pi, pi) by
:func:`factors.angles.wrap_angle` so that a track and its measurement on either side of ±180°
are a small residual apart. The Jacobian is the row ``[1, 0, ..., 0]``.

:func:`linear_bearing_factors` (and :func:`linear_bearing_factor`, one of them) build it as
built-in ``PriorFactorVector`` factors, evaluated and linearised in C++: apart from the wrap the
model is linear. The wrap is handled by moving each
  measurement onto the branch nearest the estimate the factor is built at
  (:func:`factors.angles.nearest_branch`); the caller rebuilds (re-centres) the factors if the
  solution moves a residual out of [-pi, pi).
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.angles import nearest_branch

__all__ = [
    "linear_bearing_factor",
    "linear_bearing_factors",
    "state_bearing_noise",
]


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
    ``x[0] - z'_j`` equals the wrapped residual ``wrap(x[0] - z_j)`` of the module docstring
    as long as the estimate stays within pi of the branch chosen here, evaluated and
    linearised in C++ (no Python callback). A caller whose solution
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
