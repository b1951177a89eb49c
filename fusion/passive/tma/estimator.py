"""Bearings-only target motion analysis on a factor graph: :class:`BearingsOnlyTMA`.

See :mod:`fusion.passive.tma` for the formulation (``"single"`` and ``"chain"`` target models,
robust bearing factors, diffuse prior, covariances, initialisation and observability checks).
"""

from __future__ import annotations

import logging

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray
from threadpoolctl import ThreadpoolController

from factors.motion import constant_velocity_chain
from factors.target import target_bearing, target_bearing_batch_factor
from fusion._validation import check_positive
from fusion.geometry import wrap_angle
from fusion.passive.tma.confidence import noise_inflation, range_interval
from fusion.passive.tma.initial import _pseudo_linear, _range_candidates, _transitions
from fusion.passive.tma.observability import ownship_manoeuvre, range_rel_sigma
from fusion.passive.tma.types import OwnshipTrack, TmaResult, _finite_1d, _ranges

__all__ = ["BearingsOnlyTMA"]

logger = logging.getLogger(__name__)

_ROBUST = {
    "huber": gtsam.noiseModel.mEstimator.Huber,
    "cauchy": gtsam.noiseModel.mEstimator.Cauchy,
    "tukey": gtsam.noiseModel.mEstimator.Tukey,
}
#: Robust losses act on each bearing of a vector bearing factor alone.
_PER_BEARING = gtsam.noiseModel.mEstimator.Base.ReweightScheme.Scalar
#: States per vector bearing factor of the "chain" model (a factor couples its states).
_CHAIN_WINDOW = 8
#: Bearings used to score the initial candidates (evenly spread over the window).
_SCORE_BEARINGS = 200


_BLAS: list[ThreadpoolController] = []


def _one_blas_thread():
    """Context limiting BLAS/LAPACK to one thread (threaded LAPACK on small matrices is far
    slower on a busy machine); the controller is made once."""
    if not _BLAS:
        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1)


