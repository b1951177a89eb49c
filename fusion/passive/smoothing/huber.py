"""The Huber-loss bearing-rate graph minimised by Newton steps on GTSAM's linear solve.

With the Huber loss ``rho(u) = u^2 / 2`` for ``|u| <= k``, ``k |u| - k^2 / 2`` beyond, a bearing
whose whitened residual ``u`` lies beyond ``k`` has a constant gradient and no curvature.
Levenberg-Marquardt on GTSAM's robust noise model is iteratively reweighted least squares: it
gives such a bearing the curvature ``k / |u|`` it does not have, and on tracks with many of them
(two boxes of one boat a degree apart, each the other's outliers) it moves by small fractions of
the way per iteration; after its 100 iterations it had stopped up to 0.4 deg short of the
minimum on the Autoferry camera bearings.

:func:`huber_minimum` takes Newton steps instead: each solves the chain's linear graph (its
motion factors and prior, linearised once by the caller, :mod:`~fusion.passive.smoothing.graph`;
QR along the chain) with the bearings inside ``k`` as ordinary rows and those beyond as rows of
their exact gradient and a curvature ``ALPHA^2`` times a bearing's (small, to keep the system
well-posed where a state holds only such bearings), then a line search on the exact cost (the
step halved until the cost decreases, then while it still decreases). Within the same set of
bearings beyond ``k`` the step lands on the minimum (up to the small curvature); it stops when
the set is settled and the step moves nothing. The Huber cost is convex: the minimum is the one
Levenberg-Marquardt approaches, reached in 7-36 steps instead of 100 unfinished ones.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gtsam
import numpy as np
from numpy.typing import NDArray

from factors.angles import nearest_branch
from factors.motion import wna_sqrt_information
from fusion.geometry import wrap_angle
from fusion.passive.smoothing.types import TrackPrior

__all__ = ["huber_minimum"]

FloatArray = NDArray[np.float64]

#: Curvature of a bearing beyond the Huber threshold, as a fraction (squared) of a bearing's.
ALPHA = 1e-2
#: Halvings of the line search.
_MAX_HALVINGS = 30


def _cost(x: FloatArray, times: FloatArray, state: NDArray[np.int64], z: FloatArray,
          prior: TrackPrior | None, model: Any, r_motion: FloatArray) -> float:
    """The graph's cost at `x` (n, 2): Gaussian motion and prior, Huber bearings (GTSAM's
    ``error``: half the squared whitened residuals, ``rho`` for the bearings)."""
    dt = np.diff(times)
    e = x[1:] - np.column_stack([x[:-1, 0] + dt * x[:-1, 1], x[:-1, 1]])
    e[:, 0] = wrap_angle(e[:, 0])
    w = np.einsum("kij,kj->ki", r_motion, e)
    cost = 0.5 * float(np.sum(w * w))
    if prior is not None:
        d = x[0] - prior.mean
        d[0] = wrap_angle(d[0])
        cost += 0.5 * float(d @ np.linalg.solve(prior.covariance, d))
    u = np.abs(wrap_angle(x[state, 0] - z)) / model.sigma_bearing
    k = model.k
    return cost + float(np.sum(np.where(u <= k, 0.5 * u * u, k * u - 0.5 * k * k)))


def huber_minimum(times: FloatArray, state: NDArray[np.int64], bearing: FloatArray,
                  prior: TrackPrior | None, model: Any, states: FloatArray,
                  motion: gtsam.GaussianFactorGraph,
                  solve: Callable[[gtsam.GaussianFactorGraph], gtsam.VectorValues],
                  on_iteration: Callable[[], None] | None = None) -> FloatArray:
    """Minimum (n, 2) of one track's graph with the Huber loss on its bearings, from `states`.

    Parameters
    ----------
    times : ndarray, shape (n,)
        State times, s.
    state, bearing : ndarray, shape (m,)
        State index and bearing (rad) of each bearing factor (all unweighted).
    prior : TrackPrior or None
        Prior on the first state.
    model : _Model
        ``sigma_bearing``, ``q``, ``k`` (Huber threshold) and ``max_iterations``.
    states : ndarray, shape (n, 2)
        Start, and the point about which `motion` is linearised; every bearing stays on the
        branch nearest it (the caller re-centres and calls again if the minimum moved one).
    motion : gtsam.GaussianFactorGraph
        The motion factors and prior linearised at `states` (keys 0..n-1).
    solve : callable
        Linear solve of a chain graph (``argmin ||A dx - b||``).
    on_iteration : callable, optional
        Called after every Newton step.
    """
    n = times.size
    x0 = np.asarray(states, float)
    r_motion = wna_sqrt_information(np.diff(times), model.q, 1) if n > 1 else np.zeros((0, 2, 2))
    st = state
    zc = nearest_branch(bearing, x0[st, 0])  # each bearing on the branch nearest x0
    s, k = model.sigma_bearing, model.k
    unit = gtsam.noiseModel.Unit.Create(1)
    x = x0.copy()
    cost = _cost(x, times, st, zc, prior, model, r_motion)
    beyond_prev = None
    for _ in range(model.max_iterations):
        u = (x[st, 0] - zc) / s
        beyond = np.abs(u) > k
        # rows of dx = x_new - x0: inside k the bearing itself, beyond k its gradient
        # k sign(u) / s at x with curvature ALPHA^2 / s^2
        a = np.where(beyond, ALPHA, 1.0) / s
        b = np.where(beyond, ALPHA * (x[st, 0] - x0[st, 0]) / s - k * np.sign(u) / ALPHA,
                     (zc - x0[st, 0]) / s)
        graph = gtsam.GaussianFactorGraph()
        graph.push_back(motion)
        for key, aj, bj in zip(st.tolist(), a.tolist(), b.tolist(), strict=True):
            graph.push_back(gtsam.JacobianFactor(key, np.array([[aj, 0.0]]), np.array([bj]), unit))
        delta = solve(graph)
        target = x0 + delta.vector().reshape(n, 2)  # keys 0..n-1 in order
        step = target - x
        t = 1.0
        for _ in range(_MAX_HALVINGS):  # backtracking on the exact cost
            new_cost = _cost(x + t * step, times, st, zc, prior, model, r_motion)
            if new_cost <= cost:
                break
            t *= 0.5
        else:
            break  # no decrease along the step: at the minimum to rounding
        while t > 1e-6:  # the step overshoots most while bearings cross the threshold: the
            # best of the halvings that still decrease the cost
            half = _cost(x + 0.5 * t * step, times, st, zc, prior, model, r_motion)
            if half >= new_cost:
                break
            new_cost, t = half, 0.5 * t
        x = x + t * step
        moved = float(np.max(np.abs(t * step))) if step.size else 0.0
        decrease = cost - new_cost
        cost = new_cost
        if on_iteration is not None:
            on_iteration()
        settled = beyond_prev is not None and np.array_equal(beyond, beyond_prev)
        beyond_prev = beyond
        if settled and (moved < 1e-12 or decrease <= 1e-15 * max(cost, 1.0)):
            break
    return x
