"""TDOA factory functions on a click source position: all of a source's TDOAs, weighted.

Typed factories around closures (:class:`gtsam.CustomFactor`) of the model of
:mod:`factors.tdoa.model`, residual ``(d_i - d_j)/c + b_i - b_j - tau`` in seconds (predicted
minus measured). The module notes of :mod:`factors.tdoa` give the Jacobians; these names are
importable from there too.
"""

from __future__ import annotations

from collections.abc import Callable

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.tdoa.model import (
    MIN_RANGE,
    TdoaModel,
    check_speed,
    predicted_tdoas,  # noqa: F401  (the examples use it)
)
from factors.weighted import sqrt_weights

try:  # what np.einsum calls without `optimize`, minus its dispatch (the same arithmetic)
    from numpy._core.multiarray import c_einsum as _einsum
except ImportError:  # pragma: no cover - another numpy layout
    _einsum = np.einsum

__all__ = ["tdoa_vector_factor", "weighted_tdoa_vector_factor"]


def _speed(c: float | None, speed_key: int | None) -> float:
    """The fixed speed (NaN when unknown); exactly one of `c` and `speed_key` is given."""
    if (c is None) == (speed_key is None):
        raise ValueError("give exactly one of c (a fixed sound speed) and speed_key (unknown speed)")
    return float("nan") if c is None else check_speed(c)


def _keys(key: int, speed_key: int | None, clock_key: int | None) -> list[int]:
    keys = [int(key)]
    keys += [int(k) for k in (speed_key, clock_key) if k is not None]
    if len(set(keys)) != len(keys):
        raise ValueError(f"position, speed and clock keys must differ, got {keys}")
    return keys


def _model_error(
    model: TdoaModel, c_fixed: float, has_speed: bool, has_clock: bool
) -> Callable[[gtsam.CustomFactor, gtsam.Values, bool], tuple]:
    """Evaluate (r, [dr/dp, dr/dc?, dr/db?]) from Values: the part shared by every form."""

    def evaluate(this: gtsam.CustomFactor, values: gtsam.Values, jac: bool) -> tuple:
        keys = this.keys()
        p = values.atPoint3(keys[0])
        c = float(values.atVector(keys[1])[0]) if has_speed else c_fixed
        b = None
        if has_clock:
            b = values.atVector(keys[-1])
            if b.shape[0] != model.n:
                raise ValueError(f"clock variable has {b.shape[0]} offsets for {model.n} sensors")
        r, h_p, h_c = model.residual(p, c, b, jacobian=jac)
        if not jac:
            return r, None
        blocks = [h_p]
        if has_speed:
            blocks.append(h_c)
        if has_clock:
            blocks.append(model.incidence)
        return r, blocks

    return evaluate


def _factor(
    noise: gtsam.noiseModel.Base,
    key: int,
    model: TdoaModel,
    c: float | None,
    speed_key: int | None,
    clock_key: int | None,
) -> gtsam.CustomFactor:
    if int(noise.dim()) != model.m:
        raise ValueError(f"noise model dimension {noise.dim()} differs from the {model.m} TDOAs")
    c_fixed = _speed(c, speed_key)
    keys = _keys(key, speed_key, clock_key)
    evaluate = _model_error(model, c_fixed, speed_key is not None, clock_key is not None)

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        r, blocks = evaluate(this, values, jacobians is not None)
        if jacobians is not None:
            for k, h in enumerate(blocks):
                jacobians[k] = h
        return r

    return gtsam.CustomFactor(noise, keys, error_func)


