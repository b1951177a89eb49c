"""Data of bearings-only target motion analysis: the own-ship track and the estimated target track."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.target import target_bearing

__all__ = ["OwnshipTrack", "TmaResult"]


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
        Marginal covariance of each state, m^2, m^2/s, m^2/s^2, scaled by
        `covariance_scale`.
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
        Standard deviation of the final range along the line of sight divided by that range:
        the larger of the bearings' own Cramer-Rao bound and the graph's covariance, both
        scaled by `covariance_scale`.
    bearing_rms_deg : float
        RMS of the bearing residuals at the solution, deg.
    motion : str
        Target model used, ``"single"`` or ``"chain"`` (see :class:`BearingsOnlyTMA`).
    range_low, range_high : ndarray, shape (n,)
        Range interval at each time, m (:func:`~fusion.passive.tma.confidence.range_interval`
        of `covariances`, at the estimator's ``interval_level``).
    covariance_scale : float
        Factor applied to the graph's covariance to fit the residuals (1: none).
    residual_rho : float
        Lag-one autocorrelation of the bearing residuals.
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
    range_low: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    range_high: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    covariance_scale: float = 1.0
    residual_rho: float = 0.0

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


def _ranges(states: NDArray[np.float64], own: NDArray[np.float64]) -> NDArray[np.float64]:
    d = states[:, :2] - own
    return np.hypot(d[:, 0], d[:, 1])
