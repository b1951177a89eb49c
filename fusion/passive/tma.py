"""Bearings-only target motion analysis (TMA) on a factor graph.

A platform (own-ship) with a known track measures true bearings of a target that moves at a
(nearly) constant velocity. The target's position and velocity follow from the bearings only when
the own-ship manoeuvres; the estimator reports its covariance and says when range is unobservable.

Formulation (design notes, "Factor graphs", bearings-only target motion analysis). Two target
models, chosen with ``motion``:

* ``"single"`` (default, the classical TMA): one ``Vector4`` state ``s_0 = [x, y, vx, vy]`` at the
  first bearing time; the bearing taken at ``t_k`` sees ``s_0`` propagated by ``dt = t_k - t_0``.
  All bearings enter through one vector factor
  (:func:`factors.target.target_bearing_batch_factor` with ``dt``): one Python callback per
  evaluation, whatever the number of bearings. Per-time states and covariances follow as
  ``s_k = F(dt) s_0`` and ``P_k = F P_0 F^T``.
* ``"chain"``: one state per bearing time, bearing factors on them (one vector factor per few
  neighbouring states), linked by built-in linear constant-velocity factors
  (:func:`factors.motion.constant_velocity_chain`) with the white-noise-acceleration
  covariance ``Q(dt)`` of a small spectral density ``q``: the target may drift slowly off a
  straight line.

Why ``"single"`` is the default: for a target that holds course it is the exact model, its
covariance is consistent (the chain's process noise makes the covariance conservative for such a
target), it is better conditioned and several times faster. ``"chain"`` suits slowly
manoeuvring targets.

Both models use bearing factors that may be robust (Huber, Cauchy or Tukey, acting on each
bearing alone); a diffuse prior on
the first state (100 km, 100 m/s by default), centred on the initial guess, keeps the optimiser
from wandering along an unobservable range direction and is negligible whenever the bearings
determine the state. Covariances come from ``gtsam.Marginals``; when its Cholesky factorisation
finds the information matrix indeterminate (range unobservable, or a tiny ``q`` against the
diffuse prior), from the singular value decomposition of the dense whitened Jacobian instead
(the same matrix, factored without squaring its condition number).

Initialisation needs no truth and no second solver: closed-form candidates (the pseudo-linear
estimate, and states along the first bearing at geometrically spaced ranges with their
pseudo-linear velocities) are scored by the cost of the graph's bearing factor, with the robust
loss when one is set; the lowest-cost candidate seeds the graph, which one Levenberg-Marquardt
run solves.

Observability: range is unobservable when the own-ship keeps a constant velocity (the target's
relative track can be scaled without changing a single bearing). Two checks flag it, each with a
``logging`` warning and ``TmaResult.observable = False``: the own-ship's largest departure from a
straight constant-speed track fitted to its positions (``min_manoeuvre_m``), and the relative
standard deviation of the final range along the line of sight (``max_range_rel_sigma``), i.e. an
ill-conditioned information matrix in the range direction.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray
from threadpoolctl import ThreadpoolController

from factors.motion import constant_velocity_chain
from factors.target import target_bearing, target_bearing_batch_factor, target_bearing_jacobian
from fusion._validation import check_positive
from fusion.geometry import wrap_angle

__all__ = [
    "BearingsOnlyTMA", "OwnshipTrack", "TmaResult", "ownship_manoeuvre", "range_rel_sigma",
]

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


def _finite_1d(name: str, a: ArrayLike) -> NDArray[np.float64]:
    arr = np.asarray(a, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


@dataclass(frozen=True)
class OwnshipTrack:
    """Known own-ship positions over time.

    Attributes
    ----------
    times : ndarray, shape (n,)
        Strictly increasing times, s.
    xy : ndarray, shape (n, 2)
        Positions ``[x east, y north]``, m.
    """

    times: NDArray[np.float64]
    xy: NDArray[np.float64]

    def __post_init__(self) -> None:
        t = _finite_1d("own-ship times", self.times)
        xy = np.asarray(self.xy, dtype=float)
        if xy.shape != (t.size, 2) or not np.all(np.isfinite(xy)):
            raise ValueError(
                f"own-ship positions must be finite with shape ({t.size}, 2), got {xy.shape}"
            )
        if t.size < 2:
            raise ValueError("own-ship track needs at least 2 positions")
        if np.any(np.diff(t) <= 0):
            raise ValueError("own-ship times must be strictly increasing")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "xy", xy)

    def at(self, times: ArrayLike) -> NDArray[np.float64]:
        """Own-ship positions at `times`, linearly interpolated (no extrapolation).

        Parameters
        ----------
        times : array_like, shape (m,)
            Query times, s, inside ``[times[0], times[-1]]``.

        Returns
        -------
        ndarray, shape (m, 2)
            Positions, m.

        Raises
        ------
        ValueError
            If a query time lies outside the own-ship track.
        """
        t = _finite_1d("times", times)
        span = self.times[-1] - self.times[0]
        tol = 1e-9 * max(1.0, span, float(np.max(np.abs(self.times))))
        if t.size and (t.min() < self.times[0] - tol or t.max() > self.times[-1] + tol):
            raise ValueError(
                f"bearing times [{t.min():g}, {t.max():g}] s reach outside the own-ship track "
                f"[{self.times[0]:g}, {self.times[-1]:g}] s"
            )
        return np.column_stack(
            [np.interp(t, self.times, self.xy[:, 0]), np.interp(t, self.times, self.xy[:, 1])]
        )


@dataclass(frozen=True)
class TmaResult:
    """Target track estimated from bearings.

    Attributes
    ----------
    times : ndarray, shape (n,)
        Bearing times, s.
    states : ndarray, shape (n, 4)
        Target ``[x, y, vx, vy]`` at each time, m and m/s.
    covariances : ndarray, shape (n, 4, 4)
        Marginal covariance of each state, m^2, m^2/s, m^2/s^2.
    ownship_xy : ndarray, shape (n, 2)
        Own-ship positions at the bearing times, m.
    observable : bool
        False when either observability check failed (see `reason`).
    reason : str
        Why range is deemed unobservable; empty when observable.
    ownship_manoeuvre_m : float
        Largest distance, m, of the own-ship from a straight constant-speed track fitted to its
        positions at the bearing times.
    range_rel_sigma : float
        Standard deviation of the final range along the line of sight divided by that range.
    bearing_rms_deg : float
        RMS of the bearing residuals at the solution, deg.
    motion : str
        Target model used, ``"single"`` or ``"chain"`` (see :class:`BearingsOnlyTMA`).
    """

    times: NDArray[np.float64]
    states: NDArray[np.float64]
    covariances: NDArray[np.float64]
    ownship_xy: NDArray[np.float64]
    observable: bool
    reason: str
    ownship_manoeuvre_m: float
    range_rel_sigma: float
    bearing_rms_deg: float
    motion: str = field(default="single")

    @property
    def x(self) -> NDArray[np.float64]:
        """East position, m, shape (n,)."""
        return self.states[:, 0]

    @property
    def y(self) -> NDArray[np.float64]:
        """North position, m, shape (n,)."""
        return self.states[:, 1]

    @property
    def vx(self) -> NDArray[np.float64]:
        """East velocity, m/s, shape (n,)."""
        return self.states[:, 2]

    @property
    def vy(self) -> NDArray[np.float64]:
        """North velocity, m/s, shape (n,)."""
        return self.states[:, 3]

    @property
    def sigma_x(self) -> NDArray[np.float64]:
        """Standard deviation of `x`, m, shape (n,)."""
        return np.sqrt(self.covariances[:, 0, 0])

    @property
    def sigma_y(self) -> NDArray[np.float64]:
        """Standard deviation of `y`, m, shape (n,)."""
        return np.sqrt(self.covariances[:, 1, 1])

    @property
    def range(self) -> NDArray[np.float64]:
        """Own-ship to target range, m, shape (n,)."""
        return _ranges(self.states, self.ownship_xy)

    @property
    def bearing(self) -> NDArray[np.float64]:
        """True bearing of the estimated target from the own-ship, rad, shape (n,)."""
        return target_bearing(self.states, self.ownship_xy)


def ownship_manoeuvre(times: ArrayLike, xy: ArrayLike) -> float:
    """Largest departure of a track from its least-squares constant-velocity fit.

    Parameters
    ----------
    times : array_like, shape (n,)
        Times, s.
    xy : array_like, shape (n, 2)
        Positions, m.

    Returns
    -------
    float
        ``max_k |xy_k - (a + b t_k)|``, m, with ``a, b`` (2-vectors) fitted by least squares.
        Zero for a constant-velocity track.
    """
    t = np.asarray(times, dtype=float)
    p = np.asarray(xy, dtype=float)
    A = np.column_stack([np.ones_like(t), t - t.mean()])
    coef, *_ = np.linalg.lstsq(A, p, rcond=None)
    return float(np.max(np.linalg.norm(p - A @ coef, axis=1)))


def _ranges(states: NDArray[np.float64], own: NDArray[np.float64]) -> NDArray[np.float64]:
    d = states[:, :2] - own
    return np.hypot(d[:, 0], d[:, 1])


def range_rel_sigma(
    state: ArrayLike, own_ref: ArrayLike, dt: ArrayLike, own: ArrayLike, bearing_sigma: float
) -> float:
    """Relative range standard deviation that bearings alone give a constant-velocity target.

    Parameters
    ----------
    state : array_like, shape (4,)
        Target ``[x, y, vx, vy]`` at the reference time, m and m/s.
    own_ref : array_like, shape (2,)
        Own-ship position at the reference time, m.
    dt : array_like, shape (n,)
        Bearing times minus the reference time, s.
    own : array_like, shape (n, 2)
        Own-ship positions at the bearing times, m.
    bearing_sigma : float
        Bearing standard deviation, rad.

    Returns
    -------
    float
        ``sqrt(u^T P u) / r`` at the reference time, with ``u`` the unit line of sight, ``r`` the
        range and ``P`` the position block of the Cramér-Rao bound ``(J^T J)^-1`` of the
        whitened bearing Jacobian ``J`` (n, 4); ``inf`` when ``J`` is rank deficient (a
        constant-velocity own-ship: scaling the relative track leaves every bearing unchanged).

    Notes
    -----
    Uses no prior and no process noise, so it measures what the bearings themselves say about
    range: the "information matrix ill-conditioned in range" test.
    """
    s = np.asarray(state, dtype=float)
    o = np.asarray(own, dtype=float)
    J = target_bearing_jacobian(s, o, dt=np.asarray(dt, dtype=float)) / bearing_sigma
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    los = s[:2] - np.asarray(own_ref, dtype=float)
    r = float(np.hypot(*los))
    if sv.size < 4 or sv[-1] <= sv[0] * 1e-10 or r == 0.0:
        return float("inf")
    u = np.concatenate([los / r, [0.0, 0.0]])
    return float(np.linalg.norm((vt @ u) / sv)) / r  # sqrt(u^T V S^-2 V^T u) / r


def _transitions(dt: NDArray[np.float64]) -> NDArray[np.float64]:
    """Constant-velocity transition matrices ``F(dt)`` of a ``[x, y, vx, vy]`` state, (n, 4, 4)."""
    F = np.broadcast_to(np.eye(4), (dt.size, 4, 4)).copy()
    F[:, 0, 2] = F[:, 1, 3] = dt  # x += vx dt, y += vy dt
    return F


_BLAS: list[ThreadpoolController] = []


def _one_blas_thread():
    """Context limiting BLAS/LAPACK to one thread (threaded LAPACK on small matrices is far
    slower on a busy machine); the controller is made once."""
    if not _BLAS:
        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1)


def _pseudo_linear(
    dt: NDArray[np.float64], z: NDArray[np.float64], o: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Pseudo-linear estimate of the single state at the first bearing time.

    From ``(x + vx dt - x_o) cos z - (y + vy dt - y_o) sin z = 0`` for every bearing ``z``.
    """
    c, s = np.cos(z), np.sin(z)
    A = np.column_stack([c, -s, c * dt, -s * dt])
    b = c * o[:, 0] - s * o[:, 1]
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    return sol


