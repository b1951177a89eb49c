"""One sound speed for a whole recording, estimated on a factor graph from its fixes.

The localizer of a window reads TDOAs along straight rays at one speed ``c``. In the sea the
speed depends on depth, so the effective speed of a path (its length over its travel time) differs
from the array file's nominal value by up to about 1 %; every delay is then read as a range
difference that is 1 % too long or short, and a fix from a kilometre-scale array moves by tens
of metres, mostly in depth. A single window cannot tell ``c`` from the source's depth; the
fixes of a whole recording can, because ``c`` is shared by all of them.

:func:`estimate_sound_speed` builds one graph: a ``Point3`` per fix, one vector TDOA factor per
fix over the TDOAs it owns (read along their paths on real or image sensors, association
weights kept) with the shared speed variable, a weak prior on the speed at the nominal value
and a weak prior on each position (every variable constrained, no indeterminate system), and
solves it by Levenberg-Marquardt with a per-TDOA Huber kernel (a TDOA held by the wrong fix is
down-weighted, not allowed to pull the speed). The speed's standard deviation comes from the
marginal covariance, scaled by the a-posteriori variance factor of the residuals (the TDOA
sigmas of the front end hold the measurement noise, not the sensor-position or ray-bending
errors the residuals show). :func:`refit_fix` then re-solves any fix at the estimated speed.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (14)-(15): the model delay of a TDOA
``d_m = (|p - s_i| - |p - s_j|) / c`` with ``c`` a variable of the graph (the TDOA factor's
``speed_key``) instead of a constant. The surface image of a sensor (``z -> 2 z_s - z``) makes a
surface-reflected path a straight one (:mod:`fusion.localization.surface_paths`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.tdoa_factors import weighted_tdoa_vector_factor
from fusion.types import frozen_array

__all__ = [
    "MIN_CALIBRATION_FIXES",
    "FixTdoas",
    "SoundSpeedEstimate",
    "estimate_sound_speed",
    "fix_residuals",
    "path_sensors",
    "refit_fix",
]

#: Fewest fixes (each with a redundant TDOA) from which a recording's speed is estimated.
MIN_CALIBRATION_FIXES = 3
#: Prior standard deviation of the speed around the array file's value, m/s (about 2 %: the
#: speed of sea water lies within 1450-1550 m/s at the depths of a range).
PRIOR_SIGMA_MPS = 30.0
#: Prior standard deviation of each fix around its first solution, m (weak: a gauge, no
#: information the TDOAs do not give).
POSITION_PRIOR_M = 1000.0
#: Huber threshold of the per-TDOA kernel, in (unit-variance) sigmas.
HUBER_K = 3.0


def path_sensors(sensors: ArrayLike, pairs: ArrayLike, paths: ArrayLike, surface_z: float = 0.0
                 ) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Sensors and pairs under which TDOAs read along `paths` are direct ones.

    Parameters
    ----------
    sensors : array_like, shape (n, 3)
        Sensor positions, m (z up).
    pairs : array_like of int, shape (m, 2)
        Sensor pair ``(i, j)`` of each TDOA.
    paths : array_like of int, shape (m,)
        Path pair of each TDOA: 0 direct, 1 both surface-reflected, 2 direct at ``i`` and
        reflected at ``j``, 3 reflected at ``i`` and direct at ``j``
        (:data:`fusion.localization.surface_paths.PATHS`).
    surface_z : float
        Height of the reflecting surface, m.

    Returns
    -------
    sensors : ndarray, shape (2 n, 3)
        The sensors, then their images ``(x, y, 2 z_s - z)``.
    pairs : ndarray of int, shape (m, 2)
        Each pair on the real or image sensors of its path.
    """
    s = np.asarray(sensors, dtype=float)
    n = s.shape[0]
    image = s * [1.0, 1.0, -1.0] + [0.0, 0.0, 2.0 * surface_z]
    q = np.array(pairs, dtype=np.intp).reshape(-1, 2).copy()
    h = np.asarray(paths, dtype=np.intp).reshape(-1)
    if h.shape[0] != q.shape[0] or np.any((h < 0) | (h > 3)):
        raise ValueError("paths must hold one path pair in 0-3 per TDOA")
    q[:, 0] += n * np.isin(h, (1, 3))
    q[:, 1] += n * np.isin(h, (1, 2))
    return np.vstack([s, image]), q


