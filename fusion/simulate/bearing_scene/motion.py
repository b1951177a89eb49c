"""Straight-line relative motions and the rejection sampler behind :mod:`fusion.simulate.bearings`.

Part of the bearing simulator: :class:`Motion` is a target's straight-line motion relative to
the platform (compass bearing and bearing rate at any time) and :class:`Builder` draws motions
under the scenario's constraints (crossing, near-miss and parallel pairs, free tracks).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import wrap_angle

__all__ = ["MAX_ATTEMPTS", "Builder", "Motion", "tangent", "unit"]

#: Attempts at placing one pair of tracks before giving up.
MAX_ATTEMPTS = 2000


@dataclass(frozen=True)
class Motion:
    """Straight-line relative motion ``D(t) = d0 + u t`` of a target about the platform."""

    d0: NDArray[np.float64]  # (2,) relative position at t = 0, m
    u: NDArray[np.float64]  # (2,) relative velocity, m/s

    def rel(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Relative positions, shape (len(t), 2), m."""
        return self.d0 + np.multiply.outer(np.asarray(t, dtype=float), self.u)

    def bearing(self, t: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Compass bearing, rad (unwrapped by arctan2 into (-pi, pi])."""
        d = self.rel(np.atleast_1d(t))
        return np.arctan2(d[:, 0], d[:, 1])

    def bearing_rate(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Bearing rate, rad/s: (Dy ux - Dx uy) / R^2 for theta = atan2(Dx, Dy)."""
        d = self.rel(t)
        return (d[:, 1] * self.u[0] - d[:, 0] * self.u[1]) / np.sum(d * d, axis=1)


def unit(theta: float) -> NDArray[np.float64]:
    """Unit vector of compass bearing `theta` (rad), (east, north)."""
    return np.array([np.sin(theta), np.cos(theta)])


def tangent(theta: float) -> NDArray[np.float64]:
    """d(unit)/d(theta): direction of increasing compass bearing."""
    return np.array([np.cos(theta), -np.sin(theta)])


class Builder:
    """Draws target motions under the scenario's constraints (rejection sampling)."""

    def __init__(
        self,
        rng: np.random.Generator,
        *,
        ownship_v: NDArray[np.float64],
        duration_s: float,
        range_m: tuple[float, float],
        target_speed_mps: tuple[float, float],
        min_range_m: float,
    ) -> None:
        self.rng = rng
        self.v_o = ownship_v
        self.duration_s = duration_s
        self.range_m = range_m
        self.speed = target_speed_mps
        self.min_range_m = min_range_m
        self.check_t = np.linspace(0.0, duration_s, 361)

    def random_velocity(self) -> NDArray[np.float64]:
        """A target velocity over ground, m/s, random heading and speed in range."""
        return self.rng.uniform(*self.speed) * unit(self.rng.uniform(0.0, 2 * np.pi))

    def motion(self, t_ref: float, theta: float, r: float, v: NDArray[np.float64]) -> Motion:
        """Motion that is at bearing `theta`, range `r` at `t_ref` with ground velocity `v`."""
        u = v - self.v_o
        return Motion(r * unit(theta) - u * t_ref, u)

    def plausible(self, m: Motion) -> bool:
        """Target keeps at least ``min_range_m`` from the platform over the whole scenario."""
        d = m.rel(self.check_t)
        return bool(np.min(np.hypot(d[:, 0], d[:, 1])) >= self.min_range_m)

    def speed_ok(self, m: Motion) -> bool:
        s = float(np.hypot(*(m.u + self.v_o)))
        return self.speed[0] * 0.5 <= s <= self.speed[1] * 1.5

    def free(self) -> Motion:
        for _ in range(MAX_ATTEMPTS):
            m = self.motion(
                self.duration_s / 2,
                self.rng.uniform(0.0, 2 * np.pi),
                self.rng.uniform(*self.range_m),
                self.random_velocity(),
            )
            if self.plausible(m):
                return m
        raise ValueError("could not place a free track; widen range_m or lower target speeds")

    def crossing(
        self,
        *,
        theta_c: float | None,
        min_rate_diff: float,
        window: tuple[float, float],
        rate_diff: float | None = None,
    ) -> tuple[Motion, Motion, float]:
        """Two motions whose bearings are equal at a random time in `window`.

        With `rate_diff` (rad/s, signed) the second motion's bearing rate at the crossing is the
        first one's plus `rate_diff`; otherwise both velocities are random and the rates differ
        by at least `min_rate_diff`.
        """
        if rate_diff is not None:
            return self._crossing_at_rate(theta_c=theta_c, rate_diff=rate_diff, window=window)
        for _ in range(MAX_ATTEMPTS):
            t_c = self.rng.uniform(*window)
            th = self.rng.uniform(0.0, 2 * np.pi) if theta_c is None else theta_c
            r_a = self.rng.uniform(*self.range_m)
            s = self.rng.uniform(0.5, 0.8) if self.rng.random() < 0.5 else self.rng.uniform(1.25, 2.0)
            a = self.motion(t_c, th, r_a, self.random_velocity())
            b = self.motion(t_c, th, s * r_a, self.random_velocity())
            rates = [m.bearing_rate(np.array([t_c]))[0] for m in (a, b)]
            if abs(rates[0] - rates[1]) < min_rate_diff:
                continue
            if self.plausible(a) and self.plausible(b):
                return a, b, t_c
        raise ValueError("could not place a crossing pair; lower min_crossing_rate_deg_per_min")

    def _crossing_at_rate(
        self, *, theta_c: float | None, rate_diff: float, window: tuple[float, float]
    ) -> tuple[Motion, Motion, float]:
        """Two motions crossing at a random time with bearing rates differing by `rate_diff`."""
        for _ in range(MAX_ATTEMPTS):
            t_c = self.rng.uniform(*window)
            th = self.rng.uniform(0.0, 2 * np.pi) if theta_c is None else theta_c
            r_a = self.rng.uniform(*self.range_m)
            a = self.motion(t_c, th, r_a, self.random_velocity())
            r_b = r_a * self.rng.uniform(0.3, 2.0)
            # Tangential relative speed of b = its bearing rate x range; radial part random.
            rate_b = a.bearing_rate(np.array([t_c]))[0] + rate_diff
            radial = self.rng.uniform(-self.speed[1], self.speed[1])
            u_b = rate_b * r_b * tangent(th) + radial * unit(th)
            b = Motion(r_b * unit(th) - u_b * t_c, u_b)
            if not (self.range_m[0] <= r_b <= self.range_m[1] and self.speed_ok(b)):
                continue
            if self.plausible(a) and self.plausible(b):
                return a, b, t_c
        raise ValueError(
            f"could not place a crossing pair at a rate difference of "
            f"{np.degrees(rate_diff) * 60.0:.3g} deg/min; widen range_m or target_speed_mps"
        )

    def near_miss(
        self, *, miss: tuple[float, float], window: tuple[float, float], grid: NDArray[np.float64]
    ) -> tuple[Motion, Motion]:
        """Two motions whose bearings come within `miss` (rad) of each other but never cross."""
        for _ in range(MAX_ATTEMPTS):
            t_m = self.rng.uniform(*window)
            th = self.rng.uniform(0.0, 2 * np.pi)
            r_a = self.rng.uniform(*self.range_m)
            a = self.motion(t_m, th, r_a, self.random_velocity())
            delta = self.rng.uniform(*miss) * self.rng.choice([-1.0, 1.0])
            r_b = r_a * self.rng.uniform(0.6, 1.6)
            th_b = th + delta
            # Same bearing rate as `a` at t_m: tangential relative speed = rate * range.
            rate_a = a.bearing_rate(np.array([t_m]))[0]
            radial = self.rng.uniform(-self.speed[1], self.speed[1])
            u_b = rate_a * r_b * tangent(th_b) + radial * unit(th_b)
            b = Motion(r_b * unit(th_b) - u_b * t_m, u_b)
            if not (self.speed_ok(b) and self.plausible(a) and self.plausible(b)):
                continue
            d = np.asarray(wrap_angle(b.bearing(grid) - a.bearing(grid)))
            if np.all(np.sign(d) == np.sign(delta)) and np.min(np.abs(d)) >= miss[0]:
                return a, b
        raise ValueError("could not place a near-miss pair; widen max_miss_deg")

    def parallel(self, *, offset: tuple[float, float]) -> tuple[Motion, Motion]:
        """Two motions with a constant bearing offset (one rotated about the platform)."""
        for _ in range(MAX_ATTEMPTS):
            a = self.free()
            alpha = self.rng.uniform(*offset) * self.rng.choice([-1.0, 1.0])
            s = self.rng.uniform(0.6, 1.6)
            # Clockwise rotation by alpha in (east, north) coordinates adds alpha to the bearing.
            rot = s * np.array([[np.cos(alpha), np.sin(alpha)], [-np.sin(alpha), np.cos(alpha)]])
            b = Motion(rot @ a.d0, rot @ a.u)
            if self.speed_ok(b) and self.plausible(b):
                return a, b
        raise ValueError("could not place a parallel pair; widen target_speed_mps")
