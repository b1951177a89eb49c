"""Checks of custom factors: analytic Jacobians against central differences.

Jacobians are taken with respect to each variable's local (tangent) coordinates: the plain
derivative for vector-valued variables (``Vector``, ``Point2``, ``Point3``, ``double``), the
derivative along ``retract`` for manifold variables (``Pose2``, ``Pose3``, ``Rot2``, ``Rot3``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gtsam
import numpy as np
from numpy.typing import NDArray

__all__ = ["analytic_jacobians", "assert_jacobians", "numerical_jacobians"]

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


def numerical_jacobians(
    factor: gtsam.NonlinearFactor, values: gtsam.Values, *, delta: float = 1e-6
) -> list[NDArray[np.float64]]:
    """Central-difference Jacobians of ``factor.unwhitenedError`` at `values`.

    Parameters
    ----------
    factor : gtsam.NoiseModelFactor
        The factor (e.g. a ``gtsam.CustomFactor``).
    values : gtsam.Values
        Linearization point; must hold every key of the factor.
    delta : float, optional
        Step in each local coordinate.

    Returns
    -------
    list of ndarray, each shape (error_dim, variable_dim)
        One Jacobian per key, in ``factor.keys()`` order.
    """
    jacs = []
    for key in factor.keys():
        kind, x0 = _getter(values, key)
        n = _dim(kind, x0)
        cols = []
        for k in range(n):
            d = np.zeros(n)
            d[k] = delta
            ep = factor.unwhitenedError(_perturbed(values, key, kind, x0, d))
            em = factor.unwhitenedError(_perturbed(values, key, kind, x0, -d))
            cols.append((np.asarray(ep) - np.asarray(em)) / (2.0 * delta))
        jacs.append(np.column_stack(cols))
    return jacs


def analytic_jacobians(
    factor: gtsam.NonlinearFactor, values: gtsam.Values
) -> list[NDArray[np.float64]]:
    """The factor's own (unwhitened) Jacobians at `values`, in ``factor.keys()`` order.

    Obtained from ``factor.linearize`` (which whitens them) by undoing the whitening of a
    Gaussian noise model: ``H = W^-1 A`` with ``W`` the square-root information matrix.
    """
    lin = factor.linearize(values)
    a, _ = lin.jacobian()
    noise = factor.noiseModel()
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
) -> None:
    """Assert that a factor's analytic Jacobians match central differences.

    Use a plain Gaussian noise model on the factor under test (a robust model reweights the
    linearization, so the unwhitening above would not recover the raw Jacobian).

    Raises
    ------
    AssertionError
        Naming the key and showing both matrices when they differ beyond the tolerances.
    """
    num = numerical_jacobians(factor, values, delta=delta)
    ana = analytic_jacobians(factor, values)
    for key, hn, ha in zip(factor.keys(), num, ana, strict=True):
        np.testing.assert_allclose(
            ha, hn, rtol=rtol, atol=atol,
            err_msg=f"Jacobian for key {gtsam.DefaultKeyFormatter(key)} differs from central differences",
        )


def error_function(factor: gtsam.NonlinearFactor) -> Callable[[gtsam.Values], NDArray[np.float64]]:
    """Convenience: the factor's unwhitened error as a function of Values."""
    return lambda values: np.asarray(factor.unwhitenedError(values))
