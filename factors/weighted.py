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
"""

from __future__ import annotations

import gtsam
import numpy as np

__all__ = ["weighted_factor"]


def weighted_factor(
    factor: gtsam.NoiseModelFactor,
    weights: np.ndarray,
    index: int,
    *,
    noise: gtsam.noiseModel.Base | None = None,
) -> gtsam.CustomFactor:
    """Wrap a factor so that its cost is scaled by ``weights[index]``.

    Parameters
    ----------
    factor : gtsam.NoiseModelFactor
        The inner factor (a ``CustomFactor`` or any built-in noise-model factor) with a
        Gaussian (not robust) noise model; its whitened error and Jacobian are used.
    weights : ndarray of float64, shape (n,)
        The weight array, read (not copied) at every evaluation; the caller updates it in
        place between solves. Weights are association probabilities in [0, 1]; a negative
        value counts as 0.
    index : int
        Which entry of `weights` belongs to this factor.
    noise : gtsam.noiseModel.Base, optional, keyword-only
        Noise model of the wrapper, applied to the already whitened, weighted error; default
        ``noiseModel.Unit`` of the inner dimension. Pass a ``noiseModel.Robust`` around a unit
        model for a robust weighted factor.

    Returns
    -------
    gtsam.CustomFactor
        On the inner factor's keys; error ``sqrt(w) e_w`` (whitened, dimensionless), shape
        ``(factor.dim(),)``.

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
    if isinstance(index, bool) or int(index) != index or not 0 <= int(index) < weights.shape[0]:
        raise ValueError(f"index {index!r} is out of range for {weights.shape[0]} weights")
    index = int(index)
    inner_noise = factor.noiseModel()
    if isinstance(inner_noise, gtsam.noiseModel.Robust):
        raise ValueError("the inner factor must have a Gaussian noise model; put a robust "
                         "model on the wrapper through noise=")
    dim = int(factor.dim())
    if noise is None:
        noise = gtsam.noiseModel.Unit.Create(dim)
    elif int(noise.dim()) != dim:
        raise ValueError(f"noise model dimension {noise.dim()} differs from the factor's {dim}")
    keys = list(factor.keys())
    dims: list[int] = []  # tangent dimension of each key, learnt at the first linearization

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        scale = np.sqrt(max(float(weights[index]), 0.0))
        if jacobians is None:
            return scale * factor.whitenedError(values)  # e = sqrt(w) e_w
        A, b = factor.linearize(values).jacobian()  # whitened: A_w, b = -e_w
        if not dims:
            vv = values.zeroVectors()
            dims.extend(int(vv.at(k).shape[0]) for k in keys)
        start = 0
        for i, d in enumerate(dims):
            jacobians[i] = scale * A[:, start : start + d]  # H = sqrt(w) A_w
            start += d
        return -scale * b

    return gtsam.CustomFactor(noise, keys, error_func)
