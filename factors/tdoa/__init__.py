"""TDOA factors of a click source: the model, the GTSAM factors, a depth-gradient speed, sensor
offsets, and a one-source solve.

Modules: :mod:`factors.tdoa.model` (predicted delays and their derivatives, one speed),
:mod:`factors.tdoa.factors` (the vector and weighted vector factors), :mod:`factors.tdoa.gradient`
(travel times and the factor under a speed linear in depth), :mod:`factors.tdoa.sensors` (the
factor with each sensor's offset from its surveyed position as a variable). This module holds
the one-source solve.

Time-difference-of-arrival (TDOA) factors on a click source position, and a one-source solve.

The unknown source position ``p`` is a GTSAM ``Point3`` (m); sensors ``s_i`` (m) are known. The
residual of the pair ``(i, j)`` with measured delay ``tau`` (s, arrival at ``i`` minus arrival
at ``j``) is predicted minus measured (:mod:`factors.tdoa.model`), in seconds::

    r = (d_i - d_j)/c + b_i - b_j - tau,   d_i = |p - s_i|
    dr/dp = (u_i - u_j)/c,   dr/dc = -(d_i - d_j)/c^2,   dr/db_i = +1,   dr/db_j = -1

with ``u_i = (p - s_i)/d_i``. The sound speed ``c`` (m/s) is fixed or an unknown ``Vector(1)``;
the clock offsets ``b`` (s, measured arrival = true arrival + ``b_i``) are absent or an unknown
``Vector(n)``. Two factories share the model: :func:`tdoa_vector_factor` (all of a source's
TDOAs in one callback) and :func:`weighted_tdoa_vector_factor` (whitened residuals scaled by
``sqrt(w_k)`` read live from a caller's array; optionally robust per TDOA).
:func:`solve_source` localizes one source on a one-factor graph and returns the position, its
``gtsam.Marginals`` covariance and a :class:`TdoaSolveInfo`.

Notes
-----
Eq. (14)-(15) of the localization text (*Localization of short periodic signals*); the weights
are the ``w_km`` of its eq. (19)-(22). Design notes, "Factor graphs".

Timing (``python benchmarks/bench_tdoa_factor.py``; median of 200 solves of one source's 10
TDOAs on a 5-sensor km array, graph build + Levenberg-Marquardt, 4-6 iterations, same optimum;
2 cores shared with other jobs): one vector factor 0.26-0.43 ms per solve; ten one-TDOA
factors, the form it replaced, took 2.7-7.1 ms (8-19 times slower). A whole
:func:`solve_source` call (with ``Marginals``) takes 1.2-1.8 ms.

The factories live in :mod:`factors.tdoa.factors`, the one-source solve here; all are importable
from here.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.tdoa.factors import tdoa_vector_factor, weighted_tdoa_vector_factor
from factors.tdoa.model import TdoaModel, check_speed, predicted_tdoas

__all__ = [
    "TdoaSolveInfo",
    "predicted_tdoas",
    "solve_source",
    "tdoa_vector_factor",
    "weighted_tdoa_vector_factor",
]

_LOG = logging.getLogger(__name__)


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
