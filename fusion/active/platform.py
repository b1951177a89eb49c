"""Platform-fixed returns: steady relative to a moving sensor, moving in the world.

A sensor on a moving platform (a radar on a ferry, a towed or hull-mounted sonar) sees returns
that belong to the platform rather than to the world: sidelobes of its own structure, multipath
off its hull, artefacts at a fixed range. Such a return keeps its position *relative to the
sensor* while the sensor moves, so in the world frame it moves with the platform, and the
stationary hold (:func:`fusion.active.lifecycle.stationary_hold`, a still object does not move)
lets its track through. :class:`PlatformTest` is the same motion test in the sensor's frame: a
tentative track whose own detections do not move relative to the sensor, over a stretch in which
the sensor itself moved significantly, is platform-fixed and is not confirmed.

Choices (the method text has a fixed receiver and says nothing of moving sensors)
-----------------------------------------------------------------------------------
- The sensor's position at each detection is read from the detections (``rcv_x, rcv_y`` of a
  bistatic detection, else ``own_x, own_y``: :func:`sensor_positions`); its heading is not
  known, so the sensor frame is the world's axes moved to the sensor (translation only).
- Both statistics are :func:`fusion.active.motion.motion_statistic` on the track's own
  detections with their own position covariances, at the confidence and with the speed floor
  of the stationary hold: "steady relative to the sensor" is the generalised least-squares
  velocity of ``p_i - s_i`` not significantly beyond ``min_speed_mps``; "the sensor moved" is
  the same statistic for the sensor positions ``s_i`` at the same times, judged against the
  same detection errors. The second condition is what makes the two frames distinguishable:
  when the sensor moved less than the detections' noise can resolve (or not at all, a fixed
  receiver), a return still in one frame is still in the other and the world-frame test
  already decides; the platform test then says nothing (None), so runs with fixed receivers
  behave exactly as without it.
- Nothing is tuned: the thresholds are the chi-square quantile of the motion test and the
  errors the tracker already uses for the detections.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from fusion.active.motion import MOTION_MIN_DETECTIONS, motion_statistic
from fusion.active.types import Ping

__all__ = ["SENSOR_COLUMNS", "PlatformTest", "sensor_positions"]

#: Column pairs that give the sensor's position at a detection, in order of preference.
SENSOR_COLUMNS: tuple[tuple[str, str], ...] = (("rcv_x", "rcv_y"), ("own_x", "own_y"))


def sensor_positions(ping: Ping) -> NDArray[np.float64]:
    """Position of the sensor (receiver) at each detection of a ping.

    Parameters
    ----------
    ping : Ping

    Returns
    -------
    ndarray, shape (n, 2)
        ``rcv_x, rcv_y`` when the ping has them, else ``own_x, own_y`` (the own-ship position
        of a monostatic sensor), m; NaN when it has neither.

    Examples
    --------
    >>> p = Ping(0, 0.0, [[10.0, 0.0]], {"own_x": [2.0], "own_y": [3.0]})
    >>> sensor_positions(p).tolist()
    [[2.0, 3.0]]
    """
    for cx, cy in SENSOR_COLUMNS:
        if cx in ping.clues and cy in ping.clues:
            return np.column_stack([ping.clues[cx], ping.clues[cy]])
    return np.full((ping.n, 2), np.nan)


class PlatformTest:
    """Is a track's return fixed to the moving sensor? Two motion tests on its own detections.

    Parameters
    ----------
    probability : float, optional
        Confidence of each motion test, in (0, 1) (default 0.999, as the stationary hold).
    min_detections : int, optional
        Fewest detections for a decision (default
        :data:`fusion.active.motion.MOTION_MIN_DETECTIONS`).
    min_speed_mps : float, optional
        Relative speeds up to this count as steady (default 0), m/s; the sensor counts as moving
        only beyond it too (:func:`fusion.active.motion.motion_statistic`).

    Examples
    --------
    A return 100 m east of a sensor that moves north at 5 m/s, 1-m errors:

    >>> rows = [[t, 100.0, 5.0 * t, 1.0, 0.0, 1.0, 0.0, 5.0 * t] for t in (0.0, 2.0, 4.0, 6.0)]
    >>> PlatformTest().fixed(rows)
    True
    """

    def __init__(self, *, probability: float = 0.999, min_detections: int = MOTION_MIN_DETECTIONS,
                 min_speed_mps: float = 0.0) -> None:
        if not 0.0 < probability < 1.0:
            raise ValueError(f"platform test probability must lie in (0, 1), got {probability!r}")
        if isinstance(min_detections, bool) or int(min_detections) != min_detections \
                or min_detections < 2:
            raise ValueError(f"min_detections must be an integer >= 2, got {min_detections!r}")
        if not np.isfinite(min_speed_mps) or min_speed_mps < 0:
            raise ValueError(f"min_speed_mps must be >= 0, got {min_speed_mps!r}")
        self.probability = float(probability)
        self.min_detections = int(min_detections)
        self.min_speed_mps = float(min_speed_mps)
        self.gate = float(chi2.ppf(self.probability, 2))

    def statistics(self, rows: Sequence[Sequence[float]]) -> tuple[float, float]:
        """Motion statistics of the return relative to the sensor and of the sensor.

        Parameters
        ----------
        rows : sequence of (time, x, y, R_xx, R_xy, R_yy, sensor_x, sensor_y)
            One per detection: time (s), position (m), position covariance (m^2), sensor
            position (m).

        Returns
        -------
        (float, float)
            ``q_relative``, ``q_sensor``: chi-square (2 degrees of freedom) statistics of
            :func:`fusion.active.motion.motion_statistic` for ``p_i - s_i`` and for
            ``s_i``, both with the detections' covariances.
        """
        seen = np.asarray(rows, dtype=float)
        if seen.ndim != 2 or seen.shape[1] < 8:
            raise ValueError("platform test: rows need time, x, y, R_xx, R_xy, R_yy, sensor_x, "
                             f"sensor_y; got shape {seen.shape}")
        cov = seen[:, [3, 4, 4, 5]].reshape(-1, 2, 2)
        sensor = seen[:, 6:8]
        q_rel = motion_statistic(seen[:, 0], seen[:, 1:3] - sensor, cov=cov,
                                 min_speed_mps=self.min_speed_mps)
        q_sensor = motion_statistic(seen[:, 0], sensor, cov=cov, min_speed_mps=self.min_speed_mps)
        return q_rel, q_sensor

    def fixed(self, rows: Sequence[Sequence[float]]) -> bool | None:
        """Decide from a track's detections.

        Parameters
        ----------
        rows : sequence of (time, x, y, R_xx, R_xy, R_yy, sensor_x, sensor_y)
            As in :meth:`statistics`.

        Returns
        -------
        bool or None
            True when the sensor moved significantly and the return did not move relative to
            it; False when both moved; None when the frames cannot be told apart (fewer than
            ``min_detections`` detections, a sensor position unknown, or a sensor that did not
            move significantly).
        """
        if len(rows) < self.min_detections:
            return None
        seen = np.asarray(rows, dtype=float)
        if seen.shape[1] < 8 or not np.all(np.isfinite(seen[:, 6:8])):
            return None
        q_rel, q_sensor = self.statistics(seen)
        if q_sensor <= self.gate:
            return None
        return bool(q_rel <= self.gate)
