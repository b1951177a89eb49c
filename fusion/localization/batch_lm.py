"""Weighted TDOA least squares of many candidates at once: GTSAM's Levenberg-Marquardt in numpy.

The competition's candidate update (eq. 22) re-solves every live candidate from where it is,
each with its own TDOA weights, some 10^4 times per minute of audio. One GTSAM solve per
candidate costs a graph, a ``Values``, an optimizer and a Python callback per linearization
(about 0.4 ms for a 3-D point and a few dozen TDOAs). :func:`solve_candidates` runs the same
algorithm for all candidates of an iteration together on stacked arrays:

* the residual and Jacobian of :func:`factors.tdoa.weighted_tdoa_vector_factor` at a known speed
  (least squares), ``e_m = sqrt(max(w_m, 0)) (d_m(x) - tau_m) / sigma_m``, cost ``0.5 |e|^2``;
* :class:`gtsam.LevenbergMarquardtOptimizer` with the parameters the competition sets
  (relative error tolerance 1e-10, absolute 1e-20, default lambda schedule: initial 1e-5,
  factor 10 fixed, upper bound 1e5, minimum model fidelity 1e-3, damping ``lambda I``):
  the same step acceptance, lambda updates, stop-searching rule and convergence test
  (``NonlinearOptimizer::defaultOptimize``, ``LevenbergMarquardtOptimizer::tryLambda``).

The damped 3x3 systems are solved by numpy instead of GTSAM's Cholesky elimination, so the
positions agree with GTSAM's to rounding (a few 1e-12 m), not bit for bit
(``tests/test_batch_lm.py`` cross-checks them).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from factors.tdoa_model import MIN_RANGE

__all__ = ["solve_candidates"]

_LAMBDA_INITIAL = 1e-5
_LAMBDA_FACTOR = 10.0
_LAMBDA_UPPER = 1e5
_MIN_FIDELITY = 1e-3
_EPS = float(np.finfo(float).eps)
_EYE = np.eye(3)


def _residuals(x: NDArray, sensors: NDArray, incidence: NDArray, taus: NDArray, row: NDArray
               ) -> tuple[NDArray, NDArray, NDArray]:
    """Whitened weighted residuals (K, M), sensor offsets (K, n, 3) and ranges (K, n)."""
    diff = x[:, None, :] - sensors  # (K, n, 3)
    d = np.sqrt(np.square(diff).sum(axis=2))
    return row * (d @ incidence - taus), diff, d


def _solve_each(a: NDArray, b: NDArray) -> tuple[NDArray, NDArray]:
    """``a x = b`` system by system; a singular system gives ``x = 0`` and False."""
    x, ok = np.zeros_like(b), np.ones(a.shape[0], dtype=bool)
    for i in range(a.shape[0]):
        try:
            x[i] = np.linalg.solve(a[i], b[i])
        except np.linalg.LinAlgError:
            ok[i] = False
    return x, ok


def _cost(e: NDArray) -> NDArray:
    """``0.5 |e|^2`` per row."""
    return 0.5 * np.square(e).sum(axis=1)


def solve_candidates(
    x0: NDArray[np.float64], weights: NDArray[np.float64], sensors: NDArray[np.float64],
    pairs: NDArray[np.intp], taus: NDArray[np.float64], sigmas: NDArray[np.float64], *,
    c: float, max_iterations: int, relative_tol: float = 1e-10, absolute_tol: float = 1e-20,
    step_tol_m: float = 1e-6,
) -> NDArray[np.float64]:
    """Levenberg-Marquardt weighted TDOA fits of K candidates, each from its own start.

    Parameters
    ----------
    x0 : ndarray, shape (K, 3)
        Starting positions, m.
    weights : ndarray, shape (K, M)
        Each candidate's TDOA weights (negative counts as 0).
    sensors : ndarray, shape (n, 3)
        Sensor positions, m.
    pairs : ndarray of int, shape (M, 2)
        Sensor pair ``(i, j)`` of each TDOA.
    taus, sigmas : ndarray, shape (M,)
        Delays (arrival at ``i`` minus at ``j``) and their standard deviations, s.
    c : float, keyword-only
        Sound speed, m/s.
    max_iterations : int, keyword-only
        Largest number of (successful) Levenberg-Marquardt iterations per candidate.
    relative_tol, absolute_tol : float, keyword-only
        GTSAM's relative and absolute error-decrease tolerances.
    step_tol_m : float, keyword-only
        A candidate stops searching for a lambda once its step is shorter than this, m (GTSAM
        goes on raising lambda while rounding noise in the cost change exceeds its relative
        tolerance: up to 13 more trials at a converged point).

    Returns
    -------
    ndarray, shape (K, 3)
        The positions, m: what one GTSAM solve per candidate of
        :func:`factors.tdoa.weighted_tdoa_vector_factor` (at speed `c`, no robust loss) returns,
        to rounding.
    """
    x = np.array(x0, dtype=float).reshape(-1, 3)
    k = x.shape[0]
    sensors = np.asarray(sensors, dtype=float)
    pairs = np.asarray(pairs)
    m = pairs.shape[0]
    taus = np.asarray(taus, dtype=float)
    # (d_i - d_j) / c of every pair as one product with the ranges
    incidence = np.zeros((sensors.shape[0], m))
    incidence[pairs[:, 0], np.arange(m)] += 1.0 / c
    incidence[pairs[:, 1], np.arange(m)] -= 1.0 / c
    row = np.sqrt(np.maximum(np.asarray(weights, dtype=float).reshape(k, m), 0.0)) \
        * (1.0 / np.asarray(sigmas, dtype=float))
    error = _cost(_residuals(x, sensors, incidence, taus, row)[0])
    lam = np.full(k, _LAMBDA_INITIAL)
    iterations = np.zeros(k, dtype=int)
    active = (error > 0.0) & (max_iterations > 0)
    while np.any(active):
        idx = np.flatnonzero(active)
        before = error[idx]
        rows = row[idx]
        e, diff, d = _residuals(x[idx], sensors, incidence, taus, rows)
        u = diff / np.maximum(d, MIN_RANGE)[:, :, None]  # unit vectors from the sensors
        jac = rows[:, :, None] * (incidence.T @ u)  # (K, M, 3)
        jac_t = jac.transpose(0, 2, 1)
        hess = jac_t @ jac  # (K, 3, 3)
        grad = jac_t @ e[:, :, None]  # (K, 3, 1)
        # linearized cost at zero step: the cost itself (GTSAM recomputes it from the linearization)
        old_linear = _cost(e)
        s = np.arange(idx.size)  # the candidates still searching for a lambda
        while s.size:
            ks = idx[s]
            try:
                delta = np.linalg.solve(hess[s] + lam[ks, None, None] * _EYE, -grad[s])
                solved = np.ones(s.size, dtype=bool)
            except np.linalg.LinAlgError:  # singular (GTSAM's Cholesky fails): one by one
                delta, solved = _solve_each(hess[s] + lam[ks, None, None] * _EYE, -grad[s])
            # linearized cost change -(g.delta) - 0.5 delta' H delta
            linear_change = -(delta * (grad[s] + 0.5 * (hess[s] @ delta))).sum(axis=(1, 2))
            delta = delta[..., 0]
            new_x = x[ks] + delta
            new_error = _cost(_residuals(new_x, sensors, incidence, taus, rows[s])[0])
            cost_change = error[ks] - new_error
            valid = solved & (linear_change >= 0.0)
            known = valid & (linear_change > _EPS * old_linear[s])
            success = known & (cost_change > _MIN_FIDELITY * np.where(known, linear_change, 0.0))
            # GTSAM stops searching when the cost change is below the tolerance; here also when
            # the step is shorter than step_tol_m (a larger lambda only shortens it, and GTSAM's
            # further trials are decided by rounding in the cost change)
            stop = valid & ((np.abs(cost_change) < relative_tol * error[ks])
                            | (np.abs(delta).max(axis=1) < step_tol_m))
            # a successful step: taken, lambda decreased, one iteration more
            ok = ks[success]
            x[ok], error[ok] = new_x[success], new_error[success]
            lam[ok] /= _LAMBDA_FACTOR
            iterations[ok] += 1
            # no step: lambda increased and tried again, unless the change is negligible or
            # lambda reached its upper bound
            retry = ~success & ~stop
            lam[ks[retry]] *= _LAMBDA_FACTOR
            s = s[retry & (lam[ks] < _LAMBDA_UPPER)]
        # defaultOptimize: stop at the iteration limit or when the error stops decreasing
        after = error[idx]
        decrease = before - after
        converged = (after <= 0.0) | (decrease < relative_tol * before) | (decrease < absolute_tol)
        active[idx] = ~converged & (iterations[idx] < max_iterations) & np.isfinite(before)
    return x
