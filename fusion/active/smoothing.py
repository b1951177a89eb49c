"""Fixed-interval smoothing of confirmed active tracks on a GTSAM factor graph.

The tracker's fuzzy association decides which detection each track takes on each ping; this
module refines the track afterwards with every one of them. One small graph per track (tracks
are independent): ``Vector4`` states ``(x, y, vx, vy)`` (m, m/s), one per ping the track lived
through, tied by the tracker's constant-velocity model with white-noise acceleration
(:func:`factors.motion.constant_velocity_chain`, built-in linear factors); one position factor
per associated detection with that detection's own 2 x 2 covariance (the bistatic error ellipse
the tracker used, :mod:`fusion.active.bistatic`), ``H = [I 0]``; a prior ``N(0, s^2 I)`` on the
first velocity, the tracker's ``speed_sigma_mps``. The birth detection and the velocity prior
together are the filter's initial state ``N([z_0, 0, 0], diag(R_0, s^2 I))``, so on these
linear-Gaussian factors the graph's solution is the Rauch-Tung-Striebel smoother of the tracker's
own Kalman filter (the same model and the same detections; the tests check it against
``filterpy.kalman.rts_smoother``). The model is linear: one elimination gives the solution and
``gtsam.Marginals`` the covariance of every state.

See the "Factor graphs" notes of the project design (batch optimisation equal to an RTS
smoother on linear-Gaussian data).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.motion import constant_velocity_chain
from fusion.active.types import TrackingResult

__all__ = [
    "SmoothedTrack",
    "SmoothedTracking",
    "TrackSmoother",
    "position_factor",
    "smooth_tracks",
    "velocity_prior_factor",
]

logger = logging.getLogger(__name__)

_H_POSITION = np.hstack([np.eye(2), np.zeros((2, 2))])
_H_VELOCITY = np.hstack([np.zeros((2, 2)), np.eye(2)])


def _linear_factor(
    key: int, H: NDArray[np.float64], z: NDArray[np.float64], cov: NDArray[np.float64],
    estimate: NDArray[np.float64],
) -> gtsam.LinearContainerFactor:
    """Built-in linear factor ``|| H x - z ||^2_cov`` on one ``Vector4`` state."""
    try:
        L = np.linalg.cholesky(cov)  # cov = L L^T; whitening W = L^-1
    except np.linalg.LinAlgError:
        raise ValueError(f"covariance must be symmetric positive definite, got {cov.tolist()}") \
            from None
    W = np.linalg.inv(L)
    point = gtsam.Values()
    point.insert(key, estimate)
    # whitened error W (H x - z) = W H dx - b with dx = x - x_0, b = W (z - H x_0)
    jf = gtsam.JacobianFactor(key, W @ H, W @ (z - H @ estimate), gtsam.noiseModel.Unit.Create(2))
    return gtsam.LinearContainerFactor(jf, point)


def position_factor(
    key: int, z: ArrayLike, cov: ArrayLike, *, estimate: ArrayLike
) -> gtsam.LinearContainerFactor:
    """Position measurement of a ``(x, y, vx, vy)`` state as a built-in linear factor.

    Parameters
    ----------
    key : int
        Key of the ``Vector4`` state.
    z : array_like, shape (2,)
        Measured position, m.
    cov : array_like, shape (2, 2)
        Its covariance, m^2 (symmetric positive definite).
    estimate : array_like, shape (4,), keyword-only
        Linearisation point (the factor is linear: any point gives the same factor).

    Returns
    -------
    gtsam.LinearContainerFactor
        A ``JacobianFactor`` whose error is ``H x - z`` with ``H = [I 0]``, whitened by ``cov``.

    Examples
    --------
    >>> f = position_factor(0, [3.0, 4.0], np.eye(2), estimate=np.zeros(4))
    >>> v = gtsam.Values(); v.insert(0, np.array([3.0, 4.0, 1.0, 1.0]))
    >>> f.error(v) < 1e-20
    True
    """
    return _linear_factor(int(key), _H_POSITION, np.asarray(z, dtype=float).reshape(2),
                          np.asarray(cov, dtype=float).reshape(2, 2),
                          np.asarray(estimate, dtype=float).reshape(4))


def velocity_prior_factor(
    key: int, sigma_mps: float, *, estimate: ArrayLike
) -> gtsam.LinearContainerFactor:
    """Prior ``N(0, sigma^2 I)`` on the velocity of a ``(x, y, vx, vy)`` state (built-in, linear).

    Parameters
    ----------
    key : int
        Key of the ``Vector4`` state.
    sigma_mps : float
        Standard deviation of each velocity component, m/s (> 0).
    estimate : array_like, shape (4,), keyword-only
        Linearisation point.

    Returns
    -------
    gtsam.LinearContainerFactor
    """
    if not np.isfinite(sigma_mps) or sigma_mps <= 0:
        raise ValueError(f"speed_sigma_mps must be positive, got {sigma_mps!r}")
    return _linear_factor(int(key), _H_VELOCITY, np.zeros(2), np.eye(2) * float(sigma_mps) ** 2,
                          np.asarray(estimate, dtype=float).reshape(4))


@dataclass(frozen=True)
class SmoothedTrack:
    """States of one track smoothed with all of its detections.

    Attributes
    ----------
    time : ndarray, shape (n,)
        State times, s, strictly increasing.
    state : ndarray, shape (n, 4)
        ``x, y, vx, vy`` (m, m/s).
    covariance : ndarray, shape (n, 4, 4)
        Marginal covariance of each state (m^2, m^2/s, m^2/s^2).
    """

    time: NDArray[np.float64]
    state: NDArray[np.float64]
    covariance: NDArray[np.float64]


class TrackSmoother:
    """Fixed-interval smoother of one track: a GTSAM graph of motion and position factors.

    Parameters
    ----------
    accel_psd : float, optional
        White-acceleration spectral density of the motion model, m^2/s^3 (> 0; default 0.04, the
        tracker's).
    speed_sigma_mps : float, optional
        Standard deviation of each velocity component before any detection, m/s (> 0; default 3,
        the tracker's).

    Examples
    --------
    >>> sm = TrackSmoother().smooth([0.0, 60.0, 120.0], [[0, 0], [120, 0], [240, 0]],
    ...                             np.broadcast_to(np.eye(2) * 100.0, (3, 2, 2)))
    >>> sm.state[1].round(1).tolist()
    [119.5, 0.0, 2.0, 0.0]
    """

    def __init__(self, *, accel_psd: float = 0.04, speed_sigma_mps: float = 3.0) -> None:
        if not np.isfinite(accel_psd) or accel_psd <= 0:
            raise ValueError(f"accel_psd must be > 0 to smooth, got {accel_psd!r}")
        if not np.isfinite(speed_sigma_mps) or speed_sigma_mps <= 0:
            raise ValueError(f"speed_sigma_mps must be positive, got {speed_sigma_mps!r}")
        self.accel_psd = float(accel_psd)
        self.speed_sigma_mps = float(speed_sigma_mps)

    def smooth(
        self, times: ArrayLike, positions: ArrayLike, covariances: ArrayLike, *,
        initial: ArrayLike | None = None,
    ) -> SmoothedTrack:
        """Smooth one track.

        Parameters
        ----------
        times : array_like, shape (n,)
            Times of the track's pings, s, non-decreasing (rows of one time share one state).
        positions : array_like, shape (n, 2)
            Associated detection of each ping, m; NaN rows where the track had none. The first
            row must hold a detection (the track's birth).
        covariances : array_like, shape (n, 2, 2)
            Position covariance of each detection, m^2 (ignored on NaN rows).
        initial : array_like, shape (n, 4), optional
            Linearisation point, e.g. the filter's states (default: the detections, velocity
            0); the model is linear, so it does not change the result.

        Returns
        -------
        SmoothedTrack
            One state per distinct time.
        """
        t = np.asarray(times, dtype=float).reshape(-1)
        z = np.asarray(positions, dtype=float).reshape(-1, 2)
        R = np.asarray(covariances, dtype=float).reshape(-1, 2, 2)
        n = t.size
        if z.shape[0] != n or R.shape[0] != n or n == 0:
            raise ValueError(f"times, positions and covariances must have one row per ping, got "
                             f"{n}, {z.shape[0]}, {R.shape[0]}")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
            raise ValueError("times must be finite and non-decreasing")
        seen = np.all(np.isfinite(z), axis=1)
        if not seen[0]:
            raise ValueError("the first ping of a track must hold its (birth) detection")
        if not np.all(np.isfinite(R[seen])):
            raise ValueError("covariances of the detections must be finite")
        uniq, state_of = np.unique(t, return_inverse=True)
        if initial is None:
            x0 = np.zeros((uniq.size, 4))
            x0[:, :2] = np.nan
            x0[state_of[seen], :2] = z[seen]
            x0[:, :2] = _fill_forward(x0[:, :2])
        else:
            x_init = np.asarray(initial, dtype=float).reshape(n, 4)
            x0 = np.empty((uniq.size, 4))
            x0[state_of] = x_init
        keys = np.arange(uniq.size)
        graph = gtsam.NonlinearFactorGraph()
        chain = constant_velocity_chain(keys, uniq, self.accel_psd, estimates=x0, wrap=False)
        if isinstance(chain, gtsam.NonlinearFactorGraph):
            graph.push_back(chain)
        else:  # a list of factors (factors.motion before its chain became a graph)
            for f in chain:
                graph.add(f)
        graph.add(velocity_prior_factor(0, self.speed_sigma_mps, estimate=x0[0]))
        for i in np.flatnonzero(seen):
            k = int(state_of[i])
            graph.add(position_factor(k, z[i], R[i], estimate=x0[k]))
        values = gtsam.Values()
        for k in keys:
            values.insert(int(k), x0[k])
        linear = graph.linearize(values)
        delta = linear.optimize()  # the exact solution: the factors are linear
        marginals = gtsam.Marginals(linear, delta)
        state = np.array([x0[k] + delta.at(int(k)) for k in keys])
        cov = np.array([marginals.marginalCovariance(int(k)) for k in keys])
        return SmoothedTrack(time=uniq, state=state, covariance=0.5 * (cov + np.swapaxes(cov, 1, 2)))


def _fill_forward(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows with NaN take the last finite row before them (the first row is finite)."""
    ok = np.all(np.isfinite(a), axis=1)
    idx = np.maximum.accumulate(np.where(ok, np.arange(a.shape[0]), 0))
    return a[idx]


@dataclass(frozen=True)
class SmoothedTracking:
    """Tracker output with smoothed states and per-row uncertainty.

    Attributes
    ----------
    columns : dict of str to ndarray
        ``track_id,event,time,x,y,vx,vy,status`` (the tracker's rows, in its order) and
        ``sigma_x, sigma_y`` (m): states of smoothed tracks replaced by the smoothed ones, the
        sigmas from the smoothed marginal covariance there and from the filter's covariance on
        the other rows.
    smoothed : ndarray of bool, shape (n_rows,)
        Rows of smoothed tracks.
    """

    columns: dict[str, NDArray]
    smoothed: NDArray[np.bool_]


def smooth_tracks(
    result: TrackingResult, smoother: TrackSmoother, *, confirmed_only: bool = True
) -> SmoothedTracking:
    """Smooth every (confirmed) track of a tracker run on its own graph.

    Parameters
    ----------
    result : TrackingResult
        A run of :class:`fusion.active.tracker.Tracker`.
    smoother : TrackSmoother
        Configured like the tracker (its ``accel_psd`` and ``speed_sigma_mps``).
    confirmed_only : bool, optional
        Smooth only tracks confirmed at some ping (default); tentative tracks keep their
        filtered states.

    Returns
    -------
    SmoothedTracking
    """
    cols = dict(result.columns())
    n_rows = cols["track_id"].size
    if n_rows == 0:
        return SmoothedTracking({**cols, "sigma_x": np.zeros(0), "sigma_y": np.zeros(0)},
                                np.zeros(0, dtype=bool))
    P = np.concatenate([p.covariance for p in result.pings])
    z = np.concatenate([p.measurement for p in result.pings])
    Rz = np.concatenate([p.measurement_cov for p in result.pings])
    state = np.column_stack([cols["x"], cols["y"], cols["vx"], cols["vy"]])
    sigma = np.sqrt(np.stack([P[:, 0, 0], P[:, 1, 1]], axis=1))
    ids = result.confirmed_ids() if confirmed_only else np.unique(cols["track_id"])
    smoothed = np.isin(cols["track_id"], ids)
    for tid in ids.tolist():
        rows = np.flatnonzero(cols["track_id"] == tid)  # in ping order
        sm = smoother.smooth(cols["time"][rows], z[rows], Rz[rows], initial=state[rows])
        k = np.searchsorted(sm.time, cols["time"][rows])
        state[rows] = sm.state[k]
        sigma[rows] = np.sqrt(np.stack([sm.covariance[k, 0, 0], sm.covariance[k, 1, 1]], axis=1))
    logger.info("smoothed %d tracks (%d rows)", ids.size, int(smoothed.sum()))
    out = {**cols, "x": state[:, 0], "y": state[:, 1], "vx": state[:, 2], "vy": state[:, 3],
           "sigma_x": sigma[:, 0], "sigma_y": sigma[:, 1]}
    return SmoothedTracking(out, smoothed)
