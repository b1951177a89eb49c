"""Bearing-rate smoothing on factor graphs: one track, online, and many tracks through crossings.

Every track is a chain of states ``x_k = (theta_k, theta_dot_k)`` (bearing, rad; bearing rate,
rad/s) at the scan times, tied by constant-rate motion factors with white-noise-acceleration
noise (:func:`factors.motion.wna_covariance`) and by bearing factors, with a prior on the first
state (for instance from acquisition). This is the bearing-rate graph of the project's design
notes ("Factor graphs"). Apart from the wrap of the bearings the model is linear, so it is built
from GTSAM's own linear factors, evaluated in C++ (:func:`factors.motion.constant_velocity_chain`,
:func:`factors.bearing.linear_bearing_factors`): every bearing (and the prior bearing) is put on
the branch nearest the current estimate, motion residuals are wrapped at the linearisation
point, and a graph whose solution moved a residual onto another branch is re-centred there and
solved again. The result is the optimum of the wrapped model of the scalar factors
(:func:`factors.bearing.bearing_factor`, :func:`factors.motion.constant_velocity_factor`).

- :class:`BearingSmoother` -- batch smoothing of one track: one sparse linear solve (Gaussian
  noise) or Levenberg-Marquardt (optional Huber/Cauchy noise for outlier bearings), covariances
  from ``gtsam.Marginals``. On linear-Gaussian data it equals a Rauch-Tung-Striebel smoother.
- :class:`OnlineBearingSmoother` -- the same graph grown one scan at a time with iSAM2;
  :class:`OnlineBearingSmootherSet` grows many tracks in one iSAM2, one update per scan.
- :class:`NearestNeighbourTracker` -- a Kalman (filterpy) bearing tracker with global nearest
  neighbour assignment. Alone it is the baseline; with ``crossing_aware=True`` it predicts
  crossings and lets tracks coast through them, leaving the ambiguous detections shared.
- :class:`MultiTrackSmoother` -- tracks from unlabeled per-scan detections: initial tracks from
  the crossing-aware tracker, then expectation-maximisation around every crossing. Shared
  detections enter each candidate track through association-weighted factors
  (:func:`factors.weighted.weighted_factor`) whose weights are the detections' responsibilities
  (each track's predicted likelihood against a clutter component), re-estimated until they
  settle; graphs stay small (one per track and crossing cluster).

Crossings are predicted with "Target Track Crossing Prediction/Detection" (Struzinski): the
crossing time of two straight bearing tracks, eq. (2), ``t_c = (B0_2 - B0_1) / (B'_1 - B'_2)``,
is tested against the prediction window, eq. (3), and the detection window, eq. (4).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import gtsam
import numpy as np
from filterpy.kalman import KalmanFilter, rts_smoother
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from factors.angles import nearest_branch
from factors.bearing import linear_bearing_factors, state_bearing_noise
from factors.motion import (
    constant_velocity_chain,
    constant_velocity_steps,
    transition_matrix,
    wna_covariance,
)
from factors.weighted import weighted_factor
from fusion._validation import check_positive
from fusion.geometry import wrap_angle

__all__ = [
    "CROSSING_OUTCOMES",
    "BearingSmoother",
    "MultiTrackResult",
    "MultiTrackSmoother",
    "NearestNeighbourTracker",
    "OnlineBearingSmoother",
    "OnlineBearingSmootherSet",
    "SmoothedTrack",
    "TrackPrior",
    "TrackerResult",
    "crossing_outcomes",
    "crossing_time",
    "identity_swaps",
    "rts_reference",
    "smooth_bearings",
]

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Robust loss names accepted by the smoothers.
ROBUST_LOSSES = ("none", "huber", "cauchy")

#: Solves of one graph at most, re-centring the bearings on the previous solution each time.
_MAX_RECENTRE = 5


# --------------------------------------------------------------------------------------------
# data


@dataclass(frozen=True)
class TrackPrior:
    """Gaussian prior on a track's first state (e.g. from acquisition).

    Attributes
    ----------
    bearing : float
        Bearing, rad.
    rate : float
        Bearing rate, rad/s.
    sigma_bearing : float
        Standard deviation of `bearing`, rad (> 0).
    sigma_rate : float
        Standard deviation of `rate`, rad/s (> 0).
    """

    bearing: float
    rate: float
    sigma_bearing: float
    sigma_rate: float

    def __post_init__(self) -> None:
        for name in ("bearing", "rate"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"prior {name} must be finite")
        for name in ("sigma_bearing", "sigma_rate"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"prior {name} must be finite and > 0, got {v!r}")

    @property
    def mean(self) -> FloatArray:
        """``[bearing, rate]``, shape (2,)."""
        return np.array([self.bearing, self.rate])

    @property
    def covariance(self) -> FloatArray:
        """Diagonal covariance, shape (2, 2)."""
        return np.diag([self.sigma_bearing**2, self.sigma_rate**2])


@dataclass(frozen=True)
class SmoothedTrack:
    """A smoothed bearing track.

    Attributes
    ----------
    track_id : int
        Track identifier.
    times : ndarray, shape (n,)
        State times, s, increasing.
    bearing : ndarray, shape (n,)
        Smoothed bearing, rad, wrapped to [-pi, pi).
    rate : ndarray, shape (n,)
        Smoothed bearing rate, rad/s.
    sigma_bearing : ndarray, shape (n,)
        Marginal standard deviation of the bearing, rad.
    sigma_rate : ndarray, shape (n,)
        Marginal standard deviation of the rate, rad/s.
    """

    track_id: int
    times: FloatArray
    bearing: FloatArray
    rate: FloatArray
    sigma_bearing: FloatArray
    sigma_rate: FloatArray

    def __len__(self) -> int:
        return int(self.times.shape[0])


@dataclass(frozen=True)
class TrackerResult:
    """Output of :class:`NearestNeighbourTracker`.

    Attributes
    ----------
    labels : ndarray of int, shape (n_detections,)
        Track index of each detection (in input order), ``-1`` for none (clutter, tentative or
        shared).
    candidates : tuple of tuple of int, length n_detections
        For a detection inside a crossing region, the tracks that may own it (two or more);
        empty otherwise.
    first_scan, last_scan : ndarray of int, shape (n_tracks,)
        Scan indices (into `scan_times`) of each confirmed track's first and last state.
    states : tuple of ndarray
        Per track, the filtered states ``(n_scans_of_track, 2)`` [rad (unwrapped), rad/s].
    scan_times : ndarray, shape (n_scans,)
        The distinct detection times, s.
    """

    labels: NDArray[np.int64]
    candidates: tuple[tuple[int, ...], ...]
    first_scan: NDArray[np.int64]
    last_scan: NDArray[np.int64]
    states: tuple[FloatArray, ...]
    scan_times: FloatArray

    @property
    def n_tracks(self) -> int:
        """Number of confirmed tracks."""
        return len(self.states)


@dataclass(frozen=True)
class MultiTrackResult:
    """Output of :class:`MultiTrackSmoother`.

    Attributes
    ----------
    tracks : tuple of SmoothedTrack
        One per track, ``track_id`` 0, 1, ...
    labels : ndarray of int, shape (n_detections,)
        Most probable owner (``track_id``) of each detection in input order, ``-1`` for clutter.
    shared : ndarray of bool, shape (n_detections,)
        Detections that entered more than one track through association-weighted factors.
    em_iterations : int
        Largest number of expectation-maximisation iterations over the crossing clusters.
    """

    tracks: tuple[SmoothedTrack, ...]
    labels: NDArray[np.int64]
    shared: NDArray[np.bool_]
    em_iterations: int


# --------------------------------------------------------------------------------------------
# helpers


def crossing_time(
    bearing_a: ArrayLike, rate_a: ArrayLike, bearing_b: ArrayLike, rate_b: ArrayLike
) -> FloatArray | float:
    """Time until two straight bearing tracks cross, s (relative to the time of the bearings).

    Parameters
    ----------
    bearing_a, bearing_b : float or array_like
        Bearings at a common reference time, rad (the intercepts ``B0`` of eq. (1)).
    rate_a, rate_b : float or array_like
        Bearing rates, rad/s (``B'``).

    Returns
    -------
    float or ndarray
        ``t_c`` of "Target Track Crossing Prediction/Detection", eq. (2), taking the wrapped
        bearing difference; ``inf`` for parallel tracks.

    Examples
    --------
    >>> round(crossing_time(0.0, 0.01, 0.1, 0.0), 9)
    10.0
    """
    db = wrap_angle(np.asarray(bearing_b, float) - np.asarray(bearing_a, float))
    dr = np.asarray(rate_a, float) - np.asarray(rate_b, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        tc = np.where(dr != 0.0, db / np.where(dr != 0.0, dr, 1.0), np.inf)  # eq. (2)
    return float(tc) if np.ndim(tc) == 0 else tc


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
    if not hard.all():
        wrap_noise = _robust_noise(gtsam.noiseModel.Unit.Create(2), loss, model.k)
        inner = linear_bearing_factors(gauss, meas.state[~hard], meas.bearing[~hard],
                                       estimates=states[meas.state[~hard]])
        for factor, w in zip(inner, widx[~hard], strict=True):
            graph.add(weighted_factor(factor, weights, int(w), noise=wrap_noise))
    return graph


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
) -> tuple[gtsam.NonlinearFactorGraph | gtsam.GaussianFactorGraph, gtsam.Values, FloatArray]:
    """Minimise the graph built at `states`; rebuilt at the solution and solved again while the
    solution moved a bearing or motion residual onto another branch.

    Without a robust loss every factor is linear, so one Gauss-Newton step (one sparse linear
    solve) reaches the minimum and the linear graph is returned for the marginals; a robust
    loss is minimised by Levenberg-Marquardt.
    """
    for _ in range(_MAX_RECENTRE):
        graph = _build_graph(times, meas, prior, model, loss, weights, states)
        values = gtsam.Values()
        for k in range(times.size):
            values.insert(k, states[k])
        if loss == "none":
            graph = graph.linearize(values)
            values = values.retract(graph.optimize())  # x = x_0 + argmin ||A dx - b||^2
        else:
            values = gtsam.LevenbergMarquardtOptimizer(
                graph, values, _lm_params(model.max_iterations)
            ).optimize()
        new = np.array([values.atVector(k) for k in range(times.size)])
        same = np.all(np.abs(_branches(times, meas, prior, new)
                             - _branches(times, meas, prior, states)) < np.pi)
        states = new
        if same:
            break
    else:
        logger.warning("bearing branches still changing after %d re-centred solves",
                       _MAX_RECENTRE)
    return graph, values, states


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


def _solve(
    times: FloatArray,
    meas: _Measurements,
    prior: TrackPrior | None,
    model: _Model,
    *,
    init: FloatArray | None = None,
    weights: FloatArray | None = None,
    marginals: bool = False,
) -> tuple[FloatArray, FloatArray | None]:
    """Minimise one track graph (:func:`_optimize`); states (n, 2) and optionally sigmas (n, 2)."""
    states = np.asarray(_initial_states(times, meas, prior) if init is None else init, float)
    losses = [model.loss] if model.loss != "cauchy" else ["huber", "cauchy"]
    graph = values = None
    for loss in losses:  # a redescending loss starts from the convex Huber solution
        graph, values, states = _optimize(times, meas, prior, model, loss, weights, states)
    if not marginals:
        return states, None
    marg = gtsam.Marginals(graph, values)
    var = np.array([marg.marginalCovariance(k).diagonal() for k in range(times.size)])
    return states, np.sqrt(var)


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
    graph, values, states = _optimize(times, meas, prior, model, "none", None,
                                      np.asarray(init, float))
    marg = gtsam.Marginals(graph, values)
    return states, [np.asarray(marg.marginalCovariance(int(k))) for k in keys]


def _default_prior(z0: float, model: _Model, sigma_rate: float) -> TrackPrior:
    return TrackPrior(bearing=float(z0), rate=0.0, sigma_bearing=10.0 * model.sigma_bearing,
                      sigma_rate=sigma_rate)


# --------------------------------------------------------------------------------------------
# one track, batch


class BearingSmoother:
    """Batch bearing-rate smoother of one track (the bearing-rate graph minimised at once).

    Parameters
    ----------
    sigma_bearing : float, keyword-only
        Standard deviation of a bearing measurement, rad.
    q : float, keyword-only
        Bearing acceleration power spectral density, rad^2/s^3 (white-noise-acceleration model).
    robust : {"none", "huber", "cauchy"}, keyword-only
        Loss on the bearing factors (``gtsam.noiseModel.Robust``); ``"cauchy"`` is solved from
        the Huber solution.
    robust_k : float, keyword-only
        Robust loss threshold in standard deviations (default 1.345, the 95 %-efficient Huber).
    prior_sigma_rate : float, keyword-only
        Rate standard deviation of the default prior (first bearing, zero rate), rad/s.
    max_iterations : int, keyword-only
        Levenberg-Marquardt iteration cap (robust losses).

    Notes
    -----
    Cost: ``||x_0 - m_0||^2_P0 + sum_k ||x_{k+1} - F_k x_k||^2_{Q_k} + sum_j rho(wrap(theta_{k_j}
    - z_j) / sigma)``, with ``F_k`` and ``Q_k`` of :mod:`factors.motion`. With ``robust="none"``
    and no wrapping this is the linear-Gaussian smoothing problem whose solution is the
    Rauch-Tung-Striebel smoother (same ``F``, ``Q``, ``H = [1, 0]``, ``R = sigma^2``, prior);
    it is solved by one sparse linear solve. Several bearings may share a time (they all tie
    that state).

    Examples
    --------
    >>> t = np.arange(20.0)
    >>> sm = BearingSmoother(sigma_bearing=0.01, q=1e-8)
    >>> tr = sm.smooth(t, 0.3 + 0.002 * t)
    >>> bool(abs(tr.rate[5] - 0.002) < 1e-4)
    True
    """

    def __init__(
        self,
        *,
        sigma_bearing: float,
        q: float,
        robust: str = "none",
        robust_k: float = 1.345,
        prior_sigma_rate: float = 0.05,
        max_iterations: int = 100,
    ) -> None:
        self.model = _Model(
            sigma_bearing=check_positive("sigma_bearing", sigma_bearing),
            q=check_positive("q", q),
            loss=_check_loss(robust),
            k=check_positive("robust_k", robust_k),
            max_iterations=int(max_iterations),
        )
        self.prior_sigma_rate = check_positive("prior_sigma_rate", prior_sigma_rate)

    def smooth(
        self,
        times: ArrayLike,
        bearings: ArrayLike,
        *,
        prior: TrackPrior | None = None,
        track_id: int = 0,
    ) -> SmoothedTrack:
        """Smooth one track.

        Parameters
        ----------
        times : array_like, shape (n,)
            Measurement times, s, non-decreasing (equal times share a state).
        bearings : array_like, shape (n,)
            Measured bearings, rad (any branch).
        prior : TrackPrior, optional
            Prior on the first state; default: first bearing with ``10 sigma_bearing``, zero
            rate with ``prior_sigma_rate``.
        track_id : int, optional
            Identifier copied to the result.

        Returns
        -------
        SmoothedTrack
            One state per distinct time.
        """
        t, z = _check_detections(times, bearings)
        state_times, state_of = np.unique(t, return_inverse=True)
        meas = _Measurements(state=state_of.astype(np.int64), bearing=z)
        if prior is None:
            x0 = _initial_states(state_times, meas, None)[0]
            prior = _default_prior(x0[0], self.model, self.prior_sigma_rate)
        states, sig = _solve(state_times, meas, prior, self.model, marginals=True)
        return SmoothedTrack(
            track_id=int(track_id),
            times=state_times,
            bearing=np.asarray(wrap_angle(states[:, 0])),
            rate=states[:, 1].copy(),
            sigma_bearing=sig[:, 0],
            sigma_rate=sig[:, 1],
        )


# --------------------------------------------------------------------------------------------
# one track, online


def rts_reference(
    times: ArrayLike, bearings: ArrayLike, prior: TrackPrior, *, sigma_bearing: float, q: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """filterpy's Kalman filter + Rauch-Tung-Striebel smoother on the bearing-rate model.

    The linear-Gaussian reference that :class:`BearingSmoother` equals on unwrapped data (the
    bearings are used as given, without wrapping).

    Parameters
    ----------
    times : array_like, shape (n,)
        Scan times, s, increasing.
    bearings : array_like, shape (n,)
        One bearing per scan, rad.
    prior : TrackPrior
        Prior of the first state.
    sigma_bearing : float
        Bearing noise standard deviation, rad.
    q : float
        Bearing-acceleration PSD, rad^2/s^3.

    Returns
    -------
    x, P, K, Pp : ndarray
        ``filterpy.kalman.rts_smoother`` outputs: smoothed states (n, 2), covariances (n, 2, 2),
        smoother gains and predicted covariances.
    """
    t = np.asarray(times, dtype=float)
    z = np.asarray(bearings, dtype=float)
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.x, kf.P = prior.mean.copy(), prior.covariance.copy()
    kf.H, kf.R = np.array([[1.0, 0.0]]), np.array([[sigma_bearing**2]])
    xs, ps, fs, qs = [], [], [], []
    for k in range(t.size):
        if k:
            F, Q = transition_matrix(t[k] - t[k - 1], 1), wna_covariance(t[k] - t[k - 1], q, 1)
            kf.predict(F=F, Q=Q)
            fs.append(F)
            qs.append(Q)
        kf.update(np.array([z[k]]))
        xs.append(kf.x.copy())
        ps.append(kf.P.copy())
    # filterpy applies Fs[k], Qs[k] between steps k and k + 1; the last pair is unused
    fs.append(np.eye(2))
    qs.append(np.zeros((2, 2)))
    return rts_smoother(np.array(xs), np.array(ps), fs, qs)


class OnlineBearingSmootherSet:
    """Several bearing tracks grown scan by scan in one iSAM2: one update per scan.

    Every track is the bearing-rate graph of :class:`BearingSmoother`; the tracks share the scan
    times and one ``gtsam.ISAM2``, so a scan costs one update whatever the number of tracks.

    Parameters
    ----------
    priors : sequence of TrackPrior, keyword-only
        Prior on each track's state at `t0` (one per track, at least one).
    t0 : float, keyword-only
        Time of the first states, s.
    sigma_bearing, q, robust, robust_k :
        As in :class:`BearingSmoother`.
    relinearize_threshold : float, keyword-only
        iSAM2 relinearization threshold (tangent-space step), default 1e-3; used with a robust
        loss only.

    Notes
    -----
    Built-in linear factors (:func:`factors.motion.constant_velocity_steps` for the motion of all
    tracks over a scan, :func:`factors.bearing.linear_bearing_factors`): a new state enters at its
    constant-rate prediction and its bearings on the branch nearest that prediction. Without a
    robust loss every factor is linear, so relinearization cannot change the estimate and is
    switched off; with one, iSAM2 relinearizes (the robust weights depend on the estimate).
    The cost of an iSAM2 update grows slowly with the length of the chains it holds.

    Examples
    --------
    >>> priors = [TrackPrior(bearing=b, rate=0.0, sigma_bearing=0.1, sigma_rate=0.01)
    ...           for b in (0.3, -2.0)]
    >>> on = OnlineBearingSmootherSet(priors=priors, t0=0.0, sigma_bearing=0.01, q=1e-8)
    >>> for k in range(1, 10):
    ...     est = on.step(float(k), [[0.3 + 0.002 * k], []])
    >>> est.shape, bool(abs(est[0, 1] - 0.002) < 5e-4)
    ((2, 2), True)
    """

    def __init__(
        self,
        *,
        priors: Sequence[TrackPrior],
        t0: float,
        sigma_bearing: float,
        q: float,
        robust: str = "none",
        robust_k: float = 1.345,
        relinearize_threshold: float = 1e-3,
    ) -> None:
        self.model = _Model(
            sigma_bearing=check_positive("sigma_bearing", sigma_bearing),
            q=check_positive("q", q),
            loss=_check_loss(robust),
            k=check_positive("robust_k", robust_k),
            max_iterations=1,
        )
        if not np.isfinite(t0):
            raise ValueError("t0 must be finite")
        priors = list(priors)
        if not priors or not all(isinstance(p, TrackPrior) for p in priors):
            raise ValueError("priors must be a non-empty sequence of TrackPrior")
        self._n = len(priors)
        params = gtsam.ISAM2Params()
        params.enableRelinearization = self.model.loss != "none"
        params.setRelinearizeThreshold(float(relinearize_threshold))
        params.relinearizeSkip = 1
        self._isam = gtsam.ISAM2(params)
        self._times: list[float] = [float(t0)]
        self._last = np.array([p.mean for p in priors])  # (n_tracks, 2)
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        for j, p in enumerate(priors):
            graph.add(gtsam.PriorFactorVector(self._key(0, j), p.mean,
                                              gtsam.noiseModel.Gaussian.Covariance(p.covariance)))
            values.insert(self._key(0, j), p.mean)
        self._isam.update(graph, values)
        base = gtsam.noiseModel.Isotropic.Sigma(1, self.model.sigma_bearing)
        self._state_noise = state_bearing_noise(_robust_noise(base, self.model.loss, self.model.k), 2)

    def _key(self, k: int, track: int) -> int:
        """Key of state `k` of `track`."""
        return k * self._n + track

    def _check_track(self, track: int) -> int:
        if isinstance(track, bool) or int(track) != track or not 0 <= int(track) < self._n:
            raise ValueError(f"track must be an index in [0, {self._n}), got {track!r}")
        return int(track)

    @property
    def n_tracks(self) -> int:
        """Number of tracks."""
        return self._n

    @property
    def n_states(self) -> int:
        """Number of states of each track so far."""
        return len(self._times)

    def step(self, time: float, bearings: Sequence[Sequence[float]]) -> FloatArray:
        """Add one scan of every track and update.

        Parameters
        ----------
        time : float
            Scan time, s, after the previous one (equal to it adds bearings to the last states).
        bearings : sequence of sequence of float, length n_tracks
            Each track's bearings of this scan, rad (empty for a miss).

        Returns
        -------
        ndarray, shape (n_tracks, 2)
            Current (filtered) states ``[bearing (rad, wrapped), rate (rad/s)]``.
        """
        time = float(time)
        if not np.isfinite(time) or time < self._times[-1]:
            raise ValueError(f"scan time {time!r} is before the previous scan {self._times[-1]}")
        if len(bearings) != self._n:
            raise ValueError(f"{len(bearings)} bearing lists for {self._n} tracks")
        zs = [np.asarray(b, dtype=float).ravel() for b in bearings]
        owner = np.repeat(np.arange(self._n), [z.size for z in zs])
        z = np.concatenate(zs) if zs else np.zeros(0)
        if not np.all(np.isfinite(z)):
            raise ValueError("bearings must be finite")
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        dt = time - self._times[-1]
        ref = self._last
        k = len(self._times) - 1
        if dt > 0:
            ref = self._last.copy()
            ref[:, 0] += dt * self._last[:, 1]  # F x_{k-1}
            keys_prev = [self._key(k, j) for j in range(self._n)]
            k += 1
            keys_next = [self._key(k, j) for j in range(self._n)]
            graph.push_back(constant_velocity_steps(keys_prev, keys_next, dt, self.model.q,
                                                    estimates_prev=self._last,
                                                    estimates_next=ref))
            for key, x in zip(keys_next, ref, strict=True):
                values.insert(key, x)
            self._times.append(time)
        if z.size:
            for factor in linear_bearing_factors(
                self._state_noise, [self._key(k, j) for j in owner], z, estimates=ref[owner]
            ):
                graph.add(factor)
        self._isam.update(graph, values)
        self._last = np.array([self._isam.calculateEstimateVector(self._key(k, j))
                               for j in range(self._n)])
        return np.column_stack([wrap_angle(self._last[:, 0]), self._last[:, 1]])

    def covariance(self, track: int) -> FloatArray:
        """Marginal covariance of a track's latest state, shape (2, 2)."""
        return self._isam.marginalCovariance(self._key(len(self._times) - 1,
                                                       self._check_track(track)))

    def result(self, track: int, *, track_id: int | None = None) -> SmoothedTrack:
        """One track's states smoothed by the current iSAM2 estimate, with marginal sigmas.

        Parameters
        ----------
        track : int
            Track index (order of `priors`).
        track_id : int, optional, keyword-only
            Identifier copied to the result; default the index.
        """
        track = self._check_track(track)
        est = self._isam.calculateBestEstimate()
        n = len(self._times)
        keys = [self._key(k, track) for k in range(n)]
        states = np.array([est.atVector(key) for key in keys])
        var = np.array([self._isam.marginalCovariance(key).diagonal() for key in keys])
        sig = np.sqrt(var)
        return SmoothedTrack(track if track_id is None else int(track_id),
                             np.array(self._times), np.asarray(wrap_angle(states[:, 0])),
                             states[:, 1].copy(), sig[:, 0], sig[:, 1])


class OnlineBearingSmoother:
    """The bearing-rate graph of one track grown scan by scan with iSAM2.

    A :class:`OnlineBearingSmootherSet` of one track.

    Parameters
    ----------
    prior : TrackPrior, keyword-only
        Prior on the state at `t0`.
    t0 : float, keyword-only
        Time of the first state, s.
    sigma_bearing, q, robust, robust_k, relinearize_threshold :
        As in :class:`OnlineBearingSmootherSet`.

    Examples
    --------
    >>> prior = TrackPrior(bearing=0.3, rate=0.0, sigma_bearing=0.1, sigma_rate=0.01)
    >>> on = OnlineBearingSmoother(prior=prior, t0=0.0, sigma_bearing=0.01, q=1e-8)
    >>> for k in range(1, 10):
    ...     est = on.step(float(k), [0.3 + 0.002 * k])
    >>> bool(abs(est[1] - 0.002) < 5e-4)
    True
    """

    def __init__(
        self,
        *,
        prior: TrackPrior,
        t0: float,
        sigma_bearing: float,
        q: float,
        robust: str = "none",
        robust_k: float = 1.345,
        relinearize_threshold: float = 1e-3,
    ) -> None:
        self._set = OnlineBearingSmootherSet(
            priors=[prior], t0=t0, sigma_bearing=sigma_bearing, q=q, robust=robust,
            robust_k=robust_k, relinearize_threshold=relinearize_threshold)
        self.model = self._set.model

    @property
    def n_states(self) -> int:
        """Number of states so far."""
        return self._set.n_states

    def step(self, time: float, bearings: Sequence[float]) -> FloatArray:
        """Add one scan and update.

        Parameters
        ----------
        time : float
            Scan time, s, after the previous one (equal to it adds bearings to the last state).
        bearings : sequence of float
            The scan's bearings of this track, rad (empty for a miss).

        Returns
        -------
        ndarray, shape (2,)
            Current (filtered) state ``[bearing (rad, wrapped), rate (rad/s)]``.
        """
        return self._set.step(time, [bearings])[0]

    def covariance(self) -> FloatArray:
        """Marginal covariance of the latest state, shape (2, 2)."""
        return self._set.covariance(0)

    def result(self, *, track_id: int = 0) -> SmoothedTrack:
        """All states smoothed by the current iSAM2 estimate, with marginal sigmas."""
        return self._set.result(0, track_id=track_id)


# --------------------------------------------------------------------------------------------
# many tracks from unlabeled detections


class NearestNeighbourTracker:
    """Kalman bearing tracker with global nearest-neighbour assignment, optionally
    crossing-aware.

    Parameters
    ----------
    sigma_bearing : float, keyword-only
        Bearing measurement standard deviation, rad.
    q : float, keyword-only
        Bearing acceleration PSD, rad^2/s^3.
    gate : float, keyword-only
        Gate on the normalised innovation, standard deviations (default 4).
    init_sigma_rate : float, keyword-only
        Rate standard deviation of a new track, rad/s.
    n_confirm : int, keyword-only
        Hits that confirm a tentative track (default 3).
    max_misses : int, keyword-only
        Consecutive misses that end a track (default 5; 1 for a tentative track).
    crossing_aware : bool, keyword-only
        Predict crossings (Struzinski eq. (2)-(4)) and let both tracks coast on their
        prediction while their bearings are closer than `separation`; detections gated by
        several coasting tracks are left shared (their candidates recorded).
    separation : float, keyword-only
        Bearing separation below which a predicted crossing is ambiguous, rad (default
        ``gate * sqrt(2) * sigma_bearing``).
    window_scans : int, keyword-only
        ``J`` of eq. (3)-(4): a crossing counts when ``|t_c|`` is within ``J`` scan periods.

    Notes
    -----
    filterpy ``KalmanFilter`` per track, state ``[bearing, rate]``; the innovation is wrapped by
    handing the filter the measurement on the branch nearest the prediction. Assignment:
    ``scipy.optimize.linear_sum_assignment`` on squared normalised innovations, gated.
    """

    def __init__(
        self,
        *,
        sigma_bearing: float,
        q: float,
        gate: float = 4.0,
        init_sigma_rate: float = 0.01,
        n_confirm: int = 3,
        max_misses: int = 5,
        crossing_aware: bool = False,
        separation: float | None = None,
        window_scans: int = 20,
    ) -> None:
        self.sigma_bearing = check_positive("sigma_bearing", sigma_bearing)
        self.q = check_positive("q", q)
        self.gate = check_positive("gate", gate)
        self.init_sigma_rate = check_positive("init_sigma_rate", init_sigma_rate)
        if n_confirm < 1 or max_misses < 1 or window_scans < 1:
            raise ValueError("n_confirm, max_misses and window_scans must be >= 1")
        self.n_confirm = int(n_confirm)
        self.max_misses = int(max_misses)
        self.crossing_aware = bool(crossing_aware)
        sep = gate * np.sqrt(2.0) * sigma_bearing if separation is None else separation
        self.separation = check_positive("separation", sep)
        self.window_scans = int(window_scans)

    def _new_filter(self, z: float) -> KalmanFilter:
        kf = KalmanFilter(dim_x=2, dim_z=1)
        kf.x = np.array([float(z), 0.0])
        kf.P = np.diag([self.sigma_bearing**2, self.init_sigma_rate**2])
        kf.H = np.array([[1.0, 0.0]])
        kf.R = np.array([[self.sigma_bearing**2]])
        return kf

    def run(self, times: ArrayLike, bearings: ArrayLike) -> TrackerResult:
        """Track unlabeled detections.

        Parameters
        ----------
        times : array_like, shape (n,)
            Detection times, s, non-decreasing; detections with equal time form a scan.
        bearings : array_like, shape (n,)
            Bearings, rad.

        Returns
        -------
        TrackerResult
        """
        t, z = _check_detections(times, bearings)
        scan_times, scan_of = np.unique(t, return_inverse=True)
        starts = np.searchsorted(scan_of, np.arange(scan_times.size))
        stops = np.append(starts[1:], t.size)
        period = float(np.median(np.diff(scan_times))) if scan_times.size > 1 else 1.0
        labels = np.full(t.size, -1, np.int64)
        candidates: list[tuple[int, ...]] = [()] * t.size
        tracks: list[dict] = []  # kf, first, states, hits, misses, confirmed, dets
        s2 = self.sigma_bearing**2
        for k, tk in enumerate(scan_times):
            idx = np.arange(starts[k], stops[k])
            live = [i for i, tr in enumerate(tracks) if tr["alive"]]
            for i in live:  # predict
                tr = tracks[i]
                dt = tk - tr["t"]
                if dt > 0:
                    tr["kf"].predict(F=transition_matrix(dt, 1), Q=wna_covariance(dt, self.q, 1))
                    tr["t"] = tk
            coasting: set[int] = set()
            if self.crossing_aware:
                conf = [i for i in live if tracks[i]["confirmed"]]
                for a_pos, a in enumerate(conf):
                    for b in conf[a_pos + 1:]:
                        xa, xb = tracks[a]["kf"].x, tracks[b]["kf"].x
                        sep = abs(wrap_angle(xa[0] - xb[0]))
                        tc = crossing_time(xa[0], xa[1], xb[0], xb[1])  # eq. (2), from now
                        # eq. (3) predicted (0 < t_c <= J K) or eq. (4) detected (-J K <= t_c <= 0)
                        if sep < self.separation and abs(tc) <= self.window_scans * period:
                            coasting.update((a, b))
            # gated cost matrix of squared normalised innovations
            zk = z[idx]
            cost = np.full((len(live), idx.size), np.inf)
            for r, i in enumerate(live):
                kf = tracks[i]["kf"]
                S = kf.P[0, 0] + s2
                nu = wrap_angle(zk - kf.x[0])
                d2 = nu**2 / S
                cost[r] = np.where(d2 < self.gate**2, d2, np.inf)
            used = np.zeros(idx.size, bool)
            assigned: dict[int, int] = {}
            if coasting:
                rows = [r for r, i in enumerate(live) if i in coasting]
                for c in range(idx.size):
                    owners = tuple(live[r] for r in rows if np.isfinite(cost[r, c]))
                    if len(owners) >= 2:
                        candidates[idx[c]] = owners
                        used[c] = True
                    elif len(owners) == 1:
                        # gated by one coasting track only: still ambiguous near a crossing
                        candidates[idx[c]] = owners
                        used[c] = True
            # global nearest neighbour: confirmed tracks first, tentative ones on the rest
            for confirmed in (True, False):
                free_rows = [r for r, i in enumerate(live)
                             if i not in coasting and tracks[i]["confirmed"] == confirmed]
                free_cols = np.flatnonzero(~used)
                if not (free_rows and free_cols.size):
                    continue
                sub = cost[np.ix_(free_rows, free_cols)]
                rr, cc = linear_sum_assignment(np.where(np.isfinite(sub), sub, 1e6))
                for r, c in zip(rr, cc, strict=True):
                    if np.isfinite(sub[r, c]):
                        assigned[live[free_rows[r]]] = int(free_cols[c])
                        used[free_cols[c]] = True
            for i in live:
                tr = tracks[i]
                if i in assigned:
                    c = assigned[i]
                    kf = tr["kf"]
                    kf.update(np.array([kf.x[0] + wrap_angle(zk[c] - kf.x[0])]))
                    labels[idx[c]] = i
                    tr["hits"] += 1
                    tr["misses"] = 0
                    if tr["hits"] >= self.n_confirm:
                        tr["confirmed"] = True
                elif i not in coasting:
                    tr["misses"] += 1
                limit = self.max_misses if tr["confirmed"] else 1
                if tr["misses"] > limit:
                    tr["alive"] = False
                else:
                    tr["states"].append(tr["kf"].x.copy())
                    tr["last"] = k
            for c in np.flatnonzero(~used):  # new tentative tracks
                kf = self._new_filter(zk[c])
                labels[idx[c]] = len(tracks)
                tracks.append({"kf": kf, "t": tk, "first": k, "last": k, "states": [kf.x.copy()],
                               "hits": 1, "misses": 0, "confirmed": False, "alive": True})
        # keep confirmed tracks, drop trailing coasted states after the last hit
        keep = [i for i, tr in enumerate(tracks) if tr["confirmed"]]
        remap = np.full(len(tracks) + 1, -1, np.int64)
        remap[keep] = np.arange(len(keep))
        labels = remap[labels]
        new_cands = tuple(
            tuple(int(remap[o]) for o in c if remap[o] >= 0) if c else () for c in candidates
        )
        first, last, states = [], [], []
        for i in keep:
            tr = tracks[i]
            own = np.flatnonzero(labels == remap[i])
            shared = [j for j, c in enumerate(new_cands) if remap[i] in c]
            last_det = int(max(scan_of[np.r_[own, shared].astype(int)])) if own.size else tr["last"]
            last_scan = min(tr["last"], last_det)
            first.append(tr["first"])
            last.append(last_scan)
            states.append(np.array(tr["states"][: last_scan - tr["first"] + 1]))
        new_cands = tuple(c if len(c) >= 2 else () for c in new_cands)
        # a detection left with a single candidate belongs to it
        for j, c in enumerate(candidates):
            if c and len(new_cands[j]) == 0:
                owners = [int(remap[o]) for o in c if remap[o] >= 0]
                if len(owners) == 1:
                    labels[j] = owners[0]
        return TrackerResult(labels, new_cands, np.array(first, np.int64),
                             np.array(last, np.int64), tuple(states), scan_times)


class MultiTrackSmoother:
    """Joint smoothing of tracks from unlabeled per-scan bearing detections.

    Parameters
    ----------
    sigma_bearing : float, keyword-only
        Bearing measurement standard deviation, rad.
    q : float, keyword-only
        Bearing acceleration PSD, rad^2/s^3.
    clutter_density : float, keyword-only
        Expected false detections per scan per radian (the clutter component of the
        responsibilities).
    p_detect : float, keyword-only
        Probability that a track is detected in a scan.
    gate, n_confirm, max_misses, init_sigma_rate, window_scans :
        Options of the initial :class:`NearestNeighbourTracker` (global nearest neighbour);
        `window_scans` is also ``J`` of the crossing test, eq. (3)-(4).
    separation : float, keyword-only
        Two tracks closer than this in bearing, with a predicted or detected crossing, are
        ambiguous, rad (default ``2.5 * sqrt(2) * sigma_bearing``).
    link_gate : float, keyword-only
        Gate on the squared Mahalanobis distance (2 degrees of freedom) of a segment link
        (default 30; the 99.9 % point of chi-square is 13.8, but the constant-rate model
        underrates the curvature of bearing tracks near closest approach).
    max_gap_scans : int, keyword-only
        Longest gap, in scan periods, that a segment link may bridge (default 40).
    fit_scans : int, keyword-only
        Scans at each end of a segment used for its end states (default 30).
    margin_scans : int, keyword-only
        Scans of context on each side of a crossing cluster in its EM graphs.
    em_tol : float, keyword-only
        EM stops when no responsibility changes by more than this.
    em_max_iterations : int, keyword-only
        EM iteration cap per cluster.
    robust : {"none", "huber", "cauchy"}, keyword-only
        Loss on the hard (single-owner) bearing factors of the final smoothing.
    min_length : int, keyword-only
        Tracks with fewer detections are dropped (default 5).

    Notes
    -----
    1. Initial tracks: :class:`NearestNeighbourTracker` (global nearest neighbour, Kalman).
    2. Segments: wherever two tracks come closer than `separation` and eq. (2) of "Target Track
       Crossing Prediction/Detection" puts their crossing within ``J`` scans (eq. (3)
       prediction or eq. (4) detection), both tracks are cut and the detections of those
       scans (one scan of margin) are released: their origin is uncertain. What is left are
       segments that follow one target each.
    3. Segment relabelling: each segment is smoothed on its bearing-rate graph (its first and
       last `fit_scans` scans, weak prior) and gives ``gtsam.Marginals`` of its first and last
       state. A segment ending at ``t_e`` and one starting at ``t_s > t_e`` are linked with
       cost ``d^2 + ln det S``, ``d^2`` the squared Mahalanobis distance between the end state
       propagated by the constant-rate model and the start state, ``S`` its covariance
       (propagated end covariance + ``Q(t_s - t_e)`` + start covariance); links with ``d^2``
       above `link_gate` are not allowed. One assignment (``linear_sum_assignment``) over all
       ends and starts, preferring more links, chains the segments into tracks: the identity
       after a crossing is the one whose bearing and rate continue those before it.
    4. The released detections in a track's gaps, gated against the track's interpolation
       across the gap, enter every candidate track through association-weighted factors
       (:func:`factors.weighted.weighted_factor`). Per crossing cluster, EM: every track of the
       cluster gets a small graph over the cluster span plus `margin_scans` of context, with its
       own detections as hard factors and each shared detection ``j`` weighted by ``w_jm``.
       Start ``w_jm = 1/M``; M-step: weighted least squares per track; E-step:
       ``w_jm = P_D N(wrap(z_j - theta_m(t_j)); 0, sigma^2) / (lambda + sum_m' P_D N(...))``
       with ``lambda`` the clutter density; repeat until the weights settle.
    5. Final smoothing of every whole track with the settled weights; marginals from
       ``gtsam.Marginals``.

    Responsibilities use the measurement variance alone (as in probabilistic multi-hypothesis
    tracking), not the state covariance, which would need a ``Marginals`` per iteration.
    """

    def __init__(
        self,
        *,
        sigma_bearing: float,
        q: float,
        clutter_density: float = 0.1,
        p_detect: float = 0.9,
        gate: float = 4.0,
        n_confirm: int = 3,
        max_misses: int = 5,
        init_sigma_rate: float = 0.01,
        window_scans: int = 20,
        separation: float | None = None,
        link_gate: float = 30.0,
        max_gap_scans: int = 40,
        fit_scans: int = 30,
        margin_scans: int = 10,
        em_tol: float = 1e-3,
        em_max_iterations: int = 30,
        robust: str = "none",
        robust_k: float = 1.345,
        min_length: int = 5,
    ) -> None:
        self.model = _Model(
            sigma_bearing=check_positive("sigma_bearing", sigma_bearing),
            q=check_positive("q", q),
            loss=_check_loss(robust),
            k=check_positive("robust_k", robust_k),
            max_iterations=50,
        )
        self.clutter_density = check_positive("clutter_density", clutter_density)
        if not 0 < p_detect <= 1:
            raise ValueError(f"p_detect must be in (0, 1], got {p_detect!r}")
        self.p_detect = float(p_detect)
        self.tracker = NearestNeighbourTracker(
            sigma_bearing=sigma_bearing, q=q, gate=gate, init_sigma_rate=init_sigma_rate,
            n_confirm=n_confirm, max_misses=max_misses, window_scans=window_scans,
        )
        sep = 2.5 * np.sqrt(2.0) * sigma_bearing if separation is None else separation
        self.separation = check_positive("separation", sep)
        self.link_gate = check_positive("link_gate", link_gate)
        if max_gap_scans < 1 or fit_scans < 2 or margin_scans < 0:
            raise ValueError("max_gap_scans must be >= 1, fit_scans >= 2, margin_scans >= 0")
        self.max_gap_scans = int(max_gap_scans)
        self.fit_scans = int(fit_scans)
        self.margin_scans = int(margin_scans)
        self.em_tol = check_positive("em_tol", em_tol)
        self.em_max_iterations = int(em_max_iterations)
        self.min_length = int(min_length)

    def _likelihood(self, z: FloatArray, theta: FloatArray) -> FloatArray:
        s = self.model.sigma_bearing
        nu = wrap_angle(z - theta)
        return self.p_detect * np.exp(-0.5 * (nu / s) ** 2) / (np.sqrt(2 * np.pi) * s)

    def run(self, times: ArrayLike, bearings: ArrayLike) -> MultiTrackResult:
        """Form, associate and smooth tracks.

        Parameters
        ----------
        times : array_like, shape (n,)
            Detection times, s, non-decreasing; equal times form a scan.
        bearings : array_like, shape (n,)
            Bearings, rad.

        Returns
        -------
        MultiTrackResult
        """
        t, z = _check_detections(times, bearings)
        tr = self.tracker.run(t, z)
        scan_times = tr.scan_times
        scan_of = np.searchsorted(scan_times, t)
        segments = self._segments(tr, z, scan_of)
        ends = [self._segment_ends(seg, z, scan_of, scan_times) for seg in segments]
        chains = self._link(ends, scan_times)
        # hard labels per track, drop short tracks
        labels = np.full(t.size, -1, np.int64)
        kept: list[list[int]] = []
        for ch in chains:
            if sum(segments[p].size for p in ch) >= self.min_length:
                for p in ch:
                    labels[segments[p]] = len(kept)
                kept.append(ch)
        n_tracks = len(kept)
        first = np.array([scan_of[segments[ch[0]][0]] for ch in kept], np.int64)
        last = np.array([scan_of[segments[ch[-1]][-1]] for ch in kept], np.int64)
        # candidates in the gaps of every track
        cand: list[list[int]] = [[] for _ in range(t.size)]
        for m, ch in enumerate(kept):
            for p, p_next in zip(ch[:-1], ch[1:], strict=True):
                for j in self._gap_candidates(ends[p], ends[p_next], scan_times, z, scan_of,
                                               labels):
                    cand[j].append(m)
        pair_det_l, pair_track_l = [], []
        for j, c in enumerate(cand):
            for m in c:
                pair_det_l.append(j)
                pair_track_l.append(m)
        pair_det = np.array(pair_det_l, np.int64)
        pair_track = np.array(pair_track_l, np.int64)
        shared_idx = np.unique(pair_det)
        weights = np.zeros(pair_det.size)
        for j in shared_idx:
            sel = pair_det == j
            weights[sel] = 1.0 / sel.sum()
        est = []
        for m in range(n_tracks):
            times_m = scan_times[first[m]: last[m] + 1]
            meas = self._track_meas(m, first[m], last[m], z, scan_of, labels, pair_det[:0],
                                    pair_track[:0])
            est.append(_initial_states(times_m, meas, None))
        cands = tuple(tuple(c) for c in cand)
        clusters = self._clusters(shared_idx, cands, scan_of)
        max_iter = 0
        for cl in clusters:
            max_iter = max(max_iter, self._em_cluster(
                cl, t, z, scan_times, scan_of, labels, first, last, est, weights,
                pair_det, pair_track))
        tracks = []
        for m in range(n_tracks):
            times_m = scan_times[first[m]: last[m] + 1]
            meas = self._track_meas(m, first[m], last[m], z, scan_of, labels, pair_det,
                                    pair_track)
            prior = self._prior(m, est)
            states, sig = _solve(times_m, meas, prior, self.model, init=est[m], weights=weights,
                                 marginals=True)
            tracks.append(SmoothedTrack(m, times_m, np.asarray(wrap_angle(states[:, 0])),
                                        states[:, 1].copy(), sig[:, 0], sig[:, 1]))
        # final labels: most probable owner of each shared detection, clutter if below 0.5
        out_labels = labels.copy()
        for j in shared_idx:
            sel = np.flatnonzero(pair_det == j)
            best = sel[np.argmax(weights[sel])]
            out_labels[j] = pair_track[best] if weights[best] >= 0.5 else -1
        shared = np.zeros(t.size, bool)
        shared[shared_idx] = True
        logger.info("%d segments linked into %d tracks; %d shared detections in %d crossing "
                    "clusters", len(segments), n_tracks, shared_idx.size, len(clusters))
        return MultiTrackResult(tuple(tracks), out_labels, shared, max_iter)

    # -- segments ---------------------------------------------------------------------------

    def _segments(self, tr: TrackerResult, z: FloatArray,
                  scan_of: NDArray[np.int64]) -> list[NDArray[np.int64]]:
        """Cut the tracker's tracks where two of them are ambiguous; detections per segment."""
        n_scans = tr.scan_times.size
        period = float(np.median(np.diff(tr.scan_times))) if n_scans > 1 else 1.0
        ambiguous = np.zeros((tr.n_tracks, n_scans), bool)
        for a in range(tr.n_tracks):
            for b in range(a + 1, tr.n_tracks):
                lo = max(tr.first_scan[a], tr.first_scan[b])
                hi = min(tr.last_scan[a], tr.last_scan[b])
                if hi < lo:
                    continue
                xa = tr.states[a][lo - tr.first_scan[a]: hi - tr.first_scan[a] + 1]
                xb = tr.states[b][lo - tr.first_scan[b]: hi - tr.first_scan[b] + 1]
                sep = np.abs(wrap_angle(xa[:, 0] - xb[:, 0]))
                tc = np.asarray(crossing_time(xa[:, 0], xa[:, 1], xb[:, 0], xb[:, 1]))
                # eq. (3) predicted or eq. (4) detected crossing, and close in bearing
                amb = (sep < self.separation) & (np.abs(tc) <= self._window_s(period))
                if amb.any():
                    k = np.flatnonzero(amb) + lo
                    for d in (-1, 0, 1):  # one scan of margin
                        kk = np.clip(k + d, 0, n_scans - 1)
                        ambiguous[a, kk] = True
                        ambiguous[b, kk] = True
        segments: list[NDArray[np.int64]] = []
        for m in range(tr.n_tracks):
            own = np.flatnonzero(tr.labels == m)
            own = own[np.argsort(scan_of[own], kind="stable")]
            keep = own[~ambiguous[m, scan_of[own]]]
            if keep.size == 0:
                continue
            amb_scans = np.flatnonzero(ambiguous[m])
            # a new segment starts after every ambiguous scan between two kept detections
            cut = np.searchsorted(amb_scans, scan_of[keep])
            for c in np.unique(cut):
                seg = keep[cut == c]
                if seg.size >= self.tracker.n_confirm:
                    segments.append(seg)
        return segments

    def _window_s(self, period: float) -> float:
        """``J K`` of eq. (3)-(4), s."""
        return self.tracker.window_scans * period

    def _segment_ends(self, seg: NDArray[np.int64], z: FloatArray, scan_of: NDArray[np.int64],
                      scan_times: FloatArray) -> tuple:
        """First and last scan of a segment with their states and marginal covariances."""
        s0, s1 = int(scan_of[seg[0]]), int(scan_of[seg[-1]])
        out = []
        w = self.fit_scans
        spans = [(s0, s1)] if s1 - s0 < 2 * w else [(s0, s0 + w - 1), (s1 - w + 1, s1)]
        for a, b in spans:
            sel = seg[(scan_of[seg] >= a) & (scan_of[seg] <= b)]
            times_ab = scan_times[a: b + 1]
            meas = _Measurements(state=(scan_of[sel] - a).astype(np.int64), bearing=z[sel])
            x0 = _initial_states(times_ab, meas, None)
            prior = TrackPrior(bearing=float(x0[0, 0]), rate=float(x0[0, 1]),
                               sigma_bearing=10.0 * self.model.sigma_bearing,
                               sigma_rate=self.tracker.init_sigma_rate)
            states, covs = _solve_cov(times_ab, meas, prior, self.model, x0,
                                      (0, b - a))
            out.append((states, covs))
        (st_a, cov_a), (st_b, cov_b) = out[0], out[-1]
        return (s0, st_a[0], cov_a[0], s1, st_b[-1], cov_b[-1])

    def _link(self, ends: list[tuple], scan_times: FloatArray) -> list[list[int]]:
        """Chain segments by one assignment of segment ends to later segment starts."""
        n = len(ends)
        if n == 0:
            return []
        period = float(np.median(np.diff(scan_times))) if scan_times.size > 1 else 1.0
        big = 1e9
        cost = np.full((n, n), np.inf)
        for e in range(n):
            _, _, _, s1, x_e, p_e = ends[e]
            for s in range(n):
                s0, x_s, p_s = ends[s][0], ends[s][1], ends[s][2]
                dt = float(scan_times[s0] - scan_times[s1]) if s0 > s1 else -1.0
                if s == e or dt <= 0 or dt > self.max_gap_scans * period:
                    continue
                f = transition_matrix(dt, 1)
                cov = f @ p_e @ f.T + wna_covariance(dt, self.model.q, 1) + p_s
                nu = x_s - f @ x_e
                nu[0] = wrap_angle(nu[0])
                d2 = float(nu @ np.linalg.solve(cov, nu))
                if d2 <= self.link_gate:
                    cost[e, s] = d2 + float(np.log(np.linalg.det(cov)))
        finite = np.isfinite(cost)
        if not finite.any():
            return [[p] for p in range(n)]
        # admissible links cost less than any pair of non-links: the most links, then the
        # cheapest
        shift = cost[finite].min()
        c = np.where(finite, cost - shift, big)
        rr, cc = linear_sum_assignment(c)
        nxt = {int(r): int(s) for r, s in zip(rr, cc, strict=True) if finite[r, s]}
        has_prev = set(nxt.values())
        chains = []
        for p in range(n):
            if p in has_prev:
                continue
            ch = [p]
            while ch[-1] in nxt:
                ch.append(nxt[ch[-1]])
            chains.append(ch)
        return chains

    def _gap_candidates(self, end: tuple, start: tuple, scan_times: FloatArray, z: FloatArray,
                        scan_of: NDArray[np.int64], labels: NDArray[np.int64]) -> list[int]:
        """Unassigned detections in the gap between two linked segments, gated against the
        track's interpolation across the gap (forward and backward predictions fused)."""
        s1, x_e, p_e = end[3], end[4], end[5]
        s0, x_s, p_s = start[0], start[1], start[2]
        sel = np.flatnonzero((scan_of > s1) & (scan_of < s0) & (labels < 0))
        out = []
        for j in sel:
            dt_f = float(scan_times[scan_of[j]] - scan_times[s1])
            dt_b = float(scan_times[s0] - scan_times[scan_of[j]])
            f_f, f_b = transition_matrix(dt_f, 1), transition_matrix(dt_b, 1)
            # forward prediction from the end, backward prediction from the start
            m_f = f_f @ x_e
            v_f = (f_f @ p_e @ f_f.T + wna_covariance(dt_f, self.model.q, 1))[0, 0]
            m_b = np.linalg.solve(f_b, x_s)
            fi = np.linalg.inv(f_b)
            v_b = (fi @ (p_s + wna_covariance(dt_b, self.model.q, 1)) @ fi.T)[0, 0]
            theta = m_f[0] + wrap_angle(m_b[0] - m_f[0]) * v_f / (v_f + v_b)
            var = v_f * v_b / (v_f + v_b) + self.model.sigma_bearing**2
            if abs(wrap_angle(z[j] - theta)) < self.tracker.gate * np.sqrt(var):
                out.append(int(j))
        return out

    def _prior(self, m: int, est: list[FloatArray]) -> TrackPrior:
        x0 = est[m][0]
        return TrackPrior(bearing=float(x0[0]), rate=float(x0[1]),
                          sigma_bearing=10.0 * self.model.sigma_bearing,
                          sigma_rate=self.tracker.init_sigma_rate)

    def _clusters(self, shared_idx: NDArray[np.int64], cands: tuple[tuple[int, ...], ...],
                  scan_of: NDArray[np.int64]) -> list[NDArray[np.int64]]:
        """Group shared detections: same candidate track and < margin scans apart."""
        if shared_idx.size == 0:
            return []
        parent = np.arange(shared_idx.size)

        def find(a: int) -> int:
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a

        last_seen: dict[int, int] = {}
        for pos, j in enumerate(shared_idx):
            for m in cands[j]:
                if m in last_seen and scan_of[j] - scan_of[shared_idx[last_seen[m]]] <= (
                    self.margin_scans
                ):
                    parent[find(pos)] = find(last_seen[m])
                last_seen[m] = pos
        roots = np.array([find(p) for p in range(shared_idx.size)])
        return [shared_idx[roots == r] for r in np.unique(roots)]

    def _track_meas(self, m: int, s0: int, s1: int, z: FloatArray, scan_of: NDArray[np.int64],
                    labels: NDArray[np.int64], pair_det: NDArray[np.int64],
                    pair_track: NDArray[np.int64]) -> _Measurements:
        """Track m's bearings on scans s0..s1: own (hard) and shared (weighted)."""
        own = np.flatnonzero((labels == m) & (scan_of >= s0) & (scan_of <= s1))
        pw = np.flatnonzero((pair_track == m) & (scan_of[pair_det] >= s0)
                            & (scan_of[pair_det] <= s1))
        dets = np.r_[own, pair_det[pw]]
        return _Measurements(
            state=(scan_of[dets] - s0).astype(np.int64),
            bearing=z[dets],
            weight_index=np.r_[np.full(own.size, -1, np.int64), pw].astype(np.int64),
        )

    def _em_cluster(self, cl, t, z, scan_times, scan_of, labels, first, last, est, weights,
                    pair_det, pair_track) -> int:
        """EM over one crossing cluster; updates `weights` and `est` in place."""
        sel = np.flatnonzero(np.isin(pair_det, cl))
        members = np.unique(pair_track[sel])
        lo = int(scan_of[cl].min()) - self.margin_scans
        hi = int(scan_of[cl].max()) + self.margin_scans
        spans = {m: (max(lo, int(first[m])), min(hi, int(last[m]))) for m in members}
        metas = {m: self._track_meas(m, *spans[m], z, scan_of, labels, pair_det, pair_track)
                 for m in members}
        it = 0
        for it in range(1, self.em_max_iterations + 1):  # noqa: B007
            theta = np.zeros(sel.size)
            for m in members:  # M-step: weighted least squares per track
                s0, s1 = spans[m]
                times_m = scan_times[s0: s1 + 1]
                init = est[m][s0 - first[m]: s1 - first[m] + 1]
                prior = TrackPrior(bearing=float(init[0, 0]), rate=float(init[0, 1]),
                                   sigma_bearing=10.0 * self.model.sigma_bearing,
                                   sigma_rate=self.tracker.init_sigma_rate)
                states, _ = _solve(times_m, metas[m], prior, self.model, init=init,
                                   weights=weights)
                est[m][s0 - first[m]: s1 - first[m] + 1] = states
                on_m = pair_track[sel] == m
                dets = pair_det[sel][on_m]
                theta[on_m] = states[scan_of[dets] - s0, 0]
            # E-step: responsibilities against the tracks' predicted bearings + clutter
            lik = self._likelihood(z[pair_det[sel]], theta)
            denom = np.full(t.size, self.clutter_density)
            np.add.at(denom, pair_det[sel], lik)
            new = lik / denom[pair_det[sel]]
            change = float(np.max(np.abs(new - weights[sel]))) if sel.size else 0.0
            weights[sel] = new
            if change < self.em_tol:
                break
        return it


CROSSING_OUTCOMES = ("kept", "swap", "lost", "unscored")


def crossing_outcomes(
    true_labels: ArrayLike,
    est_labels: ArrayLike,
    times: ArrayLike,
    crossings: Sequence[tuple[int, int, float]],
    *,
    guard_s: float,
    window_s: float,
    min_fraction: float = 0.5,
) -> NDArray[np.str_]:
    """What became of the two tracks' identities at each true crossing.

    Parameters
    ----------
    true_labels, est_labels : array_like of int, shape (n,)
        True track of each detection (-1 clutter) and the estimated owner (-1 none).
    times : array_like, shape (n,)
        Detection times, s.
    crossings : sequence of (int, int, float)
        True crossings ``(track_a, track_b, t_cross)``.
    guard_s : float
        Half-width of the ambiguous interval around ``t_cross`` that is not scored, s.
    window_s : float
        Length of the scored windows ``[t_c - guard - window, t_c - guard)`` (before) and
        ``(t_c + guard, t_c + guard + window]`` (after), s.
    min_fraction : float, optional
        Share of a true track's detections in a window that one estimated track must own to
        follow it there (default 0.5).

    Returns
    -------
    ndarray of str, shape (n_crossings,)
        Per crossing, with ``f(x, W)`` the estimated track that follows true track ``x`` in
        window ``W`` (the most frequent estimated label of x's detections there, if it owns at
        least `min_fraction` of them):

        - ``"unscored"``: a or b has no detection in one of the windows;
        - ``"lost"``: a or b is followed by no track before or after, or by the same track as
          the other one, or after the crossing by a track that followed neither before
          (fragmented or restarted);
        - ``"swap"``: after the crossing a is followed by b's track from before, or b by a's;
        - ``"kept"``: both followed by their own tracks before and after.

    Examples
    --------
    >>> t = np.repeat(np.arange(10.0), 2)
    >>> true = np.tile([0, 1], 10)
    >>> crossing_outcomes(true, true, t, [(0, 1, 5.0)], guard_s=0.5, window_s=4).tolist()
    ['kept']
    """
    tl = np.asarray(true_labels)
    el = np.asarray(est_labels)
    t = np.asarray(times, float)
    if not (tl.shape == el.shape == t.shape and tl.ndim == 1):
        raise ValueError("true_labels, est_labels and times must be 1-D of equal length")

    def follower(trk: int, sel_t: NDArray[np.bool_]) -> int | None:
        sel = (tl == trk) & sel_t
        n = int(sel.sum())
        if n == 0:
            return None
        lab = el[sel]
        lab = lab[lab >= 0]
        if lab.size == 0:
            return -1
        u, c = np.unique(lab, return_counts=True)
        i = int(np.argmax(c))
        return int(u[i]) if c[i] >= min_fraction * n else -1

    out = []
    for a, b, tc in crossings:
        before = (t >= tc - guard_s - window_s) & (t < tc - guard_s)
        after = (t > tc + guard_s) & (t <= tc + guard_s + window_s)
        fb = [follower(x, before) for x in (a, b)]
        fa = [follower(x, after) for x in (a, b)]
        if None in fb or None in fa:
            out.append("unscored")
        elif -1 in fb or -1 in fa or fb[0] == fb[1] or fa[0] == fa[1]:
            out.append("lost")
        elif fa[0] == fb[1] or fa[1] == fb[0]:
            out.append("swap")
        elif fa != fb:
            out.append("lost")
        else:
            out.append("kept")
    return np.array(out, dtype="<U8")


def identity_swaps(
    true_labels: ArrayLike,
    est_labels: ArrayLike,
    times: ArrayLike,
    crossings: Sequence[tuple[int, int, float]],
    *,
    guard_s: float,
    window_s: float,
) -> NDArray[np.bool_]:
    """Which true crossings exchanged the two tracks' identities.

    ``crossing_outcomes(...) == "swap"``; lost or fragmented tracks are not swaps (see
    :func:`crossing_outcomes`).

    Returns
    -------
    ndarray of bool, shape (n_crossings,)
    """
    return crossing_outcomes(true_labels, est_labels, times, crossings, guard_s=guard_s,
                             window_s=window_s) == "swap"


def smooth_bearings(
    track_id: ArrayLike,
    times: ArrayLike,
    bearings: ArrayLike,
    *,
    single: BearingSmoother,
    multi: MultiTrackSmoother,
) -> tuple[SmoothedTrack, ...]:
    """Smooth a bearing file's rows: labelled tracks alone, unknown-origin rows jointly.

    Parameters
    ----------
    track_id : array_like of int, shape (n,)
        Track of each row; ``-1`` marks a detection of unknown origin.
    times : array_like, shape (n,)
        Times, s (any order).
    bearings : array_like, shape (n,)
        Bearings, rad.
    single : BearingSmoother
        Smoother of each labelled track (``track_id >= 0``).
    multi : MultiTrackSmoother
        Tracker-smoother of the unknown-origin rows; its tracks are numbered after the
        largest labelled id.

    Returns
    -------
    tuple of SmoothedTrack
        Labelled tracks first (by id), then the tracks formed from unknown-origin rows.
    """
    ids = np.asarray(track_id)
    t = np.asarray(times, float)
    z = np.asarray(bearings, float)
    if not (ids.shape == t.shape == z.shape and ids.ndim == 1):
        raise ValueError("track_id, times and bearings must be 1-D of equal length")
    out: list[SmoothedTrack] = []
    for tid in np.unique(ids[ids >= 0]):
        sel = np.flatnonzero(ids == tid)
        sel = sel[np.argsort(t[sel], kind="stable")]
        out.append(single.smooth(t[sel], z[sel], track_id=int(tid)))
    unk = np.flatnonzero(ids < 0)
    if unk.size:
        unk = unk[np.argsort(t[unk], kind="stable")]
        offset = int(ids.max()) + 1 if (ids >= 0).any() else 0
        res = multi.run(t[unk], z[unk])
        for tr in res.tracks:
            out.append(SmoothedTrack(tr.track_id + offset, tr.times, tr.bearing, tr.rate,
                                     tr.sigma_bearing, tr.sigma_rate))
    return tuple(out)
