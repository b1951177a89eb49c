"""Manoeuvring vessel traffic around a fixed sensor (``fusion simulate bearings --traffic``).

Part of :mod:`fusion.simulate.bearings`. Unlike the straight-line scenarios, vessels here
turn, change speed, pass close to the sensor and cross other vessels' bearings again and again,
the physics a constant-velocity bearing model ignores:

- *transits* hold a course at 3-10 m/s with one or two course changes (10-60 deg at 0.3-2
  deg/s) and speed changes (x0.6-1.4 over 30-120 s);
- *close passes*: transits whose line passes 150-600 m from the sensor (bearing sweeps of
  up to 180 deg in a minute or two);
- *ferries* shuttle between two points 1-4 km apart near the sensor, turning 180 deg at each
  end after a short stop (the same bearings crossed in both directions);
- *loiterers* (fishing, pilot boats) circle or zigzag slowly, their bearings swinging back and
  forth (repeated crossings with everything nearby).

Positions are integrated on a fine grid (0.5 s) from heading and speed; bearings are those of
the positions seen from the sensor at the origin.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["TRAFFIC_RANGES", "traffic_positions"]

#: Ranges of the traffic scenario's draws (documented in the module notes).
TRAFFIC_RANGES = {
    "n_vessels": (14, 22),
    "duration_s": 3600.0,
    "sample_period_s": (5.0, 15.0),
    "noise_deg": (0.1, 0.8),
    "p_detect": (0.9, 1.0),
    "range_m": (500.0, 9000.0),
    "fractions": {"transit": 0.45, "close": 0.2, "ferry": 0.15, "loiter": 0.2},
}

_DT = 0.5


def _integrate(heading: NDArray[np.float64], speed: NDArray[np.float64],
               start: NDArray[np.float64]) -> NDArray[np.float64]:
    v = np.stack([np.sin(heading), np.cos(heading)], axis=1) * speed[:, None]
    return start + np.concatenate([[np.zeros(2)], np.cumsum(v[:-1] * _DT, axis=0)])


def _smooth_steps(rng: np.random.Generator, t: NDArray[np.float64], n: int, size: tuple,
                  rate: tuple[float, float]) -> NDArray[np.float64]:
    """Sum of `n` ramps: each changes the value by a draw from `size` at a rate from `rate`."""
    out = np.zeros(t.size)
    for _ in range(n):
        t0 = rng.uniform(0.1, 0.85) * t[-1]
        amount = rng.uniform(*size) * rng.choice([-1.0, 1.0])
        dur = abs(amount) / rng.uniform(*rate)
        out += amount * np.clip((t - t0) / dur, 0.0, 1.0)
    return out


def _transit(rng: np.random.Generator, t: NDArray[np.float64], close: bool) -> NDArray[np.float64]:
    speed0 = rng.uniform(3.0, 10.0)
    course = rng.uniform(0.0, 2.0 * np.pi)
    u = np.array([np.sin(course), np.cos(course)])
    normal = np.array([u[1], -u[0]])
    cpa = rng.uniform(150.0, 600.0) if close else rng.uniform(800.0, 6000.0)
    t_cpa = rng.uniform(0.15, 0.85) * t[-1]
    # straight-line start so that the unperturbed track passes `cpa` from the sensor at t_cpa
    start = cpa * rng.choice([-1.0, 1.0]) * normal - u * speed0 * t_cpa
    n_turns = 0 if close else int(rng.integers(1, 3))
    heading = course + _smooth_steps(rng, t, n_turns, (np.radians(10), np.radians(60)),
                                     (np.radians(0.3), np.radians(2.0)))
    speed = speed0 * (1.0 + _smooth_steps(rng, t, int(rng.integers(0, 2)), (0.1, 0.4),
                                          (0.4 / 120.0, 0.4 / 30.0)))
    return _integrate(heading, np.maximum(speed, 0.5), start)


def _ferry(rng: np.random.Generator, t: NDArray[np.float64]) -> NDArray[np.float64]:
    length = rng.uniform(1000.0, 4000.0)
    course = rng.uniform(0.0, 2.0 * np.pi)
    u = np.array([np.sin(course), np.cos(course)])
    normal = np.array([u[1], -u[0]])
    a = rng.uniform(300.0, 2500.0) * rng.choice([-1.0, 1.0]) * normal - u * length * rng.uniform(0.2, 0.8)
    speed = rng.uniform(4.0, 8.0)
    stop = rng.uniform(30.0, 120.0)
    leg = length / speed
    period = 2.0 * (leg + stop)
    phase = np.mod(t + rng.uniform(0.0, period), period)
    s = np.where(phase < leg, phase / leg, np.where(phase < leg + stop, 1.0,
                 np.where(phase < 2 * leg + stop, 1.0 - (phase - leg - stop) / leg, 0.0)))
    s = 0.5 - 0.5 * np.cos(np.pi * s)  # accelerate and slow down at the ends
    return a + np.outer(s * length, u)


def _loiter(rng: np.random.Generator, t: NDArray[np.float64]) -> NDArray[np.float64]:
    r = rng.uniform(800.0, 5000.0)
    th = rng.uniform(0.0, 2.0 * np.pi)
    centre = r * np.array([np.sin(th), np.cos(th)])
    speed = rng.uniform(1.0, 3.5)
    if rng.random() < 0.5:  # circles
        radius = rng.uniform(200.0, 900.0)
        omega = speed / radius * rng.choice([-1.0, 1.0])
        ph = rng.uniform(0.0, 2.0 * np.pi)
        drift = rng.normal(0.0, 0.3, 2)
        return centre + radius * np.stack([np.sin(omega * t + ph), np.cos(omega * t + ph)], 1) \
            + np.outer(t, drift)
    heading = rng.uniform(0.0, 2.0 * np.pi) + np.radians(70.0) * np.sign(
        np.sin(2.0 * np.pi * t / rng.uniform(300.0, 900.0)))  # zigzag legs
    heading = np.convolve(heading, np.ones(60) / 60.0, mode="same")  # turns of ~30 s
    heading[:30], heading[-30:] = heading[30], heading[-31]
    return _integrate(heading, np.full(t.size, speed), centre)


def traffic_positions(rng: np.random.Generator, n_vessels: int, duration_s: float
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64], list[str]]:
    """Fine time grid, vessel positions (n, m, 2) relative to the sensor (m) and their kinds."""
    t = np.arange(0.0, duration_s + _DT / 2, _DT)
    fr = TRAFFIC_RANGES["fractions"]
    kinds = list(rng.choice(list(fr), size=n_vessels, p=np.array(list(fr.values()))))
    pos = []
    for k in kinds:
        for _ in range(200):  # keep vessels out of the sensor's immediate vicinity
            if k == "transit" or k == "close":
                xy = _transit(rng, t, k == "close")
            elif k == "ferry":
                xy = _ferry(rng, t)
            else:
                xy = _loiter(rng, t)
            rng_m = np.hypot(xy[:, 0], xy[:, 1])
            if rng_m.min() >= 120.0:
                break
        pos.append(xy)
    return t, np.array(pos), [str(k) for k in kinds]