def tdoa_vector_factor(
    noise: gtsam.noiseModel.Base,
    key: int,
    sensors: ArrayLike,
    pairs: ArrayLike,
    taus: ArrayLike,
    *,
    c: float | None = None,
    speed_key: int | None = None,
    clock_key: int | None = None,
) -> gtsam.CustomFactor:
    """One factor carrying all TDOAs of a source as one m-vector residual (the fast form).

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        Noise model of dimension m, s (e.g. ``Diagonal.Sigmas(sigmas)``). A
        ``noiseModel.Robust`` here reweights the whole vector as one block (GTSAM's
        mEstimator semantics), which does not single out a bad TDOA: for per-TDOA robustness
        use :func:`weighted_tdoa_vector_factor` with ``robust=``.
    key : int
        Key of the source position, a ``Point3``, m.
    sensors : array_like, shape (n, 3)
        Sensor positions, m (copied).
    pairs : array_like of int, shape (m, 2)
        Sensor pairs ``(i, j)``.
    taus : array_like, shape (m,)
        Measured delays, arrival at ``i`` minus arrival at ``j``, s (copied).
    c : float, optional, keyword-only
        Fixed sound speed, m/s. Give exactly one of `c` and `speed_key`.
    speed_key : int, optional, keyword-only
        Key of an unknown sound speed, a ``Vector(1)``, m/s.
    clock_key : int, optional, keyword-only
        Key of unknown clock offsets, a ``Vector(n)`` (one per sensor, s); TDOAs fix only
        their differences, so the caller adds a prior (e.g. on a reference sensor).

    Returns
    -------
    gtsam.CustomFactor
        On ``[key, speed_key?, clock_key?]``; error ``r`` of shape (m,), s, row k
        ``(d_i - d_j)/c + b_i - b_j - tau_k`` for pair k ``(i, j)``;
        Jacobians of shapes (m, 3), (m, 1), (m, n).

    Notes
    -----
    Eq. (14)-(15) of the localization text for every TDOA of one source, in one callback.

    Examples
    --------
    >>> s = np.array([[0.0, 0, 0], [100.0, 0, 0], [0, 100.0, 0]])
    >>> pairs = np.array([[0, 1], [0, 2]])
    >>> taus = predicted_tdoas([30.0, 40.0, 0.0], s, pairs, c=1500.0)
    >>> f = tdoa_vector_factor(gtsam.noiseModel.Isotropic.Sigma(2, 1e-5), 0, s, pairs, taus, c=1500.0)
    >>> v = gtsam.Values(); v.insert(0, gtsam.Point3(30.0, 40.0, 0.0))
    >>> bool(np.abs(f.unwhitenedError(v)).max() < 1e-15)
    True
    """
    return _factor(noise, key, TdoaModel.build(sensors, pairs, taus), c, speed_key, clock_key)