def _range_candidates(
    dt: NDArray[np.float64], z: NDArray[np.float64], o: NDArray[np.float64],
    ranges: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Closed-form states along the first bearing, shape (r + r^2, 4).

    For each range ``r_0`` of `ranges` on the first bearing: the state whose velocity best
    satisfies the pseudo-linear equations with that position held,
    ``vx dt cos z - vy dt sin z = -(x - x_o) cos z + (y - y_o) sin z`` (least squares, all ranges
    at once); and for each pair ``(r_0, r_1)`` the straight track from range ``r_0`` on the first
    bearing to range ``r_1`` on the last (it fits both bearings exactly).
    """
    c, s = np.cos(z), np.sin(z)
    u0 = np.array([np.sin(z[0]), np.cos(z[0])])
    u1 = np.array([np.sin(z[-1]), np.cos(z[-1])])
    pos = o[0] + np.outer(ranges, u0)  # (r, 2)
    A = np.column_stack([c * dt, -s * dt])
    B = -np.outer(c, pos[:, 0]) + np.outer(s, pos[:, 1]) + (c * o[:, 0] - s * o[:, 1])[:, None]
    vel, *_ = np.linalg.lstsq(A, B, rcond=None)  # (2, r)
    held = np.column_stack([pos, vel.T])
    end = o[-1] + np.outer(ranges, u1)  # (r, 2)
    p0 = np.repeat(pos, ranges.size, axis=0)
    p1 = np.tile(end, (ranges.size, 1))
    span = dt[-1] if dt[-1] > 0 else 1.0
    two = np.column_stack([p0, (p1 - p0) / span])  # straight track between the two ranges
    return np.vstack([held, two])


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
        Relative range standard deviation above which range counts as unobservable.
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
        max_range_rel_sigma: float = 0.3,
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
            rel = range_rel_sigma(states[-1], own[-1], t - t[-1], own, self.bearing_sigma)
        reasons = []
        if manoeuvre < self.min_manoeuvre_m:
            reasons.append(
                f"own-ship did not manoeuvre (largest departure from a straight constant-speed "
                f"track {manoeuvre:.3g} m < {self.min_manoeuvre_m:g} m)"
            )
        if not rel <= self.max_range_rel_sigma:
            reasons.append(
                f"range ill-conditioned (relative range sigma {rel:.3g} > "
                f"{self.max_range_rel_sigma:g})"
            )
        reason = "; ".join(reasons)
        if reason:
            logger.warning("TMA range unobservable: %s", reason)
        return TmaResult(
            times=t, states=states, covariances=covs, ownship_xy=own, observable=not reasons,
            reason=reason, ownship_manoeuvre_m=manoeuvre, range_rel_sigma=rel,
            bearing_rms_deg=rms_deg, motion=motion,
        )
