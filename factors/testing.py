"""Checks of custom factors: analytic Jacobians against central differences.

Jacobians are taken with respect to each variable's local (tangent) coordinates: the plain
derivative for vector-valued variables (``Vector``, ``Point2``, ``Point3``, ``double``), the
derivative along ``retract`` for manifold variables (``Pose2``, ``Pose3``, ``Rot2``, ``Rot3``).

Two error functions can be differentiated: the unwhitened error of a noise-model factor (the
default), or the whitened error ``-b`` of the factor's own linearisation (``whitened=True``;
automatic for factors without an unwhitened error, such as ``LinearContainerFactor``, and the
way to check factors whose noise model cannot be unwhitened, such as a ``Diagonal`` with zero
precisions). With a robust noise model the unwhitened Jacobian is taken from a copy of the
factor with the robust model's Gaussian part (``cloneWithNewNoiseModel``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gtsam
import numpy as np
from numpy.typing import NDArray

__all__ = ["analytic_jacobians", "assert_jacobians", "error_function", "numerical_jacobians"]

_MANIFOLD_ACCESSORS = ("atPose2", "atPose3", "atRot2", "atRot3")


def _getter(values: gtsam.Values, key: int) -> tuple[str, Any]:
    """The accessor that reads `key` and its value."""
    for name in _MANIFOLD_ACCESSORS:
        try:
            return name, getattr(values, name)(key)
        except (RuntimeError, TypeError):
            continue
    try:
        return "atVector", np.asarray(values.atVector(key), dtype=float)
    except (RuntimeError, TypeError):
        pass
    try:
        return "atDouble", float(values.atDouble(key))
    except (RuntimeError, TypeError):
        raise ValueError(f"key {key}: unsupported variable type for numerical Jacobians") from None


def _perturbed(values: gtsam.Values, key: int, kind: str, x0: Any, d: NDArray[np.float64]):
    out = gtsam.Values(values)
    if kind == "atVector":
        out.update(key, x0 + d)
    elif kind == "atDouble":
        out.update(key, float(x0 + d[0]))
    else:
        out.update(key, x0.retract(d))
    return out


def _dim(kind: str, x0: Any) -> int:
    if kind == "atVector":
        return int(np.size(x0))
    if kind == "atDouble":
        return 1
    return int(len(x0.localCoordinates(x0)))


def _use_whitened(factor: gtsam.NonlinearFactor, whitened: bool | None) -> bool:
    if whitened is None:
        return not hasattr(factor, "unwhitenedError")
    return bool(whitened)


def _whitened_error(factor: gtsam.NonlinearFactor, values: gtsam.Values) -> NDArray[np.float64]:
    if hasattr(factor, "whitenedError"):
        return np.asarray(factor.whitenedError(values))
    return -np.asarray(factor.linearize(values).jacobian()[1])  # b = -e_w


def numerical_jacobians(
    factor: gtsam.NonlinearFactor,
    values: gtsam.Values,
    *,
    delta: float = 1e-6,
    whitened: bool | None = None,
) -> list[NDArray[np.float64]]:
    """Central-difference Jacobians of the factor's error at `values`.

    Parameters
    ----------
    factor : gtsam.NonlinearFactor
        The factor (e.g. a ``gtsam.CustomFactor``).
    values : gtsam.Values
        Linearization point; must hold every key of the factor.
    delta : float, optional
        Step in each local coordinate.
    whitened : bool or None, optional, keyword-only
        Differentiate the whitened error instead of ``unwhitenedError``; ``None`` (default)
        does so only for factors without an unwhitened error.

    Returns
    -------
    list of ndarray, each shape (error_dim, variable_dim)
        One Jacobian per key, in ``factor.keys()`` order.
    """
    if _use_whitened(factor, whitened):
        def err(v: gtsam.Values) -> NDArray[np.float64]:
            return _whitened_error(factor, v)
    else:
        def err(v: gtsam.Values) -> NDArray[np.float64]:
            return np.asarray(factor.unwhitenedError(v))
    jacs = []
    for key in factor.keys():
        kind, x0 = _getter(values, key)
        n = _dim(kind, x0)
        cols = []
        for k in range(n):
            d = np.zeros(n)
            d[k] = delta
            ep = err(_perturbed(values, key, kind, x0, d))
            em = err(_perturbed(values, key, kind, x0, -d))
            cols.append((ep - em) / (2.0 * delta))
        jacs.append(np.column_stack(cols))
    return jacs


def analytic_jacobians(
    factor: gtsam.NonlinearFactor, values: gtsam.Values, *, whitened: bool | None = None
) -> list[NDArray[np.float64]]:
    """The factor's own Jacobians at `values`, in ``factor.keys()`` order.

    Obtained from ``factor.linearize``, which whitens them. Unless `whitened` (see
    :func:`numerical_jacobians`), the whitening of the Gaussian noise model is undone:
    ``H = W^-1 A`` with ``W`` the square-root information matrix.

    Raises
    ------
    ValueError
        If the factor has a robust noise model (its linearisation is reweighted).
    """
    noise = factor.noiseModel() if hasattr(factor, "noiseModel") else None
    if isinstance(noise, gtsam.noiseModel.Robust):
        raise ValueError("a robust noise model reweights the Jacobians: check the factor with "
                         "the robust model's Gaussian part (noise.noise())")
    if _use_whitened(factor, whitened):
        h_all, _ = factor.linearize(values).jacobian()
    else:
        a, _ = factor.linearize(values).jacobian()
        m = noise.dim()
        w = np.column_stack([noise.whiten(e) for e in np.eye(m)])
        h_all = np.linalg.solve(w, a)
    out, col = [], 0
    for key in factor.keys():
        kind, x0 = _getter(values, key)
        n = _dim(kind, x0)
        out.append(h_all[:, col : col + n])
        col += n
    return out


def assert_jacobians(
    factor: gtsam.NonlinearFactor,
    values: gtsam.Values,
    *,
    delta: float = 1e-6,
    rtol: float = 1e-5,
    atol: float = 1e-8,
    whitened: bool | None = None,
) -> None:
    """Assert that a factor's analytic Jacobians match central differences.

    Use a Gaussian (not robust) noise model on the factor under test: a robust model
    reweights the linearisation (:func:`analytic_jacobians` raises ``ValueError``).

    Raises
    ------
    AssertionError
        Naming the key and showing both matrices when they differ beyond the tolerances.
    """
    num = numerical_jacobians(factor, values, delta=delta, whitened=whitened)
    ana = analytic_jacobians(factor, values, whitened=whitened)
    for key, hn, ha in zip(factor.keys(), num, ana, strict=True):
        np.testing.assert_allclose(
            ha, hn, rtol=rtol, atol=atol,
            err_msg=f"Jacobian for key {gtsam.DefaultKeyFormatter(key)} differs from central differences",
        )


def error_function(
    factor: gtsam.NonlinearFactor, *, whitened: bool | None = None
) -> Callable[[gtsam.Values], NDArray[np.float64]]:
    """Convenience: the factor's (unwhitened, or whitened, as above) error as a function of Values."""
    if _use_whitened(factor, whitened):
        return lambda values: _whitened_error(factor, values)
    return lambda values: np.asarray(factor.unwhitenedError(values))