class BearingsOnlyTMA:
    """Bearings-only target motion analysis with GTSAM.

    Parameters
    ----------
    bearing_sigma_deg : float, keyword-only
        Bearing noise standard deviation, deg.
    motion : {"single", "chain"}, keyword-only
        ``"single"``: one constant-velocity state for the whole window (classical TMA).
        ``"chain"``: one state per bearing time linked by constant-velocity factors with
        acceleration spectral density `q` (allows slow manoeuvres). Without an own-ship
        manoeuvre the chain falls back to ``"single"`` (its optimum collapses onto the
        own-ship).
    q : float, keyword-only
        Acceleration power spectral density of the target, m^2/s^3 (``"chain"`` only). The
        default lets the velocity wander by ``sqrt(q T)`` ~ 0.04 m/s over ``T`` = 30 min.
    robust : {None, "huber", "cauchy", "tukey"}, keyword-only
        Robust loss on the bearing factors.
    robust_k : float, keyword-only
        Robust loss threshold, in bearing standard deviations.
    initial_ranges_m : array_like or None, keyword-only
        Ranges of the initial guesses along the first bearing, m; ``None`` uses 9 ranges
        geometrically spaced from 200 m to 50 km.
    min_range_m : float, keyword-only
        Initial fits that bring the target closer than this to the own-ship at any bearing time
        are discarded, m (the zero-range solution fits any bearings when range is unobservable).
    min_manoeuvre_m : float, keyword-only
        Own-ship departure from a straight constant-speed track below which it counts as not
        manoeuvring, m.
    max_range_rel_sigma : float, keyword-only
        Relative range standard deviation (of the noise-fitted covariance) above which range
        counts as unobservable (default 0.15: an estimate 50 % off is then more than 2.7 sigma
        from the truth in log-range, ``ln 2 / 0.15``; chosen on varied simulated cases, seeds
        0-199 of ``benchmarks/bench_tma.py --flags``).
    min_manoeuvre_sigmas : float, keyword-only
        Range counts as unobservable when the own-ship's departure from a straight
        constant-speed track, seen from the target (departure / range), subtends fewer than
        this many bearing standard deviations (the larger of the given and the fitted one).
    noise : {"fit", "given"}, keyword-only
        ``"fit"`` (default): covariances scaled to the residuals seen
        (:func:`~fusion.passive.tma.confidence.noise_inflation`: their variance and their
        correlation from one bearing to the next, never below the given noise); ``"given"``:
        the graph's covariance with `bearing_sigma_deg` as it is.
    interval_level : float, keyword-only
        Coverage of the range interval (default 0.95).
    prior_sigma_m, prior_sigma_mps : float, keyword-only
        Standard deviations of the diffuse prior on the first state, m and m/s.
    max_iterations : int, keyword-only
        Levenberg-Marquardt iteration limit.

    Examples
    --------
    >>> t = np.arange(0.0, 1200.0, 30.0)
    >>> own = np.column_stack([np.where(t < 600, 0.0, 5 * (t - 600)), 5 * np.minimum(t, 600)])
    >>> target = np.column_stack([4000 - 3 * t, 3000 + 0 * t])
    >>> z = np.arctan2(target[:, 0] - own[:, 0], target[:, 1] - own[:, 1])
    >>> res = BearingsOnlyTMA(bearing_sigma_deg=0.5).estimate(t, z, OwnshipTrack(t, own))
    >>> bool(np.allclose(res.states[-1], [4000 - 3 * t[-1], 3000, -3, 0], atol=1e-3))
    True
    """

    def __init__(
        self,
        *,
        bearing_sigma_deg: float = 1.0,
        motion: str = "single",
        q: float = 1e-6,
        robust: str | None = None,
        robust_k: float = 2.0,
        initial_ranges_m: ArrayLike | None = None,
        min_range_m: float = 1.0,
        min_manoeuvre_m: float = 5.0,
        max_range_rel_sigma: float = 0.15,
        min_manoeuvre_sigmas: float = 1.0,
        noise: str = "fit",
        interval_level: float = 0.95,
        prior_sigma_m: float = 1e5,
        prior_sigma_mps: float = 100.0,
        max_iterations: int = 100,
    ) -> None:
        positive = {
            "bearing_sigma_deg": bearing_sigma_deg,
            "q": q,
            "robust_k": robust_k,
            "max_range_rel_sigma": max_range_rel_sigma,
            "min_range_m": min_range_m,
            "prior_sigma_m": prior_sigma_m,
            "prior_sigma_mps": prior_sigma_mps,
        }
        for name, value in positive.items():
            check_positive(name, value)
        check_positive("min_manoeuvre_m", min_manoeuvre_m, allow_zero=True)
        check_positive("min_manoeuvre_sigmas", min_manoeuvre_sigmas, allow_zero=True)
        if noise not in ("fit", "given"):
            raise ValueError(f"noise must be 'fit' or 'given', got {noise!r}")
        if not 0 < interval_level < 1:
            raise ValueError(f"interval_level must be in (0, 1), got {interval_level!r}")
        if motion not in ("chain", "single"):
            raise ValueError(f"motion must be 'chain' or 'single', got {motion!r}")
        if robust is not None and robust not in _ROBUST:
            raise ValueError(f"robust must be None or one of {sorted(_ROBUST)}, got {robust!r}")
        if int(max_iterations) < 1:
            raise ValueError(f"max_iterations must be >= 1, got {max_iterations!r}")
        ranges = (
            np.geomspace(200.0, 50_000.0, 9)
            if initial_ranges_m is None
            else np.asarray(initial_ranges_m, dtype=float).ravel()
        )
        if ranges.size == 0 or not np.all(np.isfinite(ranges)) or np.any(ranges <= 0):
            raise ValueError("initial_ranges_m must hold finite ranges > 0 m")
        self.bearing_sigma = float(np.radians(bearing_sigma_deg))
        self.motion = motion
        self.q = float(q)
        self.robust = robust
        self.robust_k = float(robust_k)
        self.initial_ranges_m = ranges
        self.min_manoeuvre_m = float(min_manoeuvre_m)
        self.min_range_m = float(min_range_m)
        self.max_range_rel_sigma = float(max_range_rel_sigma)
        self.min_manoeuvre_sigmas = float(min_manoeuvre_sigmas)
        self.noise = noise
        self.interval_level = float(interval_level)
        self.prior_sigma_m = float(prior_sigma_m)
        self.prior_sigma_mps = float(prior_sigma_mps)
        self.max_iterations = int(max_iterations)

    # ------------------------------------------------------------------ initialisation
    def initial_state(
        self, times: NDArray[np.float64], bearings: NDArray[np.float64], own: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Starting state of the graph solve: the candidate that best explains the bearings.

        Parameters
        ----------
        times : ndarray, shape (n,)
            Bearing times, s.
        bearings : ndarray, shape (n,)
            True bearings, rad.
        own : ndarray, shape (n, 2)
            Own-ship positions at the bearing times, m.

        Returns
        -------
        ndarray, shape (4,)
            ``[x, y, vx, vy]`` at ``times[0]``, m and m/s.

        Notes
        -----
        Candidates, all closed-form (no optimisation): the pseudo-linear estimate; for each
        range ``r`` of `initial_ranges_m` the target at ``own[0] + r (sin z0, cos z0)`` with the
        velocity that best satisfies the pseudo-linear equations from that position; and for
        each pair of ranges the straight track from the first bearing to the last. Each is
        scored by the sum of squared whitened bearing residuals (each capped at `robust_k`
        when a robust loss is set) on at most 200 bearings spread over the window; the lowest
        score wins, skipping candidates that put the target within `min_range_m` of the
        own-ship at those bearings (the zero-range solution fits any bearings when range is
        unobservable).
        """
        dt = times - times[0]
        candidates = np.vstack([_pseudo_linear(dt, bearings, own)[None, :],
                                _range_candidates(dt, bearings, own, self.initial_ranges_m)])
        candidates = candidates[np.all(np.isfinite(candidates), axis=1)]
        # score on at most _SCORE_BEARINGS bearings spread over the window, all candidates at once
        pick = np.unique(np.linspace(0, times.size - 1, min(times.size, _SCORE_BEARINGS))
                         .round().astype(int))
        dt_p, own_p = dt[pick], own[pick]
        rel = (candidates[:, None, :2] + dt_p[None, :, None] * candidates[:, None, 2:]
               - own_p[None, :, :])  # target - own-ship, every candidate and scored time
        far = np.min(np.hypot(rel[..., 0], rel[..., 1]), axis=1) >= self.min_range_m
        if not far.any():  # the degenerate zero-range solution fits any bearings
            return candidates[min(1, candidates.shape[0] - 1)]
        candidates = candidates[far]
        u = wrap_angle(target_bearing(candidates[:, None, :], own_p[None], dt=dt_p[None])
                       - bearings[None, pick]) / self.bearing_sigma  # whitened residuals
        if self.robust is not None:
            u = np.minimum(np.abs(u), self.robust_k)  # a robust loss: bounded influence
        return candidates[int(np.argmin(np.sum(u * u, axis=1)))]

    # ------------------------------------------------------------------ graph
    def _bearing_noise(self, m: int) -> gtsam.noiseModel.Base:
        """Noise of a batch of m bearings; a robust loss acts on each bearing alone."""
        base = gtsam.noiseModel.Isotropic.Sigma(m, self.bearing_sigma)
        if self.robust is None:
            return base
        estimator = _ROBUST[self.robust].Create(self.robust_k, _PER_BEARING)
        return gtsam.noiseModel.Robust.Create(estimator, base)

    def _solve(
        self, motion: str, times: NDArray[np.float64], bearings: NDArray[np.float64],
        own: NDArray[np.float64], s0: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Optimise the graph; per-time states (n, 4) and covariances (n, 4, 4)."""
        graph, values, keys = self._build(motion, times, bearings, own, s0)
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(self.max_iterations)
        params.setRelativeErrorTol(1e-10)
        params.setAbsoluteErrorTol(1e-12)
        solution = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
        if motion == "single":
            F = _transitions(times - times[0])
            states = F @ solution.atVector(keys[0])  # s_k = F(t_k - t_0) s_0
        else:
            states = np.stack([solution.atVector(k) for k in keys])
        try:
            marginals = gtsam.Marginals(graph, solution)
            if motion == "single":
                P = marginals.marginalCovariance(keys[0])
                covs = F @ P @ F.transpose(0, 2, 1)  # P_k = F P F^T
            else:
                covs = np.stack([marginals.marginalCovariance(k) for k in keys])
        except RuntimeError:  # gtsam's IndeterminantLinearSystemException
            logger.debug("TMA: Marginals found the information matrix indeterminate; using SVD")
            A, _ = graph.linearize(solution).jacobian(gtsam.Ordering(keys))
            _, sv, vt = np.linalg.svd(A, full_matrices=False)
            inv_sv = np.where(sv > sv[0] * 1e-15, 1.0 / np.maximum(sv, 1e-300), np.inf)
            full = (vt.T * inv_sv**2) @ vt  # (A^T A)^-1 = V S^-2 V^T
            blocks = np.stack([full[4 * i : 4 * i + 4, 4 * i : 4 * i + 4]
                               for i in range(len(keys))])
            covs = F @ blocks[0] @ F.transpose(0, 2, 1) if motion == "single" else blocks
        covs = 0.5 * (covs + covs.transpose(0, 2, 1))
        return states, covs

    def _build(
        self, motion: str, times: NDArray[np.float64], bearings: NDArray[np.float64],
        own: NDArray[np.float64], s0: NDArray[np.float64],
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values, list[int]]:
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        prior = gtsam.noiseModel.Diagonal.Sigmas(
            np.array([self.prior_sigma_m] * 2 + [self.prior_sigma_mps] * 2)
        )
        dt = times - times[0]
        if motion == "single":
            key = gtsam.symbol("s", 0)
            values.insert(key, s0)
            graph.add(gtsam.PriorFactorVector(key, s0, prior))
            # every bearing on the one state: one vector factor
            graph.add(target_bearing_batch_factor(self._bearing_noise(times.size), key, own,
                                                  bearings, dt=dt))
            return graph, values, [key]
        keys = [gtsam.symbol("x", k) for k in range(times.size)]
        states = _transitions(dt) @ s0
        for key, state in zip(keys, states, strict=True):
            values.insert(key, state)  # x_k = F(t_k - t_0) s_0
        for a in range(0, times.size, _CHAIN_WINDOW):  # bearings of a few neighbouring states
            b = min(a + _CHAIN_WINDOW, times.size)
            graph.add(target_bearing_batch_factor(self._bearing_noise(b - a), keys[a:b], own[a:b],
                                                  bearings[a:b]))
        graph.push_back(constant_velocity_chain(keys, times, self.q, estimates=states, wrap=False))
        graph.add(gtsam.PriorFactorVector(keys[0], s0, prior))
        return graph, values, keys

    # ------------------------------------------------------------------ public
    def estimate(
        self, times: ArrayLike, bearings: ArrayLike, ownship: OwnshipTrack
    ) -> TmaResult:
        """Estimate the target track from true bearings.

        Parameters
        ----------
        times : array_like, shape (n,)
            Strictly increasing bearing times, s, inside the own-ship track.
        bearings : array_like, shape (n,)
            True bearings, rad, clockwise from north.
        ownship : OwnshipTrack
            Own-ship track, interpolated to `times`.

        Returns
        -------
        TmaResult
            Per-time states and covariances, observability flags.

        Raises
        ------
        ValueError
            Fewer than 4 bearings, non-finite values, times not increasing, or bearing times
            outside the own-ship track.
        """
        t = _finite_1d("bearing times", times)
        z = _finite_1d("bearings", bearings)
        if t.size != z.size:
            raise ValueError(f"{t.size} bearing times but {z.size} bearings")
        if t.size < 4:
            raise ValueError(f"TMA needs at least 4 bearings (4 unknowns), got {t.size}")
        if np.any(np.diff(t) <= 0):
            raise ValueError("bearing times must be strictly increasing")
        z = np.asarray(wrap_angle(z), dtype=float)
        own = ownship.at(t)

        with _one_blas_thread():
            manoeuvre = ownship_manoeuvre(t, own)
            s0 = self.initial_state(t, z, own)
            motion = self.motion
            if motion == "chain" and manoeuvre < self.min_manoeuvre_m:
                # Without an own-ship manoeuvre the chain's optimum collapses onto the own-ship
                # (the target then follows the own-ship's constant velocity at zero CV cost);
                # the single-state model keeps the initial range instead.
                motion = "single"
            states, covs = self._solve(motion, t, z, own, s0)
            if motion == "chain" and np.min(_ranges(states, own)) < self.min_range_m:
                logger.info("TMA chain solution collapsed onto the own-ship; using a single state")
                motion = "single"
                states, covs = self._solve(motion, t, z, own, s0)
            resid = wrap_angle(target_bearing(states, own) - z)
            rms_deg = float(np.degrees(np.sqrt(np.mean(np.square(resid)))))
            scale, rho, s_fit = noise_inflation(resid, self.bearing_sigma)
            if self.noise == "given":
                scale = 1.0
            covs = covs * scale
            rel = range_rel_sigma(states[-1], own[-1], t - t[-1], own, self.bearing_sigma)
            rel = rel * float(np.sqrt(scale))
            low, high, rel_post = range_interval(states, covs, own, level=self.interval_level)
        reasons = []
        if manoeuvre < self.min_manoeuvre_m:
            reasons.append(
                f"own-ship did not manoeuvre (largest departure from a straight constant-speed "
                f"track {manoeuvre:.3g} m < {self.min_manoeuvre_m:g} m)"
            )
        sigma_eff = max(self.bearing_sigma, s_fit)
        subtended = manoeuvre / float(np.median(_ranges(states, own)))
        if manoeuvre >= self.min_manoeuvre_m and subtended < self.min_manoeuvre_sigmas * sigma_eff:
            reasons.append(
                f"own-ship manoeuvre too small for the range (departure {manoeuvre:.3g} m seen "
                f"from the target: {np.degrees(subtended):.3g} deg < "
                f"{self.min_manoeuvre_sigmas:g} x bearing sigma {np.degrees(sigma_eff):.3g} deg)"
            )
        rel_worst = max(rel, float(rel_post[-1]))
        if not rel_worst <= self.max_range_rel_sigma:
            reasons.append(
                f"range ill-conditioned (relative range sigma {rel_worst:.3g} > "
                f"{self.max_range_rel_sigma:g})"
            )
        reason = "; ".join(reasons)
        if reason:
            logger.warning("TMA range unobservable: %s", reason)
        return TmaResult(
            times=t, states=states, covariances=covs, ownship_xy=own, observable=not reasons,
            reason=reason, ownship_manoeuvre_m=manoeuvre, range_rel_sigma=rel_worst,
            bearing_rms_deg=rms_deg, motion=motion, range_low=low, range_high=high,
            covariance_scale=float(scale), residual_rho=rho,
        )
