"""Seeded bearings-only TMA scenario: a manoeuvring own-ship and a constant-velocity target.

The own-ship steams a first leg, turns at a constant rate through a random course change and
steams a second leg (or keeps its course when ``manoeuvre=False``, the unobservable case). A
target a few kilometres away moves at a constant velocity. True bearings (clockwise from north)
of the target are sampled every ``period_s`` seconds with Gaussian noise.

Files (see the file-format notes, section 8): ``bearings.csv`` (``time,bearing_deg``),
``ownship.csv`` (``time,x,y``, every ``ownship_period_s``) and the truth ``truth.csv``
(``time,x,y,vx,vy,range`` of the target at the bearing times).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import wrap_angle
from fusion.io import write_table

__all__ = ["TmaScenario", "simulate_tma", "write_scenario"]


@dataclass(frozen=True)
class TmaScenario:
    """A simulated bearings-only TMA scenario.

    Attributes
    ----------
    times : ndarray, shape (n,)
        Bearing times, s.
    bearings : ndarray, shape (n,)
        Noisy true bearings, rad, clockwise from north, in ``[-pi, pi)``.
    truth : ndarray, shape (n, 4)
        Target ``[x, y, vx, vy]`` at the bearing times, m and m/s.
    ownship_times : ndarray, shape (m,)
        Own-ship sample times, s.
    ownship_xy : ndarray, shape (m, 2)
        Own-ship positions, m.
    bearing_sigma_deg : float
        Bearing noise standard deviation, deg.
    """

    times: NDArray[np.float64]
    bearings: NDArray[np.float64]
    truth: NDArray[np.float64]
    ownship_times: NDArray[np.float64]
    ownship_xy: NDArray[np.float64]
    bearing_sigma_deg: float

    @property
    def ownship_at_bearings(self) -> NDArray[np.float64]:
        """Own-ship positions at the bearing times, m, shape (n, 2)."""
        return np.column_stack(
            [
                np.interp(self.times, self.ownship_times, self.ownship_xy[:, 0]),
                np.interp(self.times, self.ownship_times, self.ownship_xy[:, 1]),
            ]
        )

    @property
    def true_range(self) -> NDArray[np.float64]:
        """True own-ship to target range at the bearing times, m, shape (n,)."""
        d = self.truth[:, :2] - self.ownship_at_bearings
        return np.hypot(d[:, 0], d[:, 1])


def simulate_tma(
    *,
    seed: int,
    duration_s: float = 1800.0,
    period_s: float = 20.0,
    bearing_sigma_deg: float = 1.0,
    manoeuvre: bool = True,
    ownship_speed_mps: float = 5.0,
    turn_rate_deg_s: float = 1.0,
    ownship_period_s: float = 5.0,
    range_m: tuple[float, float] = (3000.0, 8000.0),
    target_speed_mps: tuple[float, float] = (2.0, 8.0),
) -> TmaScenario:
    """Draw a TMA scenario.

    Parameters
    ----------
    seed : int, keyword-only
        Seed of ``np.random.default_rng``.
    duration_s : float, keyword-only
        Scenario length, s; the turn starts at half of it.
    period_s : float, keyword-only
        Bearing sample period, s.
    bearing_sigma_deg : float, keyword-only
        Bearing noise standard deviation, deg.
    manoeuvre : bool, keyword-only
        Course change of 60-120 deg (random side) at mid-scenario; ``False`` keeps a straight
        constant-speed track.
    ownship_speed_mps : float, keyword-only
        Own-ship speed, m/s.
    turn_rate_deg_s : float, keyword-only
        Own-ship turn rate, deg/s.
    ownship_period_s : float, keyword-only
        Own-ship position sample period, s.
    range_m : (float, float), keyword-only
        Interval of the initial target range, m.
    target_speed_mps : (float, float), keyword-only
        Interval of the target speed, m/s.

    Returns
    -------
    TmaScenario
    """
    positive = {"duration_s": duration_s, "period_s": period_s,
                "ownship_period_s": ownship_period_s, "turn_rate_deg_s": turn_rate_deg_s}
    for name, v in positive.items():
        if not np.isfinite(v) or v <= 0:
            raise ValueError(f"{name} must be finite and > 0, got {v!r}")
    if not np.isfinite(bearing_sigma_deg) or bearing_sigma_deg < 0:
        raise ValueError(f"bearing_sigma_deg must be finite and >= 0, got {bearing_sigma_deg!r}")
    rng = np.random.default_rng(seed)
    course0 = rng.uniform(0.0, 2 * np.pi)
    change = np.radians(rng.uniform(60.0, 120.0)) * rng.choice([-1.0, 1.0]) if manoeuvre else 0.0
    r0 = rng.uniform(*range_m)
    bearing0 = rng.uniform(0.0, 2 * np.pi)
    speed = rng.uniform(*target_speed_mps)
    course_t = rng.uniform(0.0, 2 * np.pi)

    # own-ship: integrate the course on a fine grid (1 s), constant-rate turn from mid-scenario
    fine_t = np.arange(0.0, duration_s + 1.0, 1.0)
    rate = np.radians(turn_rate_deg_s)
    t_turn = 0.5 * duration_s
    turned = np.clip((fine_t - t_turn) * rate, 0.0, abs(change)) * np.sign(change)
    course = course0 + turned
    vel = ownship_speed_mps * np.column_stack([np.sin(course), np.cos(course)])
    xy_fine = np.vstack([[0.0, 0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]), axis=0)])
    own_t = np.arange(0.0, duration_s + 1e-9, ownship_period_s)
    own_xy = np.column_stack(
        [np.interp(own_t, fine_t, xy_fine[:, 0]), np.interp(own_t, fine_t, xy_fine[:, 1])]
    )

    times = np.arange(0.0, duration_s + 1e-9, period_s)
    p0 = r0 * np.array([np.sin(bearing0), np.cos(bearing0)])
    v_t = speed * np.array([np.sin(course_t), np.cos(course_t)])
    truth = np.column_stack(
        [p0[0] + v_t[0] * times, p0[1] + v_t[1] * times,
         np.full_like(times, v_t[0]), np.full_like(times, v_t[1])]
    )
    own_b = np.column_stack(
        [np.interp(times, fine_t, xy_fine[:, 0]), np.interp(times, fine_t, xy_fine[:, 1])]
    )
    d = truth[:, :2] - own_b
    clean = np.arctan2(d[:, 0], d[:, 1])  # beta = atan2(dx, dy), clockwise from north
    noisy = wrap_angle(clean + rng.normal(0.0, np.radians(bearing_sigma_deg), times.size))
    return TmaScenario(
        times=times, bearings=np.asarray(noisy, dtype=float), truth=truth,
        ownship_times=own_t, ownship_xy=own_xy, bearing_sigma_deg=float(bearing_sigma_deg),
    )


def write_scenario(out_dir: Path, *, seed: int) -> list[Path]:
    """Write a TMA scenario: ``bearings.csv``, ``ownship.csv`` and ``truth.csv``.

    A scenario writer (:mod:`fusion.simulate`: `out_dir`, `seed`, the written files returned).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sc = simulate_tma(seed=seed)
    paths = [
        write_table(out_dir / "bearings.csv",
                    {"time": sc.times, "bearing_deg": np.degrees(sc.bearings)}),
        write_table(out_dir / "ownship.csv",
                    {"time": sc.ownship_times, "x": sc.ownship_xy[:, 0], "y": sc.ownship_xy[:, 1]}),
        write_table(out_dir / "truth.csv",
                    {"time": sc.times, "x": sc.truth[:, 0], "y": sc.truth[:, 1],
                     "vx": sc.truth[:, 2], "vy": sc.truth[:, 3], "range": sc.true_range}),
    ]
    return [Path(p) for p in paths]
