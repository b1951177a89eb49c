"""Online smoothing: bearing-rate graphs grown one scan at a time with iSAM2.

:class:`OnlineBearingSmootherSet` grows many tracks in one ``gtsam.ISAM2`` (one update per scan);
:class:`OnlineBearingSmoother` is a set of one track.
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np
from numpy.typing import NDArray

from factors.bearing import linear_bearing_factors, state_bearing_noise
from factors.motion import constant_velocity_steps
from fusion._validation import check_positive
from fusion.geometry import check_radians, wrap_angle
from fusion.passive.smoothing.graph import _check_loss, _Model, _robust_noise
from fusion.passive.smoothing.types import SmoothedTrack, TrackPrior

__all__ = ["OnlineBearingSmoother", "OnlineBearingSmootherSet"]

FloatArray = NDArray[np.float64]


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
        check_radians(z)
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
