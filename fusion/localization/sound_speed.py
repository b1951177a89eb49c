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

With ``gradient=True`` the speed is a linear profile ``c(d) = c_ref + g (d - d_ref)`` of depth
``d`` (:class:`LinearProfile`; :mod:`factors.tdoa.gradient`: travel times along straight rays,
their log-mean speed), ``[c_ref, g]`` one ``Vector(2)`` of the graph with a weak prior on ``g``
around the deep-water (pressure) gradient: one speed cannot fit paths that cross different
depths (a fix 11 m off on seed 7904 of ``--vary-only sound-speed``; docs/localization.md, "A
depth-dependent sound speed").

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

from factors.tdoa.factors import weighted_tdoa_vector_factor
from factors.tdoa.gradient import gradient_tdoa_factor, travel_times
from fusion.geometry import surface_image
from fusion.types import frozen_array

__all__ = [
    "MIN_CALIBRATION_FIXES",
    "FixTdoas",
    "LinearProfile",
    "SoundSpeedEstimate",
    "add_speed_prior",
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
#: Prior mean of the depth gradient of the speed, 1/s: the pressure gradient of deep water
#: below the sound channel axis (about 0.016-0.017 1/s).
GRADIENT_PRIOR_PER_S = 0.016
#: Its prior standard deviation, 1/s (broad: a Munk profile's gradient between whales and
#: sensors fitted -0.004 to 0.025 1/s on the tuning seeds; zero lies within two sigmas).
GRADIENT_SIGMA_PER_S = 0.01


@dataclass(frozen=True)
class LinearProfile:
    """A sound speed linear in depth: ``c(d) = speed_mps + gradient_per_s (d -
    reference_depth_m)``, ``d = -z`` (m); ``gradient_per_s = 0`` is one speed."""

    speed_mps: float
    gradient_per_s: float = 0.0
    reference_depth_m: float = 0.0

    def speed_at(self, depth_m: ArrayLike) -> NDArray[np.float64]:
        """The speed at depths (m, positive down), m/s."""
        return self.speed_mps + self.gradient_per_s * (np.asarray(depth_m, float)
                                                       - self.reference_depth_m)

    @property
    def vector(self) -> NDArray[np.float64]:
        """``[c_ref, g]``, the graph's variable."""
        return np.array([self.speed_mps, self.gradient_per_s])


def _profile(c: float | LinearProfile) -> LinearProfile:
    return c if isinstance(c, LinearProfile) else LinearProfile(float(c))


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
    image = surface_image(s, surface_z)
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
    gradient_per_s, gradient_sigma_per_s : float
        The depth gradient of the speed and its standard deviation, 1/s (0 and NaN when one
        speed was estimated); `speed_mps` is then the speed at `reference_depth_m`.
    reference_depth_m : float
        Depth of `speed_mps`, m (halfway between the real sensors' mean depth and the fixes'
        mean start depth; 0 for one speed).
    chi2 : float
        Sum of the squared whitened (weighted) residuals at the solution.
    """

    nominal_mps: float
    speed_mps: float
    sigma_mps: float
    n_fixes: int
    n_tdoas: int
    variance_factor: float
    positions: NDArray[np.float64]
    covariances: NDArray[np.float64]
    gradient_per_s: float = 0.0
    gradient_sigma_per_s: float = float("nan")
    reference_depth_m: float = 0.0
    chi2: float = float("nan")

    @property
    def profile(self) -> LinearProfile:
        """The estimated speed (a profile; gradient 0 for one speed)."""
        return LinearProfile(self.speed_mps, self.gradient_per_s, self.reference_depth_m)

    def to_dict(self) -> dict:
        """The estimate's scalars, JSON-ready."""
        out = {"nominal_mps": self.nominal_mps, "speed_mps": self.speed_mps,
               "sigma_mps": self.sigma_mps if np.isfinite(self.sigma_mps) else None,
               "fixes": self.n_fixes, "tdoas": self.n_tdoas,
               "variance_factor": self.variance_factor}
        if np.isfinite(self.gradient_sigma_per_s):
            out |= {"gradient_per_s": self.gradient_per_s,
                    "gradient_sigma_per_s": self.gradient_sigma_per_s,
                    "reference_depth_m": self.reference_depth_m}
        return out


def _factor(fix: FixTdoas, key: int, *, c: float | LinearProfile | None = None,
            speed_key: int | None = None, d_ref: float | None = None,
            robust: bool = True) -> gtsam.CustomFactor:
    """A fix's factor: one speed (`c` fixed or a ``Vector(1)`` at `speed_key`), or with
    `d_ref` (or a `c` with a gradient) the linear profile (a ``Vector(2)`` ``[c_ref, g]``)."""
    kernel = gtsam.noiseModel.mEstimator.Huber.Create(HUBER_K) if robust else None
    noise = gtsam.noiseModel.Diagonal.Sigmas(fix.sigmas)
    prof = None if c is None else _profile(c)
    if prof is not None and prof.gradient_per_s != 0.0:
        d_ref = prof.reference_depth_m
    if d_ref is None:
        return weighted_tdoa_vector_factor(noise, key, fix.sensors, fix.pairs, fix.taus,
                                           np.array(fix.weights),
                                           c=None if prof is None else prof.speed_mps,
                                           speed_key=speed_key, robust=kernel)
    return gradient_tdoa_factor(noise, key, fix.sensors, fix.pairs, fix.taus, d_ref=d_ref,
                                weights=np.array(fix.weights),
                                speed=None if prof is None else prof.vector,
                                speed_key=speed_key, robust=kernel)


def fix_residuals(fix: FixTdoas, position: ArrayLike, c: float | LinearProfile
                  ) -> NDArray[np.float64]:
    """Model minus measured delay of each of a fix's TDOAs at `position` and speed `c` (one
    speed, m/s, or a :class:`LinearProfile`), s."""
    p = np.asarray(position, dtype=float)
    s = fix.sensors
    prof = _profile(c)
    if prof.gradient_per_s == 0.0:
        t = np.linalg.norm(p - s, axis=1) / prof.speed_mps
    else:
        t, _, _ = travel_times(p, s, prof.speed_mps, prof.gradient_per_s,
                               prof.reference_depth_m)
    return t[fix.pairs[:, 0]] - t[fix.pairs[:, 1]] - fix.taus


def _whitened(fix: FixTdoas, p: NDArray, c: float | LinearProfile) -> NDArray[np.float64]:
    return np.sqrt(np.maximum(fix.weights, 0.0)) * fix_residuals(fix, p, c) / fix.sigmas


def add_speed_prior(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, key: int,
                    nominal_mps: float, prior_sigma_mps: float, d_ref: float | None) -> None:
    """The speed variable `key` of a recording graph with its prior: one speed about the array
    file's value, or with `d_ref` the linear profile ``[c_ref, g]`` (g about the deep-water
    pressure gradient)."""
    if d_ref is None:
        mean, sig = np.array([nominal_mps]), np.array([prior_sigma_mps])
    else:
        mean = np.array([nominal_mps, GRADIENT_PRIOR_PER_S])
        sig = np.array([prior_sigma_mps, GRADIENT_SIGMA_PER_S])
    graph.add(gtsam.PriorFactorVector(key, mean, gtsam.noiseModel.Diagonal.Sigmas(sig)))
    values.insert(key, mean)


def _solve(fixes: Sequence[FixTdoas], nominal_mps: float, prior_sigma_mps: float,
           max_iterations: int, d_ref: float | None = None
           ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """The speed-and-positions graph of `fixes`, solved (Levenberg-Marquardt); with `d_ref`
    the speed is the linear profile ``[c_ref, g]``."""
    ckey = gtsam.symbol("c", 0)
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    add_speed_prior(graph, values, ckey, nominal_mps, prior_sigma_mps, d_ref)
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
        plain.add(_factor(fix, gtsam.symbol("x", k), speed_key=ckey, d_ref=d_ref, robust=False))
        graph.add(_factor(fix, gtsam.symbol("x", k), speed_key=ckey, d_ref=d_ref))
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
                      prior_sigma_mps: float, max_iterations: int,
                      d_ref: float | None = None) -> NDArray[np.float64]:
    """Delete-one-sensor jackknife standard deviation of the speed (m/s) and, with `d_ref`,
    of the gradient (1/s) (NaN when fewer than three sensors can be left out and still teach
    the speed)."""
    speeds = []
    for k in range(n_real):
        sub = [f for f in (_without_sensor(f, k, n_real) for f in fixes) if f is not None]
        if len(sub) < MIN_CALIBRATION_FIXES:
            continue
        _, result = _solve(sub, nominal_mps, prior_sigma_mps, max_iterations, d_ref)
        speeds.append(np.asarray(result.atVector(gtsam.symbol("c", 0)), dtype=float))
    g = len(speeds)
    if g < 3:
        return np.full(1 if d_ref is None else 2, np.nan)
    v = np.array(speeds)
    return np.sqrt((g - 1) / g * np.sum((v - v.mean(0)) ** 2, axis=0))


def estimate_sound_speed(fixes: Sequence[FixTdoas], *, nominal_mps: float,
                         prior_sigma_mps: float = PRIOR_SIGMA_MPS,
                         n_real_sensors: int | None = None,
                         gradient: bool = False,
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
    gradient : bool
        Estimate a linear profile instead of one speed: the speed halfway in depth between
        the real sensors and the fixes (the least correlated with the gradient) and its depth
        gradient, prior :data:`GRADIENT_PRIOR_PER_S` +- :data:`GRADIENT_SIGMA_PER_S`.
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
    d_ref = None
    if gradient:  # halfway between the fixes and the sensors: c_ref is the paths' mean speed
        real = fixes[0].sensors[fixes[0].sensors[:, 2] <= 0.0]
        d_sensors = float(np.mean(-real[:, 2])) if real.size else 0.0
        d_ref = 0.5 * (d_sensors + float(np.mean([-f.position[2] for f in fixes])))
    graph, result = _solve(fixes, nominal_mps, prior_sigma_mps, max_iterations, d_ref)
    ckey = gtsam.symbol("c", 0)
    v = np.asarray(result.atVector(ckey), dtype=float)
    c = float(v[0])
    prof = LinearProfile(c) if d_ref is None else LinearProfile(c, float(v[1]), d_ref)
    if not 1300.0 <= c <= 1800.0:
        raise ValueError(f"the fixes point to a sound speed of {c:.1f} m/s, outside "
                         "1,300-1,800 m/s (wrong fixes or array file)")
    positions = np.array([result.atPoint3(gtsam.symbol("x", k)) for k in range(len(fixes))])
    r = np.concatenate([_whitened(f, p, prof) for f, p in zip(fixes, positions, strict=True)])
    dof = max(1, r.size - 3 * len(fixes) - v.size)
    factor = max(1.0, float(np.sum(r * r)) / dof)
    marginals = gtsam.Marginals(graph, result)
    sigmas = np.sqrt(np.diag(marginals.marginalCovariance(ckey)) * factor)
    if n_real_sensors is not None:
        jk = _sensor_jackknife(fixes, int(n_real_sensors), nominal_mps, prior_sigma_mps,
                               max_iterations, d_ref)
        sigmas = np.where(np.isfinite(jk), np.maximum(sigmas, jk), sigmas)
    cov = np.array([marginals.marginalCovariance(gtsam.symbol("x", k)) * factor
                    for k in range(len(fixes))])
    return SoundSpeedEstimate(float(nominal_mps), c, float(sigmas[0]), len(fixes), int(r.size),
                              factor, positions, cov, prof.gradient_per_s,
                              float(sigmas[1]) if d_ref is not None else float("nan"),
                              prof.reference_depth_m, float(np.sum(r * r)))


def refit_fix(fix: FixTdoas, speed_mps: float | LinearProfile, *, variance_factor: float = 1.0,
              max_iterations: int = 50) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A fix re-solved at a given speed (or :class:`LinearProfile`) from its start: (position
    (3,), covariance (3, 3)).

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
