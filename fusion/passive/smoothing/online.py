"""Online smoothing: one bearing-rate graph grown one scan at a time.

:class:`OnlineBearingSmoother` is the one incremental bearing tracker,
:class:`~fusion.passive.smoothing.fixed_lag.FixedLagBearingTrack`, with an infinite lag (every
state stays in the graph), several bearings per scan, misses, wrapped output and bearings checked
to be radians.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import check_radians, wrap_angle
from fusion.passive.smoothing.fixed_lag import FixedLagBearingTrack
from fusion.passive.smoothing.graph import _Model
from fusion.passive.smoothing.types import SmoothedTrack, TrackPrior

__all__ = ["OnlineBearingSmoother"]

FloatArray = NDArray[np.float64]


class OnlineBearingSmoother:
    """The bearing-rate graph of one track grown scan by scan with iSAM2.

    Parameters
    ----------
    prior : TrackPrior, keyword-only
        Prior on the state at `t0`.
    t0 : float, keyword-only
        Time of the first state, s.
    sigma_bearing, q, robust, robust_k :
        As in :class:`BearingSmoother`.
    relinearize_threshold : float, keyword-only
        iSAM2 relinearization threshold (tangent-space step), default 1e-3; used with a robust
        loss only.

    Notes
    -----
    The graph is that of :class:`BearingSmoother`, held by a
    :class:`~fusion.passive.smoothing.fixed_lag.FixedLagBearingTrack` that never marginalises:
    built-in linear factors, a new state entering at its constant-rate prediction and its
    bearings on the branch nearest that prediction. Without a robust loss every factor is
    linear, so relinearization cannot change the estimate and is switched off; with one, iSAM2
    relinearizes (the robust weights depend on the estimate).

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
        self.model = _Model.checked(sigma_bearing=sigma_bearing, q=q, robust=robust,
                                    robust_k=robust_k, max_iterations=1)
        if not isinstance(prior, TrackPrior):
            raise ValueError("prior must be a TrackPrior")
        if not np.isfinite(t0):
            raise ValueError("t0 must be finite")
        self._track = FixedLagBearingTrack(
            prior=prior, t0=float(t0), lag_s=math.inf, q=self.model.q, robust=self.model.loss,
            robust_k=self.model.k, relinearize_threshold=relinearize_threshold)

    @property
    def n_states(self) -> int:
        """Number of states so far."""
        return self._track.n_states

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
        time = float(time)
        last = self._track.last_time
        if not np.isfinite(time) or time < last:
            raise ValueError(f"scan time {time!r} is before the previous scan {last}")
        z = np.asarray(bearings, dtype=float).ravel()
        if not np.all(np.isfinite(z)):
            raise ValueError("bearings must be finite")
        check_radians(z)
        sigma = self.model.sigma_bearing
        if time > last:
            first = float(z[0]) if z.size else None
            self._track.update(time, bearing=first, sigma=sigma if z.size else None)
            z = z[1:]
        if z.size:
            self._track.add_bearings(np.full(z.size, time), z, np.full(z.size, sigma))
        x, _ = self._track.estimate
        return np.array([wrap_angle(x[0]), x[1]])

    def covariance(self) -> FloatArray:
        """Marginal covariance of the latest state, shape (2, 2)."""
        return self._track.estimate[1]

    def result(self, *, track_id: int = 0) -> SmoothedTrack:
        """All states smoothed by the current iSAM2 estimate, with marginal sigmas."""
        s = self._track.states()
        return SmoothedTrack(int(track_id), s.time, np.asarray(wrap_angle(s.state[:, 0])),
                             s.state[:, 1].copy(), s.sigma[:, 0], s.sigma[:, 1])