@dataclass(frozen=True)
class FixTdoas:
    """The TDOAs one fix owns, read along their paths (direct pairs of real or image sensors).

    Attributes
    ----------
    sensors : ndarray, shape (n', 3)
        Sensors (with images where a path is reflected), m.
    pairs : ndarray of int, shape (m, 2)
        Pairs of `sensors`.
    taus : ndarray, shape (m,)
        Delays at one emission of the source, s.
    sigmas : ndarray, shape (m,)
        Their standard deviations, s.
    weights : ndarray, shape (m,)
        Association weight of each TDOA in the fix, in [0, 1].
    position : ndarray, shape (3,)
        The fix at the nominal speed (the start), m.
    """

    sensors: NDArray[np.float64]
    pairs: NDArray[np.intp]
    taus: NDArray[np.float64]
    sigmas: NDArray[np.float64]
    weights: NDArray[np.float64]
    position: NDArray[np.float64]

    def __post_init__(self) -> None:
        for name in ("sensors", "taus", "sigmas", "weights", "position"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        object.__setattr__(self, "pairs", frozen_array(self.pairs, dtype=np.intp))
        m = self.taus.shape[0]
        if self.pairs.shape != (m, 2) or self.sigmas.shape != (m,) or self.weights.shape != (m,):
            raise ValueError("pairs, taus, sigmas and weights must describe the same TDOAs")
        if not np.all(np.isfinite(self.sigmas) & (self.sigmas > 0)):
            raise ValueError("TDOA sigmas must be positive and finite")

    @property
    def m(self) -> int:
        """Number of TDOAs."""
        return int(self.taus.shape[0])


@dataclass(frozen=True)
class SoundSpeedEstimate:
    """A recording's sound speed from its fixes.

    Attributes
    ----------
    nominal_mps : float
        The array file's speed (prior mean), m/s.
    speed_mps : float
        The estimate, m/s (the nominal one when nothing was estimated).
    sigma_mps : float
        Its standard deviation, m/s (inf when nothing was estimated).
    n_fixes, n_tdoas : int
        Fixes and TDOAs in the graph.
    variance_factor : float
        A-posteriori variance factor of the whitened residuals (1 when the sigmas hold).
    positions : ndarray, shape (n_fixes, 3)
        The fixes at the estimated speed, m.
    covariances : ndarray, shape (n_fixes, 3, 3)
        Their marginal covariances (with the speed's uncertainty, scaled by the variance
        factor), m^2.
    """

    nominal_mps: float
    speed_mps: float
    sigma_mps: float
    n_fixes: int
    n_tdoas: int
    variance_factor: float
    positions: NDArray[np.float64]
    covariances: NDArray[np.float64]

    def to_dict(self) -> dict:
        """The estimate's scalars, JSON-ready."""
        return {"nominal_mps": self.nominal_mps, "speed_mps": self.speed_mps,
                "sigma_mps": self.sigma_mps if np.isfinite(self.sigma_mps) else None,
                "fixes": self.n_fixes, "tdoas": self.n_tdoas,
                "variance_factor": self.variance_factor}


def _factor(fix: FixTdoas, key: int, *, c: float | None = None, speed_key: int | None = None,
            robust: bool = True) -> gtsam.CustomFactor:
    kernel = gtsam.noiseModel.mEstimator.Huber.Create(HUBER_K) if robust else None
    return weighted_tdoa_vector_factor(gtsam.noiseModel.Diagonal.Sigmas(fix.sigmas), key,
                                       fix.sensors, fix.pairs, fix.taus,
                                       np.array(fix.weights), c=c, speed_key=speed_key,
                                       robust=kernel)


def fix_residuals(fix: FixTdoas, position: ArrayLike, c: float) -> NDArray[np.float64]:
    """Model minus measured delay of each of a fix's TDOAs at `position` and speed `c`, s."""
    p = np.asarray(position, dtype=float)
    s = fix.sensors
    d = (np.linalg.norm(p - s[fix.pairs[:, 0]], axis=1)
         - np.linalg.norm(p - s[fix.pairs[:, 1]], axis=1)) / c
    return d - fix.taus


def _whitened(fix: FixTdoas, p: NDArray, c: float) -> NDArray[np.float64]:
    return np.sqrt(np.maximum(fix.weights, 0.0)) * fix_residuals(fix, p, c) / fix.sigmas


def _solve(fixes: Sequence[FixTdoas], nominal_mps: float, prior_sigma_mps: float,
           max_iterations: int) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """The speed-and-positions graph of `fixes`, solved (Levenberg-Marquardt)."""
    ckey = gtsam.symbol("c", 0)
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    graph.add(gtsam.PriorFactorVector(ckey, np.array([nominal_mps]),
                                      gtsam.noiseModel.Isotropic.Sigma(1, prior_sigma_mps)))
    values.insert(ckey, np.array([nominal_mps]))
    pos_prior = gtsam.noiseModel.Isotropic.Sigma(3, POSITION_PRIOR_M)
    priors = gtsam.NonlinearFactorGraph()
    for k, fix in enumerate(fixes):
        key = gtsam.symbol("x", k)
        priors.add(gtsam.PriorFactorPoint3(key, gtsam.Point3(*fix.position), pos_prior))
        values.insert(key, gtsam.Point3(*fix.position))
    graph.push_back(priors)
    # least squares first (the Huber kernel's small weights far from the solution would
    # crawl), then the robust graph from there
    plain = gtsam.NonlinearFactorGraph(graph)
    for k, fix in enumerate(fixes):
        plain.add(_factor(fix, gtsam.symbol("x", k), speed_key=ckey, robust=False))
        graph.add(_factor(fix, gtsam.symbol("x", k), speed_key=ckey))
    return graph, _optimize(graph, _optimize(plain, values, max_iterations), max_iterations)


def _optimize(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values,
              max_iterations: int) -> gtsam.Values:
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    params.setRelativeErrorTol(1e-12)
    params.setAbsoluteErrorTol(1e-20)
    return gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()


def _without_sensor(fix: FixTdoas, sensor: int, n_real: int) -> FixTdoas | None:
    keep = np.all(fix.pairs % n_real != sensor, axis=1)
    if np.unique(fix.pairs[keep]).size < 5:  # four sensors' delays say nothing of the speed
        return None
    return FixTdoas(fix.sensors, fix.pairs[keep], fix.taus[keep], fix.sigmas[keep],
                    fix.weights[keep], fix.position)


def _sensor_jackknife(fixes: Sequence[FixTdoas], n_real: int, nominal_mps: float,
                      prior_sigma_mps: float, max_iterations: int) -> float:
    """Delete-one-sensor jackknife standard deviation of the speed, m/s (NaN when fewer
    than three sensors can be left out and still teach the speed)."""
    speeds = []
    for k in range(n_real):
        sub = [f for f in (_without_sensor(f, k, n_real) for f in fixes) if f is not None]
        if len(sub) < MIN_CALIBRATION_FIXES:
            continue
        _, result = _solve(sub, nominal_mps, prior_sigma_mps, max_iterations)
        speeds.append(float(result.atVector(gtsam.symbol("c", 0))[0]))
    g = len(speeds)
    if g < 3:
        return float("nan")
    return float(np.sqrt((g - 1) / g * np.sum((np.array(speeds) - np.mean(speeds)) ** 2)))


def estimate_sound_speed(fixes: Sequence[FixTdoas], *, nominal_mps: float,
                         prior_sigma_mps: float = PRIOR_SIGMA_MPS,
                         n_real_sensors: int | None = None,
                         max_iterations: int = 100) -> SoundSpeedEstimate:
    """One sound speed shared by `fixes`, and the fixes at that speed (one graph).

    Parameters
    ----------
    fixes : sequence of FixTdoas
        Each fix's own TDOAs; a fix needs more TDOAs than its 3 coordinates to tell anything
        about the speed (the caller picks them).
    nominal_mps : float
        The array file's speed, m/s: the prior mean and the start.
    prior_sigma_mps : float
        Prior standard deviation of the speed, m/s.
    n_real_sensors : int, optional
        Number of real sensors (indices of the fixes' sensors modulo it name a real sensor,
        images included): the speed's standard deviation is then also measured by leaving
        out each sensor in turn (a delete-one jackknife) and the larger of the two is given.
        A sensor's survey error is shared by every fix, so the residuals of one graph do not
        show it; the jackknife does.
    max_iterations : int
        Levenberg-Marquardt iterations.

    Returns
    -------
    SoundSpeedEstimate

    Raises
    ------
    ValueError
        Fewer than :data:`MIN_CALIBRATION_FIXES` fixes, or a speed outside 1,300-1,800 m/s.
    """
    if len(fixes) < MIN_CALIBRATION_FIXES:
        raise ValueError(f"{len(fixes)} fixes with redundant TDOAs; the sound speed needs "
                         f"at least {MIN_CALIBRATION_FIXES}")
    if not (np.isfinite(nominal_mps) and nominal_mps > 0 and prior_sigma_mps > 0):
        raise ValueError("the nominal sound speed and its prior sigma must be positive")
    graph, result = _solve(fixes, nominal_mps, prior_sigma_mps, max_iterations)
    ckey = gtsam.symbol("c", 0)
    c = float(result.atVector(ckey)[0])
    if not 1300.0 <= c <= 1800.0:
        raise ValueError(f"the fixes point to a sound speed of {c:.1f} m/s, outside "
                         "1,300-1,800 m/s (wrong fixes or array file)")
    positions = np.array([result.atPoint3(gtsam.symbol("x", k)) for k in range(len(fixes))])
    r = np.concatenate([_whitened(f, p, c) for f, p in zip(fixes, positions, strict=True)])
    dof = max(1, r.size - 3 * len(fixes) - 1)
    factor = max(1.0, float(np.sum(r * r)) / dof)
    marginals = gtsam.Marginals(graph, result)
    sigma = float(np.sqrt(marginals.marginalCovariance(ckey)[0, 0] * factor))
    if n_real_sensors is not None:
        jk = _sensor_jackknife(fixes, int(n_real_sensors), nominal_mps, prior_sigma_mps,
                               max_iterations)
        sigma = max(sigma, jk) if np.isfinite(jk) else sigma
    cov = np.array([marginals.marginalCovariance(gtsam.symbol("x", k)) * factor
                    for k in range(len(fixes))])
    return SoundSpeedEstimate(float(nominal_mps), c, sigma, len(fixes), int(r.size), factor,
                              positions, cov)


def refit_fix(fix: FixTdoas, speed_mps: float, *, variance_factor: float = 1.0,
              max_iterations: int = 50) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A fix re-solved at a given speed from its start: (position (3,), covariance (3, 3)).

    The covariance is NaN where the fix's TDOAs leave its position unfixed; it is scaled by
    `variance_factor` (the recording's, :class:`SoundSpeedEstimate`).
    """
    key = gtsam.symbol("x", 0)
    plain = gtsam.NonlinearFactorGraph()
    plain.add(_factor(fix, key, c=speed_mps, robust=False))
    graph = gtsam.NonlinearFactorGraph()
    graph.add(_factor(fix, key, c=speed_mps))
    values = gtsam.Values()
    values.insert(key, gtsam.Point3(*fix.position))
    try:
        result = _optimize(graph, _optimize(plain, values, max_iterations), max_iterations)
        p = np.asarray(result.atPoint3(key), dtype=float)
        cov = gtsam.Marginals(graph, result).marginalCovariance(key) * variance_factor
    except RuntimeError:  # indeterminate: too few independent TDOAs for a 3-D fix
        return np.array(fix.position), np.full((3, 3), np.nan)
    return p, np.asarray(cov, dtype=float)
