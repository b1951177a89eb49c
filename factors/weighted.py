"""Association-weighted factor: any factor's whitened error scaled by ``sqrt(w)``.

When the origin of a measurement is uncertain (two tracks crossing, several sources sharing
TDOAs) the measurement enters every candidate's graph, each copy weighted by the probability
``w`` that it belongs there. The weight lives in an array that the caller owns and updates
between solves (an expectation-maximisation loop); the factor reads it on every evaluation, so
the graph need not be rebuilt. With ``e_w`` the inner factor's whitened error and ``A_w`` its
whitened Jacobian the wrapped factor has

.. math::

    e = \\sqrt{w}\\, e_w, \\qquad H = \\sqrt{w}\\, A_w,

so its cost is ``w`` times the inner cost: the weighted least squares of the M-step of
expectation-maximisation data association (design notes, "Association-weighted factor").

The vector form gives every row of a vector inner factor its own weight (``index`` a sequence):
a batch of shared measurements of one track in one factor, ``e_i = sqrt(w_i) e_w,i``.

The tangent dimension of each key is read from the inner factor's own linearisation the first
time the wrapper is linearised (never from the whole graph's values), so building and first
linearising a graph of many weighted factors costs the same as any later linearisation.
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["sqrt_weights", "weighted_factor"]


def sqrt_weights(weights: ArrayLike) -> NDArray[np.float64]:
    """Scale of an association-weighted error: ``sqrt(max(w, 0))`` per weight.

    Parameters
    ----------
    weights : array_like, shape (m,) or ()
        Association weights ``w`` (probabilities; a negative weight counts as 0).

    Returns
    -------
    ndarray, same shape
        ``sqrt(max(w, 0))``, the factor of the whitened error and Jacobian, so that the cost is
        ``w`` times the inner cost.

    Examples
    --------
    >>> sqrt_weights([0.25, 1.0, -0.5])
    array([0.5, 1. , 0. ])
    """
    return np.sqrt(np.maximum(weights, 0.0))  # e = sqrt(w) e_w, cost w |e_w|^2


def _key_dims(linear: gtsam.GaussianFactor, keys: list[int], n_cols: int) -> list[int]:
    """Tangent dimension of each key of a linearised factor."""
    if len(keys) == 1:
        return [n_cols]
    graph = gtsam.GaussianFactorGraph()
    graph.push_back(linear)
    gradient = graph.gradientAtZero()  # one vector per key, of the key's tangent dimension
    return [int(gradient.at(k).shape[0]) for k in keys]


def weighted_factor(
    factor: gtsam.NonlinearFactor,
    weights: np.ndarray,
    index: int | Sequence[int],
    *,
    noise: gtsam.noiseModel.Base | None = None,
) -> gtsam.CustomFactor:
    """Wrap a factor so that its cost is scaled by association weights read live from an array.

    Parameters
    ----------
    factor : gtsam.NonlinearFactor
        The inner factor: a ``CustomFactor`` or any built-in noise-model factor with a Gaussian
        (not robust) noise model, or a ``LinearContainerFactor``; its whitened error and
        Jacobian are used.
    weights : ndarray of float64, shape (n,)
        The weight array, read (not copied) at every evaluation; the caller updates it in
        place between solves. Weights are association probabilities in [0, 1]; a negative
        value counts as 0.
    index : int or sequence of int
        Which entry of `weights` belongs to this factor (one weight for the whole factor), or
        one entry per row of the inner error (length ``factor.dim()``; the vector form).
    noise : gtsam.noiseModel.Base, optional, keyword-only
        Noise model of the wrapper, applied to the already whitened, weighted error; default
        ``noiseModel.Unit`` of the inner dimension. Pass a ``noiseModel.Robust`` around a unit
        model for a robust weighted factor (with ``ReweightScheme.Scalar`` for a loss per row).

    Returns
    -------
    gtsam.CustomFactor
        On the inner factor's keys; error ``sqrt(w) e_w`` (whitened, dimensionless), shape
        ``(factor.dim(),)``; Jacobians ``sqrt(w) A_w``.

    Examples
    --------
    >>> w = np.array([0.25])
    >>> inner = gtsam.PriorFactorVector(0, np.zeros(2), gtsam.noiseModel.Isotropic.Sigma(2, 0.5))
    >>> f = weighted_factor(inner, w, 0)
    >>> v = gtsam.Values(); v.insert(0, np.array([1.0, 0.0]))
    >>> round(f.error(v) / inner.error(v), 12)
    0.25
    """
    if not isinstance(weights, np.ndarray) or weights.ndim != 1 or weights.dtype != np.float64:
        raise ValueError(
            "weights must be a 1-D float64 numpy array (updated in place by the caller)"
        )
    dim = int(factor.dim())
    idx = np.atleast_1d(np.asarray(index))
    if idx.dtype == bool or not np.issubdtype(idx.dtype, np.integer) or idx.ndim != 1:
        raise ValueError(f"index must be an integer or a 1-D sequence of integers, got {index!r}")
    if np.ndim(index) == 1 and idx.size != dim:
        raise ValueError(f"{idx.size} weight indices for a factor of dimension {dim}: give one "
                         f"index or one per row")
    if np.any((idx < 0) | (idx >= weights.shape[0])):
        raise ValueError(f"index {index!r} is out of range for {weights.shape[0]} weights")
    idx = idx.astype(np.intp)
    inner_noise = factor.noiseModel() if hasattr(factor, "noiseModel") else None
    if isinstance(inner_noise, gtsam.noiseModel.Robust):
        raise ValueError("the inner factor must have a Gaussian noise model; put a robust "
                         "model on the wrapper through noise=")
    if noise is None:
        noise = gtsam.noiseModel.Unit.Create(dim)
    elif int(noise.dim()) != dim:
        raise ValueError(f"noise model dimension {noise.dim()} differs from the factor's {dim}")
    keys = list(factor.keys())
    has_error = hasattr(factor, "whitenedError")
    dims: list[int] = []  # tangent dimension of each key, from the first linearisation

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        scale = sqrt_weights(weights[idx])  # sqrt(w), one or one per row
        if jacobians is None and has_error:
            return scale * factor.whitenedError(values)  # e = sqrt(w) e_w
        linear = factor.linearize(values)
        A, b = linear.jacobian()  # whitened: A_w, b = -e_w
        if jacobians is None:
            return -scale * b
        if not dims:
            dims.extend(_key_dims(linear, keys, A.shape[1]))
        A = A * scale[:, None] if scale.size > 1 else scale * A
        start = 0
        for i, d in enumerate(dims):
            jacobians[i] = A[:, start : start + d]  # H = sqrt(w) A_w
            start += d
        return -scale * b

    return gtsam.CustomFactor(noise, keys, error_func)
