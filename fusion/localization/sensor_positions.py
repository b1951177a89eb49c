"""Sensor positions of a recording refined from its fixes: an array's self-calibration.

An array file's positions are surveyed, a few metres off the true ones; every delay involving
a sensor is then off by the error over the speed (2 m: 1.3 ms, a thousand times a TDOA's
sigma), and the fixes of a recording move with it. One fix cannot tell a sensor's error from
its own position, but the fixes of a whale that moves across the range can: a sensor's error is
shared by all of them and bends their delays differently from each position.

:func:`estimate_sensor_positions` extends the recording's sound-speed graph
(:mod:`fusion.localization.sound_speed`) by a ``Point3`` offset per real sensor from its
surveyed position, with a zero-mean prior of the user's standard deviation
(:mod:`factors.tdoa.sensors`). The priors also hold the gauge: a translation or rotation of the
whole array with every fix, or its scale with the speed, leaves every delay unchanged, and only
the priors (the survey) pin them. Like the speed, it is solved by least squares and then with a
per-TDOA Huber kernel; the offsets' standard deviations come from the marginal covariance
scaled by the a-posteriori variance factor.

:func:`position_f` is the test of whether the refined positions are used: the drop of the
residuals' chi-square against the same graph without offsets, per offset parameter, over the
residual variance -- an F statistic of the nested models.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (14): the model delay of a TDOA with the
sensor positions ``s_i``, ``s_j`` unknowns beside the source and the speed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import NDArray

from factors.tdoa.sensors import sensor_offset_tdoa_factor
from fusion.localization.sound_speed import (
    HUBER_K,
    POSITION_PRIOR_M,
    PRIOR_SIGMA_MPS,
    FixTdoas,
    LinearProfile,
    SoundSpeedEstimate,
    add_speed_prior,
    fix_residuals,
    refit_fix,
)

__all__ = ["SensorPositionEstimate", "estimate_sensor_positions", "held_out_chi2", "position_f",
           "shifted"]

_MIRROR = np.array([1.0, 1.0, -1.0])
#: Folds of the held-out check (:func:`held_out_chi2`); fewer fixes: one fold each.
HELD_OUT_FOLDS = 5
#: Prior sigma of the offsets that pins them at the survey in the held-out check's
#: comparison graph, m.
PINNED_M = 1e-4


def shifted(fix: FixTdoas, offsets: NDArray[np.float64]) -> FixTdoas:
    """`fix` with its real sensors moved by `offsets` (n_real, 3) and images by their mirror."""
    n = offsets.shape[0]
    rows = np.arange(fix.sensors.shape[0])
    move = np.where((rows >= n)[:, None], _MIRROR, 1.0) * offsets[rows % n]
    return FixTdoas(fix.sensors + move, fix.pairs, fix.taus, fix.sigmas, fix.weights,
                    fix.position)


def _chi2(fixes: Sequence[FixTdoas], positions: NDArray, prof: LinearProfile) -> float:
    r = np.concatenate([np.sqrt(np.maximum(f.weights, 0.0)) * fix_residuals(f, p, prof)
                        / f.sigmas for f, p in zip(fixes, positions, strict=True)])
    return float(np.sum(r * r))


@dataclass(frozen=True)
class SensorPositionEstimate:
    """Sensor offsets from the survey, and the speed and fixes estimated with them.

    Attributes
    ----------
    offsets : ndarray, shape (n, 3)
        Each real sensor's offset from its surveyed position, m.
    sigmas : ndarray, shape (n, 3)
        Their standard deviations per axis, m.
    speed : SoundSpeedEstimate
        The speed (or profile) and the fixes estimated jointly with the offsets.
    sigma_m : float
        The prior standard deviation of the offsets, m.
    n_determined : float
        How many of the ``3 n`` offset parameters the fixes determine: ``3 n - tr(C) / M^2``,
        ``C`` the offsets' posterior covariance (the fixes and the speed free beside them, so
        the directions they absorb -- the gauge, a whale's own position -- count nothing) and
        ``M`` the prior sigma; each direction counts from 0 (the prior alone) to 1 (the data
        alone).
    """

    offsets: NDArray[np.float64]
    sigmas: NDArray[np.float64]
    speed: SoundSpeedEstimate
    sigma_m: float
    n_determined: float = float("nan")

    def positions(self, surveyed: NDArray[np.float64]) -> NDArray[np.float64]:
        """The refined positions, m."""
        return np.asarray(surveyed, dtype=float) + self.offsets

    def to_dict(self, surveyed: NDArray[np.float64]) -> dict:
        """JSON-ready: refined positions, their sigmas and offsets per sensor."""
        pos = self.positions(surveyed)
        return {"prior_sigma_m": self.sigma_m, "sensors": [
            {"x": float(p[0]), "y": float(p[1]), "z": float(p[2]),
             "sigma_m": [float(v) for v in s], "offset_m": [float(v) for v in o]}
            for p, s, o in zip(pos, self.sigmas, self.offsets, strict=True)]}


def estimate_sensor_positions(fixes: Sequence[FixTdoas], *, n_real: int, nominal_mps: float,
                              sigma_m: float, d_ref: float | None = None,
                              prior_sigma_mps: float = PRIOR_SIGMA_MPS,
                              max_iterations: int = 100, covariance: bool = True
                              ) -> SensorPositionEstimate:
    """The sensors' offsets, the speed and the fixes of `fixes` on one graph.

    Parameters
    ----------
    fixes : sequence of FixTdoas
        Each fix's TDOAs on the surveyed sensors (rows ``0..n_real-1``) and their images.
    n_real : int
        Number of real sensors.
    nominal_mps : float
        The array file's speed (prior mean and start), m/s.
    sigma_m : float
        Prior standard deviation of each offset per axis, m (> 0).
    d_ref : float, optional
        With it the speed is the linear profile ``[c_ref, g]`` about this depth (m), prior
        on ``g`` as :func:`fusion.localization.sound_speed.estimate_sound_speed`'s.
    covariance : bool
        False: the solution alone (sigmas NaN, ``n_determined`` NaN), as the held-out check
        needs.
    """
    if not sigma_m > 0:
        raise ValueError("the sensor position sigma must be positive")
    ckey = gtsam.symbol("c", 0)
    okeys = [gtsam.symbol("o", q) for q in range(n_real)]
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    add_speed_prior(graph, values, ckey, nominal_mps, prior_sigma_mps, d_ref)
    off_prior = gtsam.noiseModel.Isotropic.Sigma(3, sigma_m)
    for k in okeys:
        graph.add(gtsam.PriorFactorPoint3(k, gtsam.Point3(0.0, 0.0, 0.0), off_prior))
        values.insert(k, gtsam.Point3(0.0, 0.0, 0.0))
    pos_prior = gtsam.noiseModel.Isotropic.Sigma(3, POSITION_PRIOR_M)
    for k, fix in enumerate(fixes):
        key = gtsam.symbol("x", k)
        graph.add(gtsam.PriorFactorPoint3(key, gtsam.Point3(*fix.position), pos_prior))
        values.insert(key, gtsam.Point3(*fix.position))
    plain = gtsam.NonlinearFactorGraph(graph)
    kernel = gtsam.noiseModel.mEstimator.Huber.Create(HUBER_K)
    for k, fix in enumerate(fixes):
        args = (gtsam.noiseModel.Diagonal.Sigmas(fix.sigmas), gtsam.symbol("x", k), ckey,
                okeys, fix.sensors, fix.pairs, fix.taus)
        kw = {"n_real": n_real, "d_ref": 0.0 if d_ref is None else d_ref,
              "weights": np.array(fix.weights)}
        plain.add(sensor_offset_tdoa_factor(*args, **kw))
        graph.add(sensor_offset_tdoa_factor(*args, **kw, robust=kernel))
    result = _optimize(graph, _optimize(plain, values, max_iterations), max_iterations)
    v = np.asarray(result.atVector(ckey), dtype=float)
    prof = LinearProfile(float(v[0])) if d_ref is None else LinearProfile(
        float(v[0]), float(v[1]), d_ref)
    offsets = np.array([result.atPoint3(k) for k in okeys], dtype=float)
    positions = np.array([result.atPoint3(gtsam.symbol("x", k)) for k in range(len(fixes))])
    moved = [shifted(f, offsets) for f in fixes]
    chi2 = _chi2(moved, positions, prof)
    m = sum(f.m for f in fixes)
    dof = max(1, m - 3 * len(fixes) - v.size)
    factor = max(1.0, chi2 / dof)
    if not covariance:
        nan = np.full((len(fixes), 3, 3), np.nan)
        speed = SoundSpeedEstimate(
            float(nominal_mps), prof.speed_mps, float("nan"), len(fixes), m, factor, positions,
            nan, prof.gradient_per_s, float("nan"), prof.reference_depth_m, chi2)
        return SensorPositionEstimate(offsets, np.full((n_real, 3), np.nan), speed,
                                      float(sigma_m))
    keys = [ckey, *okeys, *(gtsam.symbol("x", k) for k in range(len(fixes)))]
    raw = _covariance(graph, result, keys)
    cov_all = raw * factor
    nc = v.size
    n_det = float(3 * n_real - np.trace(raw[nc:nc + 3 * n_real, nc:nc + 3 * n_real])
                  / sigma_m ** 2)
    csig = np.sqrt(np.diag(cov_all[:nc, :nc]))
    osig = np.sqrt(np.diag(cov_all)[nc:nc + 3 * n_real]).reshape(n_real, 3)
    x0 = nc + 3 * n_real
    cov = np.array([cov_all[x0 + 3 * k:x0 + 3 * k + 3, x0 + 3 * k:x0 + 3 * k + 3]
                    for k in range(len(fixes))])
    speed = SoundSpeedEstimate(
        float(nominal_mps), prof.speed_mps, float(csig[0]), len(fixes), m, factor, positions,
        cov, prof.gradient_per_s, float(csig[1]) if d_ref is not None else float("nan"),
        prof.reference_depth_m, chi2)
    return SensorPositionEstimate(offsets, osig, speed, float(sigma_m), n_det)


def _covariance(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values,
                keys: list[int]) -> NDArray[np.float64]:
    """The joint covariance of `keys` (in their order) at `values`: the inverse of the dense
    Hessian, equilibrated first (metres and seconds and 1/s differ by orders that gtsam's
    Cholesky of :class:`gtsam.Marginals` takes for an indeterminate system)."""
    h, _ = graph.linearize(values).hessian(gtsam.Ordering(keys))
    d = 1.0 / np.sqrt(np.maximum(np.diag(h), 1e-300))
    return d[:, None] * np.linalg.pinv(d[:, None] * h * d[None, :], hermitian=True) * d[None, :]


def position_f(est: SensorPositionEstimate, without: SoundSpeedEstimate) -> float:
    """F statistic of the offsets: the drop of the chi-square from `without` (the same
    fixes and speed model, surveyed positions) per offset parameter the fixes determine
    (:attr:`SensorPositionEstimate.n_determined`; ``3 n`` when it was not computed), over the
    residual variance with the offsets (at least 1: the TDOA sigmas' own scale).

    Counting every offset as a parameter (``3 n``) divided the drop by 15 for five sensors
    where the fixes of one whale determine 1-2 combinations (the rest is the gauge, the
    whale's own positions and the prior)."""
    q = est.n_determined if np.isfinite(est.n_determined) else float(est.offsets.size)
    q = max(q, 1e-3)
    dof = max(1.0, est.speed.n_tdoas - 3 * est.speed.n_fixes - q)
    return (without.chi2 - est.speed.chi2) / q / max(est.speed.chi2 / dof, 1.0)


def held_out_chi2(fixes: Sequence[FixTdoas], *, n_real: int, nominal_mps: float,
                  sigma_m: float, d_ref: float | None = None, folds: int = HELD_OUT_FOLDS
                  ) -> tuple[float, float]:
    """The offsets checked on fixes they were not fitted to: ``(with, without)``.

    The fixes (in recording order) are dealt into ``min(folds, len(fixes))`` folds; for each
    fold the speed model (one speed, or the linear profile about `d_ref`) is fitted on the
    other folds twice -- with offsets (prior `sigma_m`) and with them pinned at the survey
    (prior :data:`PINNED_M`) -- and every fix of the fold is re-solved (its own position free)
    at each; the sums of their whitened chi-squares are returned. A sensor's survey error is
    shared by every fix, so offsets fitted to some fixes explain the others' delays too;
    offsets that absorbed what one fix's delays alone hold (a whale that moved within its
    window, a misread path, noise) do not.
    """
    k_folds = min(int(folds), len(fixes))
    if k_folds < 2:
        raise ValueError("the held-out check needs at least two fixes")
    with_, without = 0.0, 0.0
    for k in range(k_folds):
        train = [f for q, f in enumerate(fixes) if q % k_folds != k]
        test = [f for q, f in enumerate(fixes) if q % k_folds == k]
        for sig, free in ((sigma_m, True), (PINNED_M, False)):
            est = estimate_sensor_positions(train, n_real=n_real, nominal_mps=nominal_mps,
                                            sigma_m=sig, d_ref=d_ref, covariance=False)
            for f in test:
                moved = shifted(f, est.offsets) if free else f
                p, _ = refit_fix(moved, est.speed.profile)
                chi2 = _chi2([moved], p[None, :], est.speed.profile)
                if free:
                    with_ += chi2
                else:
                    without += chi2
    return with_, without


def _optimize(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values,
              max_iterations: int) -> gtsam.Values:
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    params.setRelativeErrorTol(1e-8)  # the offsets to millimetres: far below their sigmas
    return gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