def _robust_rows(
    e: NDArray[np.float64], robust: gtsam.noiseModel.mEstimator.Base
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-component square-root loss ``psi(e) = sign(e) sqrt(2 rho(e))`` and ``dpsi/de``."""
    rho = np.array([robust.loss(float(x)) for x in e])
    w = np.array([robust.weight(float(x)) for x in e])
    psi = np.sign(e) * np.sqrt(2.0 * np.maximum(rho, 0.0))  # 0.5 psi^2 = rho(e)
    safe = np.abs(psi) > 1e-150
    # dpsi/de = rho'(e)/psi = w(e) e / psi; its limit at e = 0 is sqrt(w(0)) (= 1).
    dpsi = np.where(safe, w * e / np.where(safe, psi, 1.0), np.sqrt(np.maximum(w, 0.0)))
    return psi, dpsi


def _fixed_speed_error(
    model: TdoaModel, c: float, inv_sigma: NDArray[np.float64], weights: NDArray[np.float64],
    key: int,
) -> Callable[[gtsam.CustomFactor, gtsam.Values, list | None], np.ndarray]:
    """The error of :func:`weighted_tdoa_vector_factor` at a known speed, least squares.

    The same arithmetic as :meth:`TdoaModel.residual` followed by the weighting, in one call
    (the candidate solves of the competition evaluate it some 10^5 times per minute of audio).
    """
    sensors, first, second, taus = model.sensors, model.first, model.second, model.taus
    n, m = sensors.shape[0], first.shape[0]
    seen: list = [None, None, None]  # the weights last read (bytes) and their two scales
    # work arrays, reused by every call: the same operations as a fresh expression would run
    # (each result rounded once, in the same order), without their allocations
    diff, u, d, dsq, dmin = np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n), np.empty(n)
    a, b = np.empty(m), np.empty(m)
    ua, ub = np.empty((m, 3)), np.empty((m, 3))
    dmin_col = dmin[:, None]

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        np.subtract(values.atPoint3(key), sensors, out=diff)  # p - s_i, (n, 3)
        np.sqrt(_einsum("ij,ij->i", diff, diff, out=dsq), out=d)
        r = np.subtract(np.take(d, first, out=a), np.take(d, second, out=b), out=a)
        np.divide(r, c, out=r)
        np.subtract(r, taus, out=r)  # (d_i - d_j) / c - tau
        now = weights.tobytes()  # read live; the scales recomputed when they changed
        if now != seen[0]:
            scale = np.sqrt(np.maximum(weights, 0.0))  # sqrt_weights
            seen[:] = now, scale, (scale * inv_sigma)[:, None]
        if jacobians is not None:
            np.maximum(d, MIN_RANGE, out=dmin)
            np.divide(diff, dmin_col, out=u)
            h = np.subtract(np.take(u, first, axis=0, out=ua), np.take(u, second, axis=0, out=ub),
                            out=ua)
            np.divide(h, c, out=h)
            jacobians[0] = seen[2] * h
        np.multiply(r, inv_sigma, out=r)
        return seen[1] * r

    return error_func


def weighted_tdoa_vector_factor(
    noise: gtsam.noiseModel.Base,
    key: int,
    sensors: ArrayLike,
    pairs: ArrayLike,
    taus: ArrayLike,
    weights: NDArray[np.float64],
    *,
    c: float | None = None,
    speed_key: int | None = None,
    clock_key: int | None = None,
    robust: gtsam.noiseModel.mEstimator.Base | None = None,
) -> gtsam.CustomFactor:
    """Vector TDOA factor with each whitened residual scaled by ``sqrt(w_k)``, ``w`` read live.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        Diagonal Gaussian noise of the TDOAs, dimension m, s (``Diagonal.Sigmas(sigmas)``,
        ``Isotropic`` or ``Unit``). It whitens inside the factor; the factor itself carries
        ``noiseModel.Unit``.
    key, sensors, pairs, taus
        As in :func:`tdoa_vector_factor`.
    weights : ndarray of float64, shape (m,)
        Association weights, READ (not copied) at every evaluation; the caller updates them in
        place between solves. A negative weight counts as 0; weight 0 removes that TDOA.
    c, speed_key, clock_key
        As in :func:`tdoa_vector_factor`.
    robust : gtsam.noiseModel.mEstimator.Base, optional, keyword-only
        Robust loss ``rho`` applied to each whitened residual separately (e.g.
        ``mEstimator.Huber.Create(1.345)``); default none (least squares).

    Returns
    -------
    gtsam.CustomFactor
        Error ``sqrt(max(w_k, 0)) * psi(r_k / sigma_k)``, shape (m,), dimensionless (already
        whitened), where ``psi(e) = e`` without `robust` and ``sign(e) sqrt(2 rho(e))`` with
        it; its cost is ``sum_k w_k rho(r_k / sigma_k)``.

    Notes
    -----
    The weighted least squares of the candidate update of eq. (19)-(22) of the localization
    text (write ``w~_km = w_km gamma_km`` of eq. (22) into `weights`). The robust form uses the
    square-root-loss residual ``psi`` whose half square is the loss, so the cost GTSAM
    evaluates is the robust cost and the Jacobian ``psi'(e) = w(e) e / psi(e)`` is exact;
    GTSAM's own ``noiseModel.Robust`` would reweight the m-vector as one block. Far from the
    optimum the robust loss is nearly linear and Gauss-Newton steps on it crawl: start a robust
    solve from the least-squares one (as :func:`solve_source` does).

    Examples
    --------
    >>> s = np.array([[0.0, 0, 0], [100.0, 0, 0], [0, 100.0, 0]])
    >>> w = np.array([1.0, 0.25])
    >>> f = weighted_tdoa_vector_factor(gtsam.noiseModel.Isotropic.Sigma(2, 1e-3), 0, s,
    ...                                 [[0, 1], [0, 2]], [0.0, 0.0], w, c=1500.0)
    >>> v = gtsam.Values(); v.insert(0, gtsam.Point3(0.0, 0.0, 0.0))
    >>> f.unwhitenedError(v).round(3)  # r = -100/1500 s, whitened by 1e-3 s, times sqrt(w)
    array([-66.667, -33.333])
    """
    model = TdoaModel.build(sensors, pairs, taus)
    m = model.m
    if not isinstance(weights, np.ndarray) or weights.dtype != np.float64 or weights.shape != (m,):
        raise ValueError(f"weights must be a float64 numpy array of shape ({m},), updated in place "
                         "by the caller")
    if isinstance(noise, gtsam.noiseModel.Robust | gtsam.noiseModel.Constrained):
        raise ValueError("noise must be a Gaussian diagonal model; pass a robust loss via robust=")
    if int(noise.dim()) != m:
        raise ValueError(f"noise model dimension {noise.dim()} differs from the {m} TDOAs")
    sqrt_info = np.asarray(noise.R(), dtype=float)
    if np.any(sqrt_info != np.diag(np.diag(sqrt_info))):
        raise ValueError("noise must be diagonal (independent TDOAs) for per-TDOA weights")
    inv_sigma = np.diag(sqrt_info).copy()  # 1/sigma_k
    c_fixed = _speed(c, speed_key)
    keys = _keys(key, speed_key, clock_key)
    if robust is None and speed_key is None and clock_key is None:
        return gtsam.CustomFactor(gtsam.noiseModel.Unit.Create(m), keys,
                                  _fixed_speed_error(model, c_fixed, inv_sigma, weights, keys[0]))
    evaluate = _model_error(model, c_fixed, speed_key is not None, clock_key is not None)

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        r, blocks = evaluate(this, values, jacobians is not None)
        e = r * inv_sigma  # whitened residual r_k/sigma_k
        scale = sqrt_weights(weights)  # sqrt(max(w_k, 0)), read live
        if robust is None:
            row = scale * inv_sigma  # d(sqrt(w) e)/dr
        else:
            e, dpsi = _robust_rows(e, robust)  # psi(e), dpsi/de
            row = scale * dpsi * inv_sigma
        if jacobians is not None:
            for k, h in enumerate(blocks):
                jacobians[k] = row[:, None] * h
        return scale * e

    return gtsam.CustomFactor(gtsam.noiseModel.Unit.Create(m), keys, error_func)

