"""Time-difference-of-arrival (TDOA) factors on a click source position, and a one-source solve.

The unknown source position ``p`` is a GTSAM ``Point3`` (m); sensors ``s_i`` (m) are known. The
residual of the pair ``(i, j)`` with measured delay ``tau`` (s, arrival at ``i`` minus arrival
at ``j``) is predicted minus measured (:mod:`factors.tdoa_model`), in seconds::

    r = (d_i - d_j)/c + b_i - b_j - tau,   d_i = |p - s_i|
    dr/dp = (u_i - u_j)/c,   dr/dc = -(d_i - d_j)/c^2,   dr/db_i = +1,   dr/db_j = -1

with ``u_i = (p - s_i)/d_i``. The sound speed ``c`` (m/s) is fixed or an unknown ``Vector(1)``;
the clock offsets ``b`` (s, measured arrival = true arrival + ``b_i``) are absent or an unknown
``Vector(n)``. Three factories share the model: :func:`tdoa_factor` (one TDOA),
:func:`tdoa_vector_factor` (all of a source's TDOAs in one callback: the fast form) and
:func:`weighted_tdoa_vector_factor` (whitened residuals scaled by ``sqrt(w_k)`` read live from a
caller's array; optionally robust per TDOA). :func:`solve_source` localizes one source on a
one-factor graph and returns the position, its ``gtsam.Marginals`` covariance and a
:class:`TdoaSolveInfo`.

Notes
-----
Eq. (14)-(15) of the localization text (*Localization of short periodic signals*); the weights
are the ``w_km`` of its eq. (19)-(22). Design notes, "Factor graphs".

Timing (``python benchmarks/bench_tdoa_factor.py``; median of 200 solves of one source's 10
TDOAs on a 5-sensor km array, graph build + Levenberg-Marquardt, 4-6 iterations, same optimum;
2 cores shared with other jobs): one vector factor 0.26-0.43 ms per solve, ten scalar factors
2.7-7.1 ms (8-19 times slower). A whole :func:`solve_source` call (with ``Marginals``) takes
1.2-1.8 ms.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.tdoa_model import TdoaModel, check_speed, predicted_tdoas

__all__ = [
    "TdoaSolveInfo",
    "predicted_tdoas",
    "solve_source",
    "tdoa_factor",
    "tdoa_vector_factor",
    "weighted_tdoa_vector_factor",
]

_LOG = logging.getLogger(__name__)


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


def tdoa_factor(
    noise: gtsam.noiseModel.Base,
    key: int,
    sensors: ArrayLike,
    pair: tuple[int, int],
    tau: float,
    *,
    c: float | None = None,
    speed_key: int | None = None,
    clock_key: int | None = None,
) -> gtsam.CustomFactor:
    """Factor of one TDOA between the source position and its sensor pair.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        One-dimensional noise model, s (e.g. ``Isotropic.Sigma(1, 2e-5)``, or a
        ``noiseModel.Robust`` around it).
    key : int
        Key of the source position, a ``Point3``, m.
    sensors : array_like, shape (n, 3)
        Sensor positions, m (copied).
    pair : tuple of int
        The pair ``(i, j)``: `tau` is the arrival at ``i`` minus the arrival at ``j``.
    tau : float
        Measured delay, s.
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
        On ``[key, speed_key?, clock_key?]``; error ``(d_i - d_j)/c + b_i - b_j - tau``,
        shape (1,), s; Jacobians of shapes (1, 3), (1, 1), (1, n).

    Notes
    -----
    Eq. (14)-(15) of the localization text; see the module docstring for the derivatives.

    Examples
    --------
    >>> s = np.array([[0.0, 0, 0], [100.0, 0, 0]])
    >>> f = tdoa_factor(gtsam.noiseModel.Isotropic.Sigma(1, 1e-5), 0, s, (0, 1), -0.02, c=1500.0)
    >>> v = gtsam.Values(); v.insert(0, gtsam.Point3(35.0, 0.0, 0.0))
    >>> round(float(f.unwhitenedError(v)[0]), 12)
    0.0
    """
    pr = np.asarray(pair)
    if pr.shape != (2,):
        raise ValueError(f"pair must be two sensor indices (i, j), got {pair!r}")
    model = TdoaModel.build(sensors, pr[None, :], [tau])
    return _factor(noise, key, model, c, speed_key, clock_key)


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
    c, speed_key, clock_key
        As in :func:`tdoa_factor`.

    Returns
    -------
    gtsam.CustomFactor
        Error ``r`` of shape (m,), s, row k that of :func:`tdoa_factor` for pair k;
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
        As in :func:`tdoa_factor`.
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
    evaluate = _model_error(model, c_fixed, speed_key is not None, clock_key is not None)

    def error_func(
        this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list[np.ndarray] | None
    ) -> np.ndarray:
        r, blocks = evaluate(this, values, jacobians is not None)
        e = r * inv_sigma  # whitened residual r_k/sigma_k
        scale = np.sqrt(np.maximum(weights, 0.0))  # sqrt(max(w_k, 0)), read live
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


# --------------------------------------------------------------------------- one-source solve
@dataclass(frozen=True)
class TdoaSolveInfo:
    """Diagnostics of one :func:`solve_source` solve.

    Attributes
    ----------
    observable : bool
        False when the TDOAs leave a direction unfixed: the position information is near
        singular (``condition_number > max_condition`` or ``min_eigenvalue <= 0``) or, with an
        unknown speed, the speed is not separable from the position. The covariance is then NaN.
    information : ndarray, shape (3, 3)
        Marginal information of the position at the solution (speed eliminated), m^-2.
    condition_number : float
        Ratio of the largest to the smallest eigenvalue of `information` (inf if singular).
    min_eigenvalue : float
        Smallest eigenvalue of `information`, m^-2.
    weakest_direction : ndarray, shape (3,)
        Unit eigenvector of `min_eigenvalue`: the least determined direction.
    speed : float
        Sound speed of the solution, m/s (the given one when not estimated).
    speed_std : float
        Marginal standard deviation of the estimated speed, m/s; NaN when fixed or unobservable.
    residual_rms_s : float
        Root mean square of the raw TDOA residuals at the solution, s (weights ignored).
    cost : float
        Final GTSAM error: half the sum of the weighted, whitened (robust) squared residuals.
    iterations : int
        Levenberg-Marquardt iterations (of both the least-squares and the robust stage).
    """

    observable: bool
    information: NDArray[np.float64]
    condition_number: float
    min_eigenvalue: float
    weakest_direction: NDArray[np.float64]
    speed: float
    speed_std: float
    residual_rms_s: float
    cost: float
    iterations: int


def _position_information(a: NDArray[np.float64], max_condition: float) -> tuple:
    """Position marginal information from the whitened Jacobian ``a`` = [A_p | A_c?]."""
    lam = a.T @ a  # information of all unknowns
    lam_pp = lam[:3, :3]
    separable = True
    if lam.shape[0] > 3:  # eliminate the speed: Schur complement
        lam_pc, lam_cc = lam[:3, 3:], lam[3:, 3:]
        lam_pp = lam_pp - lam_pc @ np.linalg.pinv(lam_cc) @ lam_pc.T
        speed_marginal = lam_cc - lam_pc.T @ np.linalg.pinv(lam[:3, :3]) @ lam_pc
        separable = bool(lam_cc[0, 0] > 0 and speed_marginal[0, 0] > lam_cc[0, 0] / max_condition)
    lam_pp = 0.5 * (lam_pp + lam_pp.T)
    evals, evecs = np.linalg.eigh(lam_pp)
    cond = float(evals[-1] / evals[0]) if evals[0] > 0 else float("inf")
    observable = separable and evals[0] > 0 and cond <= max_condition
    return lam_pp, cond, float(evals[0]), evecs[:, 0], observable


def solve_source(
    sensors: ArrayLike,
    pairs: ArrayLike,
    taus: ArrayLike,
    sigmas: ArrayLike,
    *,
    c: float,
    initial: ArrayLike,
    robust: gtsam.noiseModel.mEstimator.Base | None = None,
    weights: ArrayLike | None = None,
    estimate_speed: bool = False,
    max_condition: float = 1e8,
    max_iterations: int = 100,
) -> tuple[NDArray[np.float64], NDArray[np.float64], TdoaSolveInfo]:
    """Localize one source from its TDOAs on a one-factor graph (Levenberg-Marquardt).

    Parameters
    ----------
    sensors : array_like, shape (n, 3)
        Sensor positions, m.
    pairs : array_like of int, shape (m, 2)
        Sensor pairs ``(i, j)``.
    taus : array_like, shape (m,)
        Measured delays, arrival at ``i`` minus arrival at ``j``, s.
    sigmas : float or array_like, shape (m,)
        Standard deviation of each TDOA, s (from the caller, e.g. the correlation peak width).
    c : float, keyword-only
        Sound speed, m/s: fixed, or the starting value with `estimate_speed`.
    initial : array_like, shape (3,), keyword-only
        Starting position, m.
    robust : gtsam.noiseModel.mEstimator.Base, optional, keyword-only
        Robust loss applied to each whitened TDOA residual (e.g. ``Huber.Create(1.345)``); the
        robust fit starts from the least-squares fit.
    weights : array_like, shape (m,), optional, keyword-only
        Association weight of each TDOA (negative counts as 0); default all 1.
    estimate_speed : bool, keyword-only
        Also estimate the sound speed (one more unknown).
    max_condition : float, keyword-only
        Largest condition number of the position information still called observable.
    max_iterations : int, keyword-only
        Levenberg-Marquardt iteration limit.

    Returns
    -------
    position : ndarray, shape (3,)
        Estimated source position, m.
    covariance : ndarray, shape (3, 3)
        Its marginal covariance from ``gtsam.Marginals``, m^2; NaN when not observable.
    info : TdoaSolveInfo
        Observability and fit diagnostics.

    Raises
    ------
    ValueError
        On malformed inputs, or fewer independent TDOAs (of positive weight) than unknowns.

    Notes
    -----
    Least squares (or robust, weighted) fit of eq. (14)-(15) of the localization text through
    :func:`weighted_tdoa_vector_factor`. A near-singular information matrix (e.g. a source in
    the plane of a planar array, whose side of the plane the TDOAs cannot tell) is reported in
    `info` and logged, not raised. The count of independent TDOAs is the rank of the pairs'
    incidence matrix: all pairs of n sensors carry n - 1.

    Examples
    --------
    >>> s = np.array([[0, 0, 0], [1000, 0, 0], [0, 1000, 0], [0, 0, 1000], [1000, 1000, 500]])
    >>> pairs = np.array([(i, j) for i in range(5) for j in range(i + 1, 5)])
    >>> taus = predicted_tdoas([400.0, 300.0, 200.0], s, pairs, c=1500.0)
    >>> p, cov, info = solve_source(s, pairs, taus, 1e-5, c=1500.0, initial=[500, 500, 500])
    >>> np.round(p, 6), info.observable
    (array([400., 300., 200.]), True)
    """
    model = TdoaModel.build(sensors, pairs, taus)
    m = model.m
    sig = np.broadcast_to(np.asarray(sigmas, dtype=float), (m,)).copy()
    if not np.all(np.isfinite(sig) & (sig > 0)):
        raise ValueError("sigmas must be positive and finite")
    w = np.ones(m) if weights is None else np.array(weights, dtype=float).reshape(-1)
    if w.shape != (m,) or not np.all(np.isfinite(w)):
        raise ValueError(f"weights must be {m} finite numbers, got shape {np.shape(weights)}")
    x0 = np.array(initial, dtype=float).reshape(-1)
    if x0.shape != (3,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"initial must be a finite position of shape (3,), got {np.shape(initial)}")
    unknowns = 3 + int(bool(estimate_speed))
    independent = int(np.linalg.matrix_rank(model.incidence[w > 0])) if np.any(w > 0) else 0
    if independent < unknowns:
        raise ValueError(f"{unknowns} unknowns need at least {unknowns} independent TDOAs, got "
                         f"{independent} (from {int(np.sum(w > 0))} TDOAs of positive weight)")
    check_speed(c)
    if not (isinstance(max_iterations, int) and max_iterations > 0):
        raise ValueError(f"max_iterations must be a positive integer, got {max_iterations!r}")

    pos_key = gtsam.symbol("p", 0)
    speed_key = gtsam.symbol("c", 0) if estimate_speed else None
    values = gtsam.Values()
    values.insert(pos_key, gtsam.Point3(*x0))
    if estimate_speed:
        values.insert(speed_key, np.array([float(c)]))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    params.setRelativeErrorTol(1e-12)
    params.setAbsoluteErrorTol(1e-20)
    iterations = 0
    # A robust fit starts from the (weighted) least-squares one: far from the optimum the robust
    # loss is nearly linear and Gauss-Newton steps on it crawl (redescending losses stall).
    for loss in (None, robust) if robust is not None else (None,):
        factor = weighted_tdoa_vector_factor(
            gtsam.noiseModel.Diagonal.Sigmas(sig), pos_key, model.sensors, model.pairs,
            model.taus, w, c=None if estimate_speed else c, speed_key=speed_key, robust=loss)
        graph = gtsam.NonlinearFactorGraph()
        graph.add(factor)
        optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
        result = values = optimizer.optimize()
        iterations += int(optimizer.iterations())

    position = np.asarray(result.atPoint3(pos_key), dtype=float)
    speed = float(result.atVector(speed_key)[0]) if estimate_speed else float(c)
    a, _ = factor.linearize(result).jacobian()  # whitened, columns [position, speed?]
    lam_pp, cond, min_eig, weakest, observable = _position_information(a, max_condition)
    raw, _, _ = model.residual(position, speed)
    covariance = np.full((3, 3), np.nan)
    speed_std = float("nan")
    if observable:
        marginals = gtsam.Marginals(graph, result)
        covariance = np.asarray(marginals.marginalCovariance(pos_key), dtype=float)
        if estimate_speed:
            speed_std = float(np.sqrt(marginals.marginalCovariance(speed_key)[0, 0]))
    else:
        _LOG.warning("TDOA solve: position not observable (condition number %.3g, weakest "
                     "direction %s); covariance set to NaN", cond, np.round(weakest, 3))
    info = TdoaSolveInfo(
        observable=bool(observable), information=lam_pp, condition_number=cond,
        min_eigenvalue=min_eig, weakest_direction=weakest, speed=speed, speed_std=speed_std,
        residual_rms_s=float(np.sqrt(np.mean(raw**2))), cost=float(graph.error(result)),
        iterations=iterations)
    return position, covariance, info
