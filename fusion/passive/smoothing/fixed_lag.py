"""One bearing track grown state by state on a GTSAM incremental fixed-lag smoother.

:class:`FixedLagBearingTrack` holds one track's states ``x_k = (bearing, bearing rate)`` on a
GTSAM ``IncrementalFixedLagSmoother`` built only from GTSAM's built-in factors: the constant-rate
motion model and the bearing measurements are exact linear relations
(:func:`factors.motion.linear_constant_velocity_factor`,
:func:`factors.bearing.linear_bearing_factor`), so the graph is linearised in C++ and never
calls back into Python. It is the one incremental bearing tracker: the passive pipeline grows
one per track (a finite lag), and :class:`~fusion.passive.smoothing.online.OnlineBearingSmoother`
is one with an infinite lag (every state kept) and, optionally, a robust bearing loss.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import NDArray

from factors.bearing import linear_bearing_factor
from factors.motion import linear_constant_velocity_factor, transition_matrix, wna_covariance
from fusion._validation import check_positive
from fusion.passive.smoothing.graph import _check_loss, _robust_noise
from fusion.passive.smoothing.types import TrackPrior

__all__ = ["FixedLagBearingTrack", "TrackStates"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TrackStates:
    """A track's states as the fixed-lag smoother left them.

    Attributes
    ----------
    time : ndarray, shape (n,)
        State times, s, increasing.
    state : ndarray, shape (n, 2)
        ``(bearing (rad), rate (rad/s))``: each state as smoothed by the data up to ``lag_s``
        after it (the last ``lag_s`` of states: by all the data so far).
    sigma : ndarray, shape (n, 2)
        Marginal standard deviations of bearing (rad) and rate (rad/s).
    """

    time: FloatArray
    state: FloatArray
    sigma: FloatArray


class FixedLagBearingTrack:
    """One bearing track on a GTSAM incremental fixed-lag smoother with linear factors.

    Parameters
    ----------
    prior : TrackPrior
        Prior on the state at `t0`.
    t0 : float
        Time of the first state, s.
    lag_s : float
        Smoother lag, s: states older than ``lag_s`` before the latest are marginalised
        (``math.inf``: none is, every state stays in the graph).
    q : float
        Bearing-acceleration power spectral density of the constant-rate model, rad^2/s^3
        (:func:`factors.motion.wna_covariance`).
    wildfire_threshold : float
        iSAM2's wildfire threshold: changes of a state's update smaller than this (rad, rad/s)
        are not propagated further down the Bayes tree (0: exact, and every estimate walks the
        whole tree).
    block_s : float
        Timestamps given to the smoother are the state times rounded down to a multiple of
        `block_s` from `t0`, so states leave the lag a block at a time: each update that
        marginalises re-eliminates the whole chain (the smoother orders the departing states
        first), and blocks make that happen once per block instead of once per state. A state is
        therefore smoothed by between ``lag_s`` and ``lag_s + block_s`` of later data.
    robust : {"none", "huber", "cauchy"}
        Loss of the bearing factors (``"none"``: Gaussian, the linear model above). A robust
        loss makes the bearing weights depend on the estimate: iSAM2 then relinearises
        (`relinearize_threshold`) and the latest state is read from the whole estimate.
    robust_k : float
        Threshold of the robust loss, in bearing sigmas.
    relinearize_threshold : float
        iSAM2 relinearisation threshold (tangent-space step), used with a robust loss only.

    Notes
    -----
    Factors (design notes, "Bearing-rate graph"): a prior ``x_0 ~ N(m, P_0)``; between states
    ``dt`` apart the motion factor ``x_k - F(dt) x_(k-1) ~ N(0, s Q(dt))`` with ``s`` the
    process-noise scale of that update; a bearing ``z`` with standard deviation ``sigma`` gives
    ``[1, 0] x_k - z ~ N(0, sigma^2)``. The prior is a ``PriorFactorVector``, the motion factor
    a whitened ``JacobianFactor`` in a ``LinearContainerFactor``
    (:func:`factors.motion.linear_constant_velocity_factor`), the bearing a ``PriorFactorVector``
    whose noise weighs the bearing alone (:func:`factors.bearing.linear_bearing_factor`): all
    built in, all exact for this linear model at any linearisation point. Bearings are cone
    angles of a line array, ``[0, pi]``, so no residual comes near the wrap. The latest estimate of
    an incremental smoother of a linear-Gaussian chain is the Kalman filter's; each state's
    estimate when it leaves the lag is the fixed-lag smoothed one.
    """

    def __init__(
        self,
        *,
        prior: TrackPrior,
        t0: float,
        lag_s: float,
        q: float,
        wildfire_threshold: float = 1e-9,
        block_s: float = 10.0,
        robust: str = "none",
        robust_k: float = 1.345,
        relinearize_threshold: float = 1e-3,
    ) -> None:
        self.lag_s = math.inf if lag_s == math.inf else check_positive("lag_s", lag_s)
        self.block_s = check_positive("block_s", block_s)
        self.q = check_positive("q", q)
        self.robust = _check_loss(robust)
        self.robust_k = check_positive("robust_k", robust_k)
        if not math.isfinite(t0):
            raise ValueError(f"t0 must be finite, got {t0!r}")
        params = gtsam.ISAM2Params()
        params.setOptimizationParams(gtsam.ISAM2GaussNewtonParams(float(wildfire_threshold)))
        # Gaussian: linear factors, exact at any point; robust: the weights move with the estimate
        params.enableRelinearization = self.robust != "none"
        if params.enableRelinearization:
            params.setRelinearizeThreshold(float(relinearize_threshold))
            params.relinearizeSkip = 1
        params.setFactorization("QR")  # the motion information (~1/q) dwarfs the prior's
        self._smoother = gtsam.IncrementalFixedLagSmoother(self.lag_s, params)
        self._t0 = float(t0)
        self._times: list[float] = []
        self._stamps: list[float] = []
        self._final: dict[int, tuple[FloatArray, FloatArray]] = {}
        self._first_live = 0  # first key still in the smoother
        self._motion_cache: dict[tuple[float, float], gtsam.noiseModel.Base] = {}
        self._model_cache: dict[float, tuple[FloatArray, FloatArray]] = {}
        graph = gtsam.NonlinearFactorGraph()
        graph.add(gtsam.PriorFactorVector(
            0, prior.mean, gtsam.noiseModel.Gaussian.Covariance(prior.covariance, False)))
        self._push(graph, float(t0), prior.mean)
        self._x = prior.mean.copy()
        self._p = prior.covariance.copy()

    # -- factors ----------------------------------------------------------------------------
    def _model(self, dt: float) -> tuple[FloatArray, FloatArray]:
        """``F(dt)`` and ``Q(dt)`` of the constant-rate model (cached per step length)."""
        if dt not in self._model_cache:
            self._model_cache[dt] = (transition_matrix(dt, 1), wna_covariance(dt, self.q, 1))
        return self._model_cache[dt]

    def _motion_noise(self, dt: float, scale: float) -> gtsam.noiseModel.Base:
        """Gaussian noise ``scale Q(dt)`` of a motion factor (cached)."""
        key = (dt, scale)
        if key not in self._motion_cache:
            # smart=False: the default turns a covariance whose off-diagonal terms are below
            # 1e-9 (q dt^2 / 2 of a slow bearing track) into a diagonal model
            self._motion_cache[key] = gtsam.noiseModel.Gaussian.Covariance(
                scale * self._model(dt)[1], False)
        return self._motion_cache[key]

    def _bearing_factor(self, key: int, bearing: float, sigma: float,
                        estimate: FloatArray) -> gtsam.NonlinearFactor:
        noise = _robust_noise(gtsam.noiseModel.Isotropic.Sigma(1, sigma), self.robust,
                              self.robust_k)
        return linear_bearing_factor(noise, key, bearing, estimate=estimate)

    # -- bookkeeping ------------------------------------------------------------------------
    def _stamp(self, time: float) -> float:
        """Smoother timestamp of a state at `time`: rounded down to a block."""
        return self._t0 + math.floor((time - self._t0) / self.block_s + 1e-9) * self.block_s

    def _push(self, graph: gtsam.NonlinearFactorGraph, time: float, guess: FloatArray) -> None:
        """Add a state at `time` with `graph`, keeping the estimates of states about to leave."""
        key = len(self._times)
        stamp = self._stamp(time)
        cutoff = stamp - self.lag_s  # the smoother marginalises stamps below this now
        k = self._first_live
        while k < key and self._stamps[k] < cutoff:
            self._final[k] = self._read(k)  # the first read walks the tree, the rest reuse it
            k += 1
        values = gtsam.Values()
        self._guess = np.asarray(guess, dtype=float)  # the new state's linearisation point
        values.insert(key, self._guess)
        self._times.append(time)
        self._stamps.append(stamp)
        self._smoother.update(graph, values, {key: stamp})
        self._first_live = k

    def _read(self, key: int) -> tuple[FloatArray, FloatArray]:
        x = np.asarray(self._smoother.calculateEstimateVector(key), dtype=float)
        p = np.asarray(self._smoother.marginalCovariance(key))
        return x, np.sqrt(np.diag(p))

    # -- public API ---------------------------------------------------------------------------
    @property
    def n_states(self) -> int:
        """Number of states so far."""
        return len(self._times)

    @property
    def last_time(self) -> float:
        """Time of the latest state, s."""
        return self._times[-1]

    @property
    def estimate(self) -> tuple[FloatArray, FloatArray]:
        """Latest state ``(bearing, rate)`` and its marginal covariance, shape (2,), (2, 2)."""
        return self._x.copy(), self._p.copy()

    def predict(self, time: float, *, q_scale: float = 1.0) -> tuple[FloatArray, FloatArray]:
        """Prediction of the state at `time` from the latest one (nothing is added).

        Returns
        -------
        x : ndarray, shape (2,)
            ``F x``.
        P : ndarray, shape (2, 2)
            ``F P F' + q_scale Q``.
        """
        dt = float(time) - self._times[-1]
        if not dt > 0:
            raise ValueError(f"time {time!r} is not after the latest state ({self._times[-1]})")
        f, q = self._model(dt)
        return f @ self._x, f @ self._p @ f.T + q_scale * q

    def update(
        self,
        time: float,
        *,
        bearing: float | None = None,
        sigma: float | None = None,
        q_scale: float = 1.0,
    ) -> tuple[FloatArray, FloatArray]:
        """Add the state at `time`: motion factor, and a bearing factor if one is given.

        Parameters
        ----------
        time : float
            State time, s, after the latest state.
        bearing : float, optional
            Measured bearing, rad (None: the state is predicted only).
        sigma : float, optional
            Its standard deviation, rad (required with `bearing`).
        q_scale : float
            Process-noise scale of this step (> 0).

        Returns
        -------
        x, P : ndarray
            The new latest state and its marginal covariance.
        """
        time = float(time)
        dt = time - self._times[-1]
        if not dt > 0:
            raise ValueError(f"time {time!r} is not after the latest state ({self._times[-1]})")
        key = len(self._times)
        guess = self._model(dt)[0] @ self._x  # F x: the linearisation point of the new state
        graph = gtsam.NonlinearFactorGraph()
        graph.add(linear_constant_velocity_factor(
            self._motion_noise(dt, check_positive("q_scale", q_scale)), key - 1, key, dt,
            estimate_prev=self._x, estimate_next=guess))
        if bearing is not None:
            if sigma is None or not (math.isfinite(bearing) and sigma > 0):
                raise ValueError("a bearing needs a finite value and a positive sigma")
            graph.add(self._bearing_factor(key, float(bearing), float(sigma), guess))
        self._push(graph, time, guess)
        self._x, self._p = self._latest()
        return self._x.copy(), self._p.copy()

    def add_bearings(
        self, times: FloatArray, bearings: FloatArray, sigmas: FloatArray
    ) -> int:
        """Add bearings to states already in the smoother (e.g. after a crossing is resolved).

        Parameters
        ----------
        times : ndarray, shape (m,)
            Times of existing states, s (others, and states already marginalised, are skipped).
        bearings, sigmas : ndarray, shape (m,)
            Bearings and their standard deviations, rad.

        Returns
        -------
        int
            Number of bearings added.
        """
        index = {t: k for k, t in enumerate(self._times) if k >= self._first_live}
        graph = gtsam.NonlinearFactorGraph()
        n = 0
        for t, z, s in zip(np.asarray(times, float), np.asarray(bearings, float),
                           np.asarray(sigmas, float), strict=True):
            k = index.get(float(t))
            if k is None:
                continue
            estimate = np.asarray(self._smoother.calculateEstimateVector(k), dtype=float)
            graph.add(self._bearing_factor(k, float(z), float(s), estimate))
            n += 1
        if n:
            self._smoother.update(graph, gtsam.Values(), {})
            self._x, self._p = self._latest()
        return n

    def _latest(self) -> tuple[FloatArray, FloatArray]:
        """Latest state and covariance from its marginal on the Bayes tree's root.

        The root clique's conditional ``R d_k = d`` is the latest state's marginal in the tangent
        space of its linearisation point, which (relinearisation off) is the guess it was
        inserted with: ``x_k = guess + (R'R)^-1 R'd``. This reads one clique, where the estimate
        of the whole tree (``calculateEstimate``) back-substitutes through every state.
        """
        key = len(self._times) - 1
        if self.robust != "none":  # relinearised: the point is no longer the guess
            x = np.asarray(self._smoother.calculateEstimateVector(key), dtype=float)
            return x, np.asarray(self._smoother.marginalCovariance(key))
        ab = np.asarray(self._smoother.getISAM2().marginalFactor(key).augmentedInformation())
        cov = np.linalg.inv(ab[:2, :2])  # information R'R of the root marginal
        return self._guess + cov @ ab[:2, 2], cov

    def states(self) -> TrackStates:
        """Every state so far: fixed-lag smoothed, the last `lag_s` by all data so far."""
        n = len(self._times)
        x = np.empty((n, 2))
        s = np.empty((n, 2))
        for k in range(n):
            x[k], s[k] = self._final[k] if k < self._first_live else self._read(k)
        return TrackStates(time=np.array(self._times), state=x, sigma=s)
