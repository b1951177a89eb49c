"""The motion test of a tentative track: do its own detections move?

Used by track management (:mod:`fusion.active.lifecycle`: the hotspot drop and the stationary
hold) and by the platform test (:mod:`fusion.active.platform`). The generalised least-squares
velocity of a track's own associated detections (constant velocity, no process noise, each
detection with its own position covariance) is tested against zero, chi-square with 2 degrees of
freedom (:func:`motion_statistic`, :class:`MotionTest`); the module notes of
:mod:`fusion.active.lifecycle` give the reasons for this choice and its defaults.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

__all__ = ["MOTION_MIN_DETECTIONS", "STILL_WANDER_S", "MotionTest", "motion_statistic", "still_speed_mps"]

#: Detections a tentative track needs before its motion test may decide (with two, the
#: least-squares velocity has no residual and one bad association decides).
MOTION_MIN_DETECTIONS = 3

#: Time over which a still object's apparent position may wander by its own position error, s
#: (the speed floor of the motion test is ``position_sigma_m / STILL_WANDER_S``): 0.5 m/s at
#: the 125-m errors of the simulated multistatic sonar, ~0.01 m/s at a harbour radar's 3 m.
STILL_WANDER_S = 250.0


def still_speed_mps(position_sigma_m: float, wander_s: float = STILL_WANDER_S) -> float:
    """Speeds that count as standing still, from the position error: ``sigma / wander_s``.

    A still object's returns do not stand exactly still: a sea-floor feature seen from changing
    bistatic geometry, a moored boat swinging on its line, drift slowly by up to about their own
    position error. Stated as a speed, that wander scales with the sensor's error, so a fixed
    speed floor that suits sonar errors of 100-170 m (0.5 m/s) is 40-100 times what a 2-4 m
    radar or lidar needs, and there it holds a real 1-m/s boat for tens of scans
    (``docs/tracking.md``, "Speed floor of the motion test from the position error").

    Parameters
    ----------
    position_sigma_m : float
        Position error per axis, m (> 0).
    wander_s : float, optional
        Time over which a still object wanders by ``position_sigma_m``, s (> 0; default
        :data:`STILL_WANDER_S`).

    Returns
    -------
    float
        m/s.

    Examples
    --------
    >>> still_speed_mps(125.0), round(still_speed_mps(3.3), 4)
    (0.5, 0.0132)
    """
    if not (np.isfinite(position_sigma_m) and position_sigma_m > 0):
        raise ValueError(f"position_sigma_m must be > 0, got {position_sigma_m!r}")
    if not (np.isfinite(wander_s) and wander_s > 0):
        raise ValueError(f"still wander time must be > 0 s, got {wander_s!r}")
    return float(position_sigma_m) / float(wander_s)


def motion_statistic(
    times: ArrayLike, xy: ArrayLike, sigma_m: float | None = None, *, cov: ArrayLike | None = None,
    min_speed_mps: float = 0.0,
) -> float:
    """Chi-square statistic of "the detections move": least-squares velocity against zero.

    Parameters
    ----------
    times : array_like, shape (k,)
        Detection times, s.
    xy : array_like, shape (k, 2)
        Detection positions, m.
    sigma_m : float, optional
        Position error per axis, the same for every detection, m (> 0).
    cov : array_like, shape (k, 2, 2), optional
        Position covariance of each detection, m^2 (instead of ``sigma_m``), e.g. from
        :func:`fusion.active.bistatic.bistatic_covariance`.
    min_speed_mps : float, optional
        Speeds up to this count as standing still, m/s (>= 0, default 0): the estimated
        velocity is first shrunk towards zero by this much,
        ``v <- v max(0, 1 - min_speed_mps / |v|)``, so the statistic measures how far it lies
        beyond the disc of such speeds.

    Returns
    -------
    float
        ``v^T Cov(v)^-1 v`` for the generalised least-squares fit ``p_i = p_0 + v t_i + e_i``,
        ``e_i ~ N(0, C_i)``: chi-square with 2 degrees of freedom for a stationary object.
        With one ``sigma_m`` for all, ``|v|^2 S_tt / sigma^2`` with
        ``v = sum (t - t_mean)(p - p_mean) / S_tt`` and ``S_tt = sum (t - t_mean)^2``.
        0 when all times are equal.

    Examples
    --------
    >>> round(motion_statistic([0.0, 90.0, 180.0], [[0, 0], [180, 0], [360, 0]], 100.0), 2)
    6.48
    """
    if (sigma_m is None) == (cov is None):
        raise ValueError("give exactly one of sigma_m and cov")
    t = np.asarray(times, dtype=float)
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    tt = t - t.mean()
    stt = float(tt @ tt)
    if stt <= 0.0:
        return 0.0

    def shrink(v: NDArray[np.float64]) -> NDArray[np.float64]:
        speed = float(np.hypot(*v))
        return v * max(0.0, 1.0 - min_speed_mps / speed) if speed > 0 else v

    if cov is None:
        v = shrink(tt @ (p - p.mean(axis=0)) / stt)
        return float(v @ v) * stt / float(sigma_m) ** 2
    # Generalised least squares for theta = (p_0, v) with weights W_i = C_i^-1 (times centred).
    W = np.linalg.inv(np.asarray(cov, dtype=float).reshape(-1, 2, 2))
    A = np.empty((4, 4))
    A[:2, :2] = W.sum(axis=0)
    A[:2, 2:] = A[2:, :2] = np.einsum("i,ijk->jk", tt, W)
    A[2:, 2:] = np.einsum("i,ijk->jk", tt * tt, W)
    Wp = np.einsum("ijk,ik->ij", W, p)
    b = np.concatenate([Wp.sum(axis=0), tt @ Wp])
    try:
        theta = np.linalg.solve(A, b)
        cov_v = np.linalg.inv(A)[2:, 2:]
        v = shrink(theta[2:])
        return float(v @ np.linalg.solve(cov_v, v))
    except np.linalg.LinAlgError:
        return 0.0


class MotionTest:
    """Do a track's own detections move? :func:`motion_statistic` against a chi-square gate.

    Parameters
    ----------
    probability : float, optional
        Confidence of "moves", in (0, 1) (default 0.999): the statistic must exceed the
        chi-square quantile with 2 degrees of freedom.
    min_detections : int, optional
        Fewest detections for a decision (default :data:`MOTION_MIN_DETECTIONS`).
    min_speed_mps : float, optional
        Speeds up to this count as standing still (default 0), m/s; see
        :func:`motion_statistic`.

    Examples
    --------
    >>> rows = [[0.0, 0.0, 0.0, 1e4, 0.0, 1e4], [90.0, 180.0, 0.0, 1e4, 0.0, 1e4],
    ...         [180.0, 360.0, 0.0, 1e4, 0.0, 1e4]]
    >>> MotionTest(probability=0.95).moves(rows)
    True
    """

    def __init__(self, *, probability: float = 0.999,
                 min_detections: int = MOTION_MIN_DETECTIONS,
                 min_speed_mps: float = 0.0, recent: bool = False) -> None:
        if not 0.0 < probability < 1.0:
            raise ValueError(f"motion_probability must lie in (0, 1), got {probability!r}")
        if min_detections < 2:
            raise ValueError(f"min_detections must be >= 2, got {min_detections!r}")
        self.probability = float(probability)
        if not np.isfinite(min_speed_mps) or min_speed_mps < 0:
            raise ValueError(f"min_speed_mps must be >= 0, got {min_speed_mps!r}")
        self.min_detections = int(min_detections)
        self.min_speed_mps = float(min_speed_mps)
        self.recent = bool(recent)
        self.gate = float(chi2.ppf(self.probability, 2))

    def moves(self, rows: Sequence[Sequence[float]]) -> bool | None:
        """Decide from a track's detections.

        Parameters
        ----------
        rows : sequence of (time, x, y, R_xx, R_xy, R_yy)
            One per detection: time (s), position (m), position covariance (m^2).

        Returns
        -------
        bool or None
            True when the statistic exceeds the gate, False when it does not, None with fewer
            than ``min_detections`` detections.
        """
        if len(rows) < self.min_detections:
            return None
        seen = np.asarray(rows)
        cov = seen[:, [3, 4, 4, 5]].reshape(-1, 2, 2)
        if motion_statistic(seen[:, 0], seen[:, 1:3], cov=cov,
                            min_speed_mps=self.min_speed_mps) > self.gate:
            return True
        half = len(rows) // 2
        if not self.recent or half < self.min_detections:
            return False
        return bool(motion_statistic(seen[half:, 0], seen[half:, 1:3], cov=cov[half:],
                                     min_speed_mps=self.min_speed_mps) > self.gate)
