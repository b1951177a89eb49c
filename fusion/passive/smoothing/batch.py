"""Batch smoothing of one bearing track, and its linear-Gaussian reference (filterpy RTS).

:class:`BearingSmoother` minimises the bearing-rate graph of one track at once (one sparse linear
solve for Gaussian noise, Levenberg-Marquardt for a robust loss), with covariances from
``gtsam.Marginals``; on linear-Gaussian data it equals the Rauch-Tung-Striebel smoother that
:func:`rts_reference` runs with filterpy.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.motion import transition_matrix, wna_covariance
from fusion._validation import check_positive
from fusion.geometry import wrap_angle
from fusion.passive.smoothing.graph import (
    _check_detections,
    _default_prior,
    _initial_states,
    _Measurements,
    _Model,
    _solve,
)
from fusion.passive.smoothing.types import SmoothedTrack, TrackPrior

__all__ = ["BearingSmoother", "rts_reference"]

FloatArray = NDArray[np.float64]


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
        self.model = _Model.checked(sigma_bearing=sigma_bearing, q=q, robust=robust,
                                    robust_k=robust_k, max_iterations=max_iterations)
        self.prior_sigma_rate = check_positive("prior_sigma_rate", prior_sigma_rate)

    def smooth(
        self,
        times: ArrayLike,
        bearings: ArrayLike,
        *,
        prior: TrackPrior | None = None,
        track_id: int = 0,
        on_rows: Callable[[int], None] | None = None,
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
        on_rows : callable, optional
            ``on_rows(n)`` as the solve goes on, with the rows it covered (``len(times)`` in
            all, in parts: a progress bar's ``update``).

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
        states, sig = _solve(state_times, meas, prior, self.model, marginals=True,
                             on_rows=on_rows)
        return SmoothedTrack(
            track_id=int(track_id),
            times=state_times,
            bearing=np.asarray(wrap_angle(states[:, 0])),
            rate=states[:, 1].copy(),
            sigma_bearing=sig[:, 0],
            sigma_rate=sig[:, 1],
        )


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
    from filterpy.kalman import KalmanFilter, rts_smoother  # the reference only (filterpy
    # imports scipy.stats, ~0.8 s CPU, which the smoothers never need)

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
