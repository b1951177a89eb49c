"""The bearing-rate graph of one track: build, re-centre on the wrap, solve, marginals.

A chain of states ``x_k = (theta_k, theta_dot_k)`` (bearing, rad; bearing rate, rad/s) at the
state times, tied by constant-rate motion factors with white-noise-acceleration noise
(:func:`factors.motion.wna_covariance`) and by bearing factors, with an optional prior on the
first state. Apart from the wrap of the bearings the model is linear, so it is built from GTSAM's
own linear factors, evaluated in C++ (:func:`factors.motion.constant_velocity_chain`,
:func:`factors.bearing.linear_bearing_factors`): every bearing (and the prior bearing) is put on
the branch nearest the current estimate, motion residuals are wrapped at the linearisation point,
and a graph whose solution moved a residual onto another branch is re-centred there and solved
again. The result is the optimum of the wrapped model (residuals wrapped at every evaluation;
the tests check it against that model written as plain ``CustomFactor`` s).
Bearings whose origin is uncertain enter with association weights ``w``: with the Gaussian
loss as the same built-in factor with ``sigma / sqrt(w)`` (cost ``w`` times the bearing
factor's), with a robust loss through :func:`factors.weighted.weighted_factor`.

The names here are the package's internals, shared by the batch, online and multi-track
smoothers; the design notes ("Factor graphs", bearing-rate graph) describe the model.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.angles import nearest_branch
from factors.bearing import linear_bearing_factors
from factors.motion import constant_velocity_chain
from factors.weighted import sqrt_weights, weighted_factor
from fusion._progress import RowShare
from fusion._stack import with_deep_stack
from fusion._validation import check_positive
from fusion.geometry import check_radians, wrap_angle
from fusion.passive.smoothing.huber import huber_minimum
from fusion.passive.smoothing.types import TrackPrior

__all__ = ["ROBUST_LOSSES"]

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Robust loss names accepted by the smoothers.
ROBUST_LOSSES = ("none", "huber", "cauchy")

#: Solves of one graph at most, re-centring the bearings on the previous solution each time.
_MAX_RECENTRE = 5
#: Graphs of more states than this are solved on a deep stack (:mod:`fusion._stack`): GTSAM
#: recurses once per state of the chain (100,000 states overflowed the main thread's stack).
_DEEP_CHAIN = 5_000


def _robust_noise(base: gtsam.noiseModel.Base, loss: str, k: float) -> gtsam.noiseModel.Base:
    if loss == "none":
        return base
    if loss == "huber":
        est = gtsam.noiseModel.mEstimator.Huber.Create(k)
    else:
        est = gtsam.noiseModel.mEstimator.Cauchy.Create(k)
    return gtsam.noiseModel.Robust.Create(est, base)


def _check_loss(loss: str) -> str:
    if loss not in ROBUST_LOSSES:
        raise ValueError(f"robust loss must be one of {', '.join(ROBUST_LOSSES)}, got {loss!r}")
    return loss


def _check_detections(times: ArrayLike, bearings: ArrayLike) -> tuple[FloatArray, FloatArray]:
    t = np.asarray(times, dtype=float)
    z = np.asarray(bearings, dtype=float)
    if t.ndim != 1 or z.shape != t.shape:
        raise ValueError(f"times and bearings must be 1-D of equal length, got {t.shape}, {z.shape}")
    if t.size == 0:
        raise ValueError("no bearings given")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(z))):
        raise ValueError("times and bearings must be finite")
    check_radians(z)
    if np.any(np.diff(t) < 0):
        raise ValueError("times must be non-decreasing")
    return t, z


def _lm_params(max_iterations: int) -> gtsam.LevenbergMarquardtParams:
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    params.setRelativeErrorTol(1e-12)
    params.setAbsoluteErrorTol(1e-14)
    return params


@dataclass(frozen=True)
class _Measurements:
    """Bearings of one track graph: state index, bearing (rad), weight index (-1 = hard)."""

    state: NDArray[np.int64]
    bearing: FloatArray
    weight_index: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))


@dataclass(frozen=True)
class _Model:
    sigma_bearing: float
    q: float
    loss: str
    k: float
    max_iterations: int

    @classmethod
    def checked(cls, *, sigma_bearing: float, q: float, robust: str, robust_k: float,
                max_iterations: int) -> _Model:
        """The model of a smoother's settings, each checked (:class:`ValueError` names the bad
        one): `sigma_bearing` (rad), `q` (rad^2/s^3), `robust` (one of :data:`ROBUST_LOSSES`),
        `robust_k` and positive; `max_iterations` as an int."""
        return cls(
            sigma_bearing=check_positive("sigma_bearing", sigma_bearing),
            q=check_positive("q", q),
            loss=_check_loss(robust),
            k=check_positive("robust_k", robust_k),
            max_iterations=int(max_iterations),
        )


def _build_graph(
    times: FloatArray,
    meas: _Measurements,
    prior: TrackPrior | None,
    model: _Model,
    loss: str,
    weights: FloatArray | None,
    states: FloatArray,
) -> gtsam.NonlinearFactorGraph:
    """The bearing-rate graph of one track over `times` (keys 0..n-1), built-in linear factors
    linearised at (and bearings re-centred on) the estimate `states` (n, 2)."""
    graph = gtsam.NonlinearFactorGraph()
    if prior is not None:
        mean = prior.mean
        mean[0] = nearest_branch(mean[0], states[0, 0])  # the prior bearing wraps too
        graph.add(
            gtsam.PriorFactorVector(0, mean, gtsam.noiseModel.Gaussian.Covariance(prior.covariance))
        )
    graph.push_back(constant_velocity_chain(np.arange(times.size), times, model.q,
                                            estimates=states))
    if meas.state.size == 0:
        return graph
    gauss = gtsam.noiseModel.Isotropic.Sigma(1, model.sigma_bearing)
    widx = meas.weight_index if meas.weight_index.size else np.full(meas.state.size, -1)
    hard = widx < 0
    if hard.any():
        for factor in linear_bearing_factors(
            _robust_noise(gauss, loss, model.k), meas.state[hard], meas.bearing[hard],
            estimates=states[meas.state[hard]],
        ):
            graph.add(factor)
    if not hard.all() and loss == "none":
        # Gaussian: w times a bearing factor's cost is the cost of the same factor with
        # sigma / sqrt(w) (factors.weighted.sqrt_weights), built in C++; w < 1e-12 adds nothing
        soft = np.flatnonzero(~hard)
        scale = sqrt_weights(weights[widx[soft]])
        for i, r in zip(soft[scale > 1e-6], scale[scale > 1e-6], strict=True):
            graph.add(linear_bearing_factors(
                gtsam.noiseModel.Isotropic.Sigma(1, model.sigma_bearing / r), meas.state[i: i + 1],
                meas.bearing[i: i + 1], estimates=states[meas.state[i: i + 1]])[0])
    elif not hard.all():
        wrap_noise = _robust_noise(gtsam.noiseModel.Unit.Create(2), loss, model.k)
        inner = linear_bearing_factors(gauss, meas.state[~hard], meas.bearing[~hard],
                                       estimates=states[meas.state[~hard]])
        for factor, w in zip(inner, widx[~hard], strict=True):
            graph.add(weighted_factor(factor, weights, int(w), noise=wrap_noise))
    return graph


def _natural(n: int) -> gtsam.Ordering:
    ordering = gtsam.Ordering()
    for k in range(n):
        ordering.push_back(k)
    return ordering


def _eliminate(graph: gtsam.GaussianFactorGraph) -> gtsam.GaussianBayesNet:
    """QR elimination of a linear chain graph (keys 0..n-1) along the chain."""
    return graph.eliminateSequential(_natural(len(graph.keys())), gtsam.EliminateQR)


def _solve_linear(graph: gtsam.GaussianFactorGraph) -> gtsam.VectorValues:
    """``argmin ||A dx - b||^2`` of a linear chain graph (keys 0..n-1) by QR.

    GTSAM's default (Cholesky of ``A^T A``) squares the condition number: with a small bearing
    acceleration PSD (rigid motion factors, information ~ 1/(q dt^3)) beside a weak prior and a
    few bearings it declares such well-posed chains "indeterminate" (issue 18: most crossing
    episodes of the hard passive benchmark fell back to nearest assignment for it). QR works
    on ``A`` itself and solves them; along the chain (natural order) it costs O(n).
    """
    return _eliminate(graph).optimize()


def _chain_marginals(graph: gtsam.GaussianFactorGraph, n: int,
                     bn: gtsam.GaussianBayesNet | None = None) -> list[FloatArray]:
    """Marginal covariances (2, 2) of the states 0..n-1 of a linear chain graph.

    QR elimination along the chain gives conditionals ``R_k x_k + S_k x_{k+1} = d_k`` (unit
    noise); backwards, ``Sigma_k = A_k Sigma_{k+1} A_k^T + R_k^{-1} R_k^{-T}`` with
    ``A_k = -R_k^{-1} S_k``: the covariances of ``gtsam.Marginals`` without its Cholesky
    factorisation, which fails on the same rigid chains as :func:`_solve_linear`'s default.
    `bn`: the graph's elimination (:func:`_eliminate`) if already done.
    """
    bn = graph.eliminateSequential(_natural(n), gtsam.EliminateQR) if bn is None else bn
    conds = [bn.at(k) for k in range(n)]
    r_inv = np.linalg.inv(np.array([c.R() for c in conds]))  # all states at once
    own = r_inv @ r_inv.transpose(0, 2, 1)
    cov: list[FloatArray] = [np.zeros((2, 2))] * n
    for k in range(n - 1, -1, -1):
        keys = list(conds[k].keys())
        if len(keys) == 1:
            cov[k] = own[k]
        else:
            if keys != [k, k + 1]:
                raise RuntimeError(f"not a chain graph: state {k} depends on {keys[1:]}")
            a = -r_inv[k] @ conds[k].S()
            cov[k] = a @ cov[k + 1] @ a.T + own[k]
    return cov


def _chain_bearing_covariance(graph: gtsam.GaussianFactorGraph, n: int,
                              states: NDArray[np.int64],
                              bn: gtsam.GaussianBayesNet | None = None) -> FloatArray:
    """Joint covariance (r, r) of the bearings of states `states` (r indices into 0..n-1, any
    order, repeats allowed) of a linear chain graph.

    From the same QR conditionals as :func:`_chain_marginals`: ``x_k = A_k x_{k+1} + e_k`` with
    ``e_k`` independent of ``x_{k+1}``, so ``Cov(x_i, x_j) = A_i ... A_{j-1} Sigma_j`` for
    ``i <= j``; the products are carried backwards along the chain, all needed states at once.
    `bn`: the graph's elimination (:func:`_eliminate`) if already done.
    """
    want = np.unique(states)
    bn = graph.eliminateSequential(_natural(n), gtsam.EliminateQR) if bn is None else bn
    r = want.size
    cross = np.zeros((r, 2, 2))  # Cov(x_k, x_{want[b]}) for the needed states after k
    out = np.zeros((r, r))
    pos = r - 1
    sigma = np.zeros((2, 2))
    for k in range(n - 1, int(want[0]) - 1, -1):
        c = bn.at(k)
        r_inv = np.linalg.inv(c.R())
        own = r_inv @ r_inv.T
        if k == n - 1:
            a = None
            sigma = own
        else:
            a = -r_inv @ c.S()
            sigma = a @ sigma @ a.T + own
            cross[pos + 1:] = a @ cross[pos + 1:]  # Cov(x_k, x_j) = A_k Cov(x_{k+1}, x_j)
        if pos >= 0 and want[pos] == k:
            cross[pos] = sigma
            out[pos, pos:] = cross[pos:, 0, 0]
            out[pos:, pos] = cross[pos:, 0, 0]
            pos -= 1
    where = np.searchsorted(want, states)
    return out[np.ix_(where, where)]


def _branches(
    times: FloatArray, meas: _Measurements, prior: TrackPrior | None, states: FloatArray
) -> FloatArray:
    """Whole turns (rad) added to each bearing, the prior bearing and each motion residual by
    re-centring on `states`."""
    z_turns = nearest_branch(meas.bearing, states[meas.state, 0]) - meas.bearing
    p_turns = [] if prior is None else [nearest_branch(prior.bearing, states[0, 0]) - prior.bearing]
    e = states[1:, 0] - states[:-1, 0] - np.diff(times) * states[:-1, 1]  # bearing part of e_k
    return np.concatenate([z_turns, p_turns, wrap_angle(e) - e])


def _optimize(
    times: FloatArray,
    meas: _Measurements,
    prior: TrackPrior | None,
    model: _Model,
    loss: str,
    weights: FloatArray | None,
    states: FloatArray,
    on_iteration: Callable[[], None] | None = None,
) -> tuple[gtsam.NonlinearFactorGraph | gtsam.GaussianFactorGraph, gtsam.Values, FloatArray,
           gtsam.GaussianBayesNet | None]:
    """Minimise the graph built at `states`; rebuilt at the solution and solved again while the
    solution moved a bearing or motion residual onto another branch.

    Without a robust loss every factor is linear, so one Gauss-Newton step (one sparse linear
    solve) reaches the minimum and the linear graph is returned for the marginals; the Huber
    loss on unweighted bearings is minimised by Newton steps on the same linear solve
    (:func:`~fusion.passive.smoothing.huber.huber_minimum`), any other robust loss by
    Levenberg-Marquardt; `on_iteration()` is called after each iteration (GTSAM's iteration
    hook for LM: the iterations are unchanged). The last item returned is the QR elimination
    of the returned linear graph (None with a robust loss), for its marginals.
    """
    bn = None
    for _ in range(_MAX_RECENTRE):
        graph = _build_graph(times, meas, prior, model, loss, weights, states)
        values = gtsam.Values()
        for k in range(times.size):
            values.insert(k, states[k])
        if loss == "none":
            graph = graph.linearize(values)
            bn = _eliminate(graph)
            values = values.retract(bn.optimize())  # x = x_0 + argmin ||A dx - b||^2
        elif loss == "huber" and not (meas.weight_index >= 0).any():
            # Newton steps on the exact Huber cost (fusion.passive.smoothing.huber): LM on the
            # robust noise model is reweighted least squares and crawls when many bearings
            # lie beyond the threshold
            motion = _build_graph(times, _Measurements(state=np.zeros(0, np.int64),
                                                       bearing=np.zeros(0)),
                                  prior, model, "none", None, states).linearize(values)
            new = huber_minimum(times, meas.state, meas.bearing, prior, model, states, motion,
                                _solve_linear, on_iteration)
            values = gtsam.Values()
            for k in range(times.size):
                values.insert(k, new[k])
        else:
            params = _lm_params(model.max_iterations)
            if on_iteration is not None:
                params.iterationHook = lambda *_: on_iteration()
            values = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
        new = np.array([values.atVector(k) for k in range(times.size)])
        same = np.all(np.abs(_branches(times, meas, prior, new)
                             - _branches(times, meas, prior, states)) < np.pi)
        states = new
        if same:
            break
    else:
        logger.warning("bearing branches still changing after %d re-centred solves",
                       _MAX_RECENTRE)
    return graph, values, states, bn


def _row_medians(a: FloatArray) -> FloatArray:
    """Median of each row of `a` (n, w) ignoring NaN; every row holds at least one number."""
    srt = np.sort(a, axis=1)  # NaN last
    cnt = np.sum(~np.isnan(a), axis=1)
    rows = np.arange(a.shape[0])
    upper = srt[rows, cnt // 2]
    lower = srt[rows, np.maximum(cnt - 1, 0) // 2]
    return np.where(cnt % 2 == 1, upper, (lower + upper) / 2.0)


def _initial_states(times: FloatArray, meas: _Measurements, prior: TrackPrior | None) -> FloatArray:
    """Initial ``(n, 2)`` states robust to outlier bearings: per state a running circular median
    of the measurements within 3 states, unwrapped and interpolated; the rate is the running
    median of the slopes."""
    n = times.size
    if meas.state.size == 0:
        b0 = prior.bearing if prior is not None else 0.0
        r0 = prior.rate if prior is not None else 0.0
        return np.column_stack([b0 + r0 * (times - times[0]), np.full(n, r0)])
    half = 3
    order = np.argsort(meas.state, kind="stable")
    st, zz = meas.state[order], meas.bearing[order]
    uniq = np.unique(st)
    lo = np.searchsorted(st, uniq - half, side="left")  # measurements of states s-3 .. s+3
    hi = np.searchsorted(st, uniq + half, side="right")
    width = int((hi - lo).max())
    idx = lo[:, None] + np.arange(width)[None, :]
    inside = idx < hi[:, None]
    zs = np.where(inside, zz[np.minimum(idx, zz.size - 1)], np.nan)
    ref = np.angle(np.nansum(np.exp(1j * zs), axis=1))  # circular mean of each window
    med = ref + _row_medians(wrap_angle(zs - ref[:, None]))
    med = np.unwrap(med)
    ts = times[uniq]
    theta = np.interp(times, ts, med)
    if uniq.size >= 2:
        slope = np.diff(med) / np.maximum(np.diff(ts), 1e-12)
        mid = 0.5 * (ts[1:] + ts[:-1])
        padded = np.concatenate([np.full(half, np.nan), slope, np.full(half, np.nan)])
        sm = _row_medians(np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1))
        rate = np.interp(times, mid, sm)
    else:
        rate = np.full(n, prior.rate if prior is not None else 0.0)
    return np.column_stack([theta, rate])


def _deep_for_long_chains(fn: Callable) -> Callable:
    """Run `fn(times, ...)` on a deep stack when the chain has more than _DEEP_CHAIN states."""

    @functools.wraps(fn)
    def wrapper(times, *args, **kwargs):
        if np.size(times) > _DEEP_CHAIN:
            return with_deep_stack(fn, times, *args, **kwargs)
        return fn(times, *args, **kwargs)

    return wrapper


@_deep_for_long_chains
def _solve(
    times: FloatArray,
    meas: _Measurements,
    prior: TrackPrior | None,
    model: _Model,
    *,
    init: FloatArray | None = None,
    weights: FloatArray | None = None,
    marginals: bool = False,
    on_rows: Callable[[int], None] | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """Minimise one track graph (:func:`_optimize`); states (n, 2) and optionally sigmas (n, 2).

    `on_rows(n)` (a progress bar's ``update``) is handed the graph's measurement rows in parts
    as the work goes on: half of them over the minimisation (half of what is left after each
    Levenberg-Marquardt iteration), the other half once the marginals are done (all of them
    over the minimisation without marginals).
    """
    states = np.asarray(_initial_states(times, meas, prior) if init is None else init, float)
    losses = [model.loss] if model.loss != "cauchy" else ["huber", "cauchy"]
    rows = int(meas.state.size)
    solve = RowShare(rows - (rows // 2 if marginals else 0), on_rows)
    graph = values = None
    for loss in losses:  # a redescending loss starts from the convex Huber solution
        graph, values, states, bn = _optimize(times, meas, prior, model, loss, weights, states,
                                          solve.half if on_rows is not None else None)
    solve.rest()
    if not marginals:
        return states, None
    share = RowShare(rows // 2, on_rows)
    lin = graph if isinstance(graph, gtsam.GaussianFactorGraph) else graph.linearize(values)
    var = np.array([c.diagonal() for c in _chain_marginals(lin, times.size,
                                                           bn if lin is graph else None)])
    share.rest()
    return states, np.sqrt(var)


@_deep_for_long_chains
def _solve_cov(
    times: FloatArray,
    meas: _Measurements,
    prior: TrackPrior,
    model: _Model,
    init: FloatArray,
    keys: Sequence[int],
) -> tuple[FloatArray, list[FloatArray]]:
    """Minimise one track graph (hard factors, Gaussian); states (n, 2) and the marginal
    covariances (2, 2) of the states `keys`."""
    graph, values, states, bn = _optimize(times, meas, prior, model, "none", None,
                                          np.asarray(init, float))
    cov = _chain_marginals(graph, times.size, bn)
    return states, [cov[int(k)] for k in keys]


def _default_prior(z0: float, model: _Model, sigma_rate: float) -> TrackPrior:
    return TrackPrior(bearing=float(z0), rate=0.0, sigma_bearing=10.0 * model.sigma_bearing,
                      sigma_rate=sigma_rate)
