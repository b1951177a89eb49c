"""Seeded bearing-time scenarios: targets in straight-line motion seen from a moving platform.

Each target moves in a straight line at constant speed; the platform (own ship) does too. The
true bearing of a target is the compass bearing from the platform to the target, so bearing
histories have the curvature of real bearing-time records (the bearing rate of a straight-line
relative motion is ``h / R(t)**2`` with ``h`` the constant relative angular momentum). The
scenario is built from pairs of tracks with known relations:

- *crossing pairs*: the second target is put on the first one's line of sight at a chosen time
  ``t_c`` at another range, with a different bearing rate, so the bearings cross at ``t_c``;
  some of them cross where the bearing wraps (north, 0/360 deg in files, or south, +-180 deg
  inside the library);
- *near-miss pairs*: the second target is put ``delta`` degrees off the first one's line of
  sight with the same bearing rate at that moment, so the bearings approach to about ``delta``
  and draw apart again without crossing (checked over the whole duration);
- *parallel pairs*: the second target's relative position is the first one's rotated about the
  platform by a fixed angle (and scaled in range), so the two bearing tracks keep an exactly
  constant offset (equal bearing rates at all times);
- *free tracks* fill the rest.

Every crossing between any two tracks (planned or not) is found from the true geometry and
listed in the ground truth; measurements are the true bearings plus Gaussian noise, sampled
every ``sample_period_s`` with detection probability ``p_detect``, plus optional uniformly
distributed detections of unknown origin (``track_id`` = -1).

Files (``write_scenario``): ``bearings.csv`` (``track_id,time,bearing_deg``, bearings in
[0, 360) deg clockwise from north), ``truth.json`` and ``truth_bearings.csv``. With
``vary=True`` the physical assumptions are drawn per scenario from :data:`VARIED_RANGES`
(:func:`varied_settings`) instead of the fixed defaults. With ``traffic=True``
(:func:`simulate_traffic`) the targets are manoeuvring vessels around a fixed sensor instead:
turns, speed changes, close passes, ferries and loiterers whose bearings cross again and again
(:data:`TRAFFIC_RANGES`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fusion._validation import check_positive
from fusion.io import write_json, write_table
from fusion.simulate.bearing_scene.motion import Builder, Motion, unit
from fusion.simulate.bearing_scene.traffic import TRAFFIC_RANGES, traffic_positions
from fusion.simulate.bearing_scene.truth import BearingScenario, TrueCrossing, find_true_crossings
from fusion.simulate.bearing_scene.varied import VARIED_RANGES, varied_settings

__all__ = [
    "TRAFFIC_RANGES",
    "VARIED_RANGES",
    "BearingScenario",
    "TrueCrossing",
    "find_true_crossings",
    "simulate_bearings",
    "simulate_traffic",
    "varied_settings",
    "write_scenario",
]

logger = logging.getLogger(__name__)


def _check_interval(name: str, lo_hi: tuple[float, float], *, positive: bool = True) -> None:
    lo, hi = lo_hi
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi or (positive and lo <= 0):
        raise ValueError(f"{name} must be an interval (lo, hi) with 0 < lo <= hi, got {lo_hi!r}")


def _draw_gaps(
    rng: np.random.Generator, n_tracks: int, duration_s: float, per_hour: float,
    length_s: tuple[float, float],
) -> list[tuple[int, float, float]]:
    """Measurement gaps ``(track, start, end)``: Poisson count per track, uniform start and length."""
    if per_hour <= 0:
        return []
    out = []
    for k in range(n_tracks):
        for _ in range(int(rng.poisson(per_hour * duration_s / 3600.0))):
            g0 = float(rng.uniform(0.0, duration_s))
            out.append((k, g0, g0 + float(rng.uniform(*length_s))))
    return out


def simulate_bearings(
    *,
    seed: int,
    n_tracks: int = 6,
    duration_s: float = 1800.0,
    sample_period_s: float = 10.0,
    noise_deg: float | Sequence[float] = 0.5,
    n_crossing_pairs: int = 2,
    n_wrap_crossings: int = 1,
    n_near_miss_pairs: int = 1,
    n_parallel_pairs: int = 0,
    p_detect: float = 1.0,
    clutter_rate: float = 0.0,
    ownship_speed_mps: float = 3.0,
    range_m: tuple[float, float] = (3000.0, 12000.0),
    target_speed_mps: tuple[float, float] = (2.0, 8.0),
    min_range_m: float = 1000.0,
    min_crossing_rate_deg_per_min: float = 1.5,
    miss_deg: tuple[float, float] = (3.0, 8.0),
    parallel_offset_deg: tuple[float, float] = (3.0, 15.0),
    event_window: tuple[float, float] = (0.2, 0.8),
    crossing_rate_deg_per_min: tuple[float, float] | None = None,
    gaps_per_hour: float = 0.0,
    gap_s: tuple[float, float] = (20.0, 120.0),
) -> BearingScenario:
    """Simulate bearing tracks with crossings, near misses and parallel tracks.

    Parameters
    ----------
    seed : int
        Seed of ``np.random.default_rng``; the same arguments give the same scenario.
    n_tracks : int, optional
        Number of tracks (at least ``2 * (n_crossing_pairs + n_near_miss_pairs +
        n_parallel_pairs)``; the rest are free tracks).
    duration_s : float, optional
        Scenario length, s.
    sample_period_s : float, optional
        Sample period K of the bearing measurements, s.
    noise_deg : float or sequence of float, optional
        Standard deviation of the Gaussian bearing noise, deg: one value for every track, or
        one per track (shape (n_tracks,)).
    n_crossing_pairs : int, optional
        Pairs built to cross once at a known time.
    n_wrap_crossings : int, optional
        How many of the crossing pairs cross where the bearing wraps, alternately at north
        (0/360 deg, the wrap of the files) and south (+-180 deg, the wrap of wrapped radians).
    n_near_miss_pairs : int, optional
        Pairs that approach within `miss_deg` and draw apart without crossing.
    n_parallel_pairs : int, optional
        Pairs with a constant bearing offset in `parallel_offset_deg` (equal rates).
    p_detect : float, optional
        Probability that a track is measured at a sample time, in (0, 1].
    clutter_rate : float, optional
        Mean number of detections of unknown origin (``track_id`` -1, bearing uniform) per
        sample time.
    ownship_speed_mps : float, optional
        Platform speed, m/s (straight line, random heading).
    range_m : (float, float), optional
        Range interval of targets at their reference time, m.
    target_speed_mps : (float, float), optional
        Target speed interval, m/s.
    min_range_m : float, optional
        Closest any target may come to the platform, m.
    min_crossing_rate_deg_per_min : float, optional
        Smallest difference of the two bearing rates at a planned crossing, deg/min.
    miss_deg : (float, float), optional
        Closest approach of near-miss pairs, deg.
    parallel_offset_deg : (float, float), optional
        Constant bearing offset of parallel pairs, deg.
    event_window : (float, float), optional
        Planned crossings and closest approaches happen in this fraction of the duration.
    crossing_rate_deg_per_min : (float, float), optional
        If given, each planned crossing pair's bearing-rate difference at its crossing is drawn
        log-uniformly in this interval (random sign), deg/min; otherwise both velocities are
        random, subject to `min_crossing_rate_deg_per_min`.
    gaps_per_hour : float, optional
        Mean number of measurement gaps per track per hour (Poisson; 0: none).
    gap_s : (float, float), optional
        Length interval of a gap, s (uniform).

    Returns
    -------
    BearingScenario

    Raises
    ------
    ValueError
        Bad counts, probabilities or intervals, or constraints that cannot be met.

    Notes
    -----
    Bearings are compass bearings ``atan2(dx, dy)`` from the platform; the bearing rate of a
    straight-line relative motion ``D(t) = D0 + u t`` is ``(D_y u_x - D_x u_y) / |D|^2``. True
    crossings are the zeros of the wrapped bearing difference, found on a grid of
    ``min(1, K / 4)`` s and refined with Brent's method (``find_true_crossings``); the +-180 deg
    jumps of the difference (targets on opposite bearings) are not crossings.

    Examples
    --------
    >>> sc = simulate_bearings(seed=1, n_tracks=6)
    >>> sc.bearing_deg.shape == sc.time.shape
    True
    """
    for name, v in (("n_tracks", n_tracks), ("n_crossing_pairs", n_crossing_pairs),
                    ("n_wrap_crossings", n_wrap_crossings), ("n_near_miss_pairs", n_near_miss_pairs),
                    ("n_parallel_pairs", n_parallel_pairs)):
        if int(v) != v or v < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {v!r}")
    if n_wrap_crossings > n_crossing_pairs:
        raise ValueError(
            f"n_wrap_crossings ({n_wrap_crossings}) must not exceed n_crossing_pairs "
            f"({n_crossing_pairs})"
        )
    n_planned = 2 * (n_crossing_pairs + n_near_miss_pairs + n_parallel_pairs)
    if n_tracks < max(n_planned, 1):
        raise ValueError(f"n_tracks ({n_tracks}) must be at least {max(n_planned, 1)} for the pairs asked")
    check_positive("duration_s", duration_s)
    check_positive("sample_period_s", sample_period_s)
    if sample_period_s > duration_s:
        raise ValueError("sample_period_s must not exceed duration_s")
    noise_arr = np.asarray(noise_deg, dtype=float)
    if noise_arr.ndim == 0:
        noise_arr = np.full(int(n_tracks), float(noise_arr))
    if noise_arr.shape != (int(n_tracks),):
        raise ValueError(f"noise_deg must be one number or one per track ({n_tracks}), "
                         f"got shape {noise_arr.shape}")
    if not np.all(np.isfinite(noise_arr) & (noise_arr >= 0)):
        raise ValueError(f"noise_deg must be finite and >= 0, got {noise_deg!r}")
    if crossing_rate_deg_per_min is not None:
        _check_interval("crossing_rate_deg_per_min", crossing_rate_deg_per_min)
    check_positive("gaps_per_hour", gaps_per_hour, allow_zero=True)
    _check_interval("gap_s", gap_s)
    if not 0.0 < p_detect <= 1.0:
        raise ValueError(f"p_detect must lie in (0, 1], got {p_detect!r}")
    check_positive("clutter_rate", clutter_rate, allow_zero=True)
    check_positive("ownship_speed_mps", ownship_speed_mps, allow_zero=True)
    check_positive("min_range_m", min_range_m)
    check_positive("min_crossing_rate_deg_per_min", min_crossing_rate_deg_per_min, allow_zero=True)
    _check_interval("range_m", range_m)
    _check_interval("target_speed_mps", target_speed_mps)
    _check_interval("miss_deg", miss_deg)
    _check_interval("parallel_offset_deg", parallel_offset_deg)
    if not 0.0 <= event_window[0] <= event_window[1] <= 1.0:
        raise ValueError(f"event_window must satisfy 0 <= lo <= hi <= 1, got {event_window!r}")

    rng = np.random.default_rng(seed)
    ownship_v = ownship_speed_mps * unit(rng.uniform(0.0, 2 * np.pi))
    builder = Builder(
        rng,
        ownship_v=ownship_v,
        duration_s=float(duration_s),
        range_m=range_m,
        target_speed_mps=target_speed_mps,
        min_range_m=min_range_m,
    )
    window = (event_window[0] * duration_s, event_window[1] * duration_s)
    step = min(1.0, sample_period_s / 4.0)
    fine = np.linspace(0.0, duration_s, int(np.ceil(duration_s / step)) + 1)

    motions: list[Motion] = []
    planned_cross: list[tuple[int, int]] = []
    planned_tc: list[TrueCrossing] = []
    near: list[tuple[int, int]] = []
    parallel: list[tuple[int, int]] = []
    wrap_bearings = (0.0, np.pi)
    for k in range(n_crossing_pairs):
        theta_c = None
        if k < n_wrap_crossings:
            theta_c = wrap_bearings[k % 2] + rng.uniform(-0.5, 0.5) * np.pi / 180.0
        rate_diff = None
        if crossing_rate_deg_per_min is not None:
            lo, hi = np.log(crossing_rate_deg_per_min)
            rate_diff = np.radians(np.exp(rng.uniform(lo, hi))) / 60.0 * rng.choice([-1.0, 1.0])
        a, b, t_c = builder.crossing(
            theta_c=theta_c,
            min_rate_diff=np.radians(min_crossing_rate_deg_per_min) / 60.0,
            window=window,
            rate_diff=rate_diff,
        )
        planned_cross.append((len(motions), len(motions) + 1))
        planned_tc.append(TrueCrossing(len(motions), len(motions) + 1, float(t_c)))
        motions += [a, b]
    for _ in range(n_near_miss_pairs):
        a, b = builder.near_miss(miss=tuple(np.radians(miss_deg)), window=window, grid=fine)
        near.append((len(motions), len(motions) + 1))
        motions += [a, b]
    for _ in range(n_parallel_pairs):
        a, b = builder.parallel(offset=tuple(np.radians(parallel_offset_deg)))
        parallel.append((len(motions), len(motions) + 1))
        motions += [a, b]
    while len(motions) < n_tracks:
        motions.append(builder.free())

    # Ground truth: every crossing of every pair.
    crossings = find_true_crossings(
        [m.bearing for m in motions], duration_s=float(duration_s), step_s=step
    )
    crossing_pairs = {(c.track_a, c.track_b) for c in crossings}
    all_pairs = [(a, b) for a in range(n_tracks) for b in range(a + 1, n_tracks)]
    non_crossing = tuple(p for p in all_pairs if p not in crossing_pairs)

    # Truth on the sample grid.
    n_t = int(np.floor(duration_s / sample_period_s + 1e-9)) + 1
    t_grid = np.arange(n_t) * float(sample_period_s)
    ownship_xy = np.multiply.outer(t_grid, ownship_v)
    rel = np.array([m.rel(t_grid) for m in motions])  # (n, n_t, 2)
    target_xy = rel + ownship_xy[None]
    truth_bearing = np.mod(np.degrees(np.arctan2(rel[..., 0], rel[..., 1])), 360.0)
    truth_rate = np.degrees(np.array([m.bearing_rate(t_grid) for m in motions]))

    # Measurements: detected rows plus clutter rows, sorted by (time, track_id).
    detected = rng.random((n_tracks, n_t)) < p_detect
    noise = rng.normal(0.0, 1.0, size=(n_tracks, n_t)) * noise_arr[:, None]
    gaps = _draw_gaps(rng, n_tracks, float(duration_s), gaps_per_hour, gap_s)
    for k, g0, g1 in gaps:
        detected[k, (t_grid >= g0) & (t_grid <= g1)] = False
    tid_grid = np.broadcast_to(np.arange(n_tracks)[:, None], (n_tracks, n_t))
    time_grid = np.broadcast_to(t_grid[None, :], (n_tracks, n_t))
    track_id = tid_grid[detected]
    time = time_grid[detected]
    true_b = truth_bearing[detected]
    meas_b = np.mod(true_b + noise[detected], 360.0)
    n_clutter = rng.poisson(clutter_rate, size=n_t) if clutter_rate > 0 else np.zeros(n_t, int)
    c_time = np.repeat(t_grid, n_clutter)
    c_b = rng.uniform(0.0, 360.0, size=c_time.size)
    track_id = np.concatenate([track_id, np.full(c_time.size, -1)]).astype(np.int64)
    time = np.concatenate([time, c_time])
    meas_b = np.concatenate([meas_b, c_b])
    true_b = np.concatenate([true_b, np.full(c_time.size, np.nan)])
    order = np.lexsort((track_id, time))
    logger.debug(
        "bearing scenario seed=%d: %d tracks, %d crossings, %d rows (%d clutter)",
        seed, n_tracks, len(crossings), order.size, c_time.size,
    )
    return BearingScenario(
        track_id=track_id[order],
        time=time[order],
        bearing_deg=meas_b[order],
        true_bearing_deg=true_b[order],
        track_ids=np.arange(n_tracks, dtype=np.int64),
        truth_time=t_grid,
        truth_bearing_deg=truth_bearing,
        truth_bearing_rate_deg_per_s=truth_rate,
        ownship_xy=ownship_xy,
        target_xy=target_xy,
        crossings=tuple(crossings),
        non_crossing_pairs=non_crossing,
        near_miss_pairs=tuple(near),
        parallel_pairs=tuple(parallel),
        planned_crossing_pairs=tuple(planned_cross),
        planned_crossings=tuple(planned_tc),
        sample_period_s=float(sample_period_s),
        noise_deg=float(np.median(noise_arr)),
        duration_s=float(duration_s),
        seed=int(seed),
        track_noise_deg=noise_arr,
        crossing_rate_diff_deg_per_min=tuple(
            float(np.degrees(motions[c.track_b].bearing_rate(np.array([c.t_cross]))[0]
                             - motions[c.track_a].bearing_rate(np.array([c.t_cross]))[0]) * 60.0)
            for c in crossings),
        gaps=tuple(gaps),
    )


def simulate_traffic(*, seed: int) -> BearingScenario:
    """Manoeuvring vessel traffic seen from a fixed sensor (draws from :data:`TRAFFIC_RANGES`).

    Parameters
    ----------
    seed : int
        Seed of ``np.random.default_rng``.

    Returns
    -------
    BearingScenario
        Measurements (true bearings plus per-track Gaussian noise, detection probability, no
        clutter), every true crossing and the bearing-rate difference at each.

    Notes
    -----
    Vessel kinds and motions are described in :mod:`fusion.simulate.bearing_scene.traffic`. The
    sensor sits at the origin (``ownship_xy`` zero). Nearly all vessels are in view the whole
    hour, so most pairs meet at least once and many more than once.
    """
    r = TRAFFIC_RANGES
    rng = np.random.default_rng(seed)
    n = int(rng.integers(r["n_vessels"][0], r["n_vessels"][1] + 1))
    duration = float(r["duration_s"])
    period = float(np.round(rng.uniform(*r["sample_period_s"])))
    noise = np.exp(rng.uniform(*np.log(r["noise_deg"]), size=n))
    p_detect = float(rng.uniform(*r["p_detect"]))
    t_fine, pos, _ = traffic_positions(rng, n, duration)
    theta = np.unwrap(np.arctan2(pos[..., 0], pos[..., 1]), axis=1)  # (n, m) rad
    rate = np.gradient(theta, t_fine, axis=1)

    def f(k: int):
        return lambda tt: np.interp(tt, t_fine, theta[k])

    crossings = find_true_crossings([f(k) for k in range(n)], duration_s=duration, step_s=1.0)
    crossing_pairs = {(c.track_a, c.track_b) for c in crossings}
    non_crossing = tuple((a, b) for a in range(n) for b in range(a + 1, n)
                         if (a, b) not in crossing_pairs)
    t_grid = np.arange(int(np.floor(duration / period + 1e-9)) + 1) * period
    tb = np.array([np.interp(t_grid, t_fine, theta[k]) for k in range(n)])
    truth_bearing = np.mod(np.degrees(tb), 360.0)
    truth_rate = np.degrees(np.array([np.interp(t_grid, t_fine, rate[k]) for k in range(n)]))
    detected = rng.random((n, t_grid.size)) < p_detect
    meas = np.mod(truth_bearing + rng.normal(0.0, 1.0, truth_bearing.shape) * noise[:, None],
                  360.0)
    tid = np.broadcast_to(np.arange(n)[:, None], detected.shape)[detected]
    time = np.broadcast_to(t_grid[None, :], detected.shape)[detected]
    order = np.lexsort((tid, time))
    target_xy = np.array([[np.interp(t_grid, t_fine, pos[k, :, j]) for j in range(2)]
                          for k in range(n)]).transpose(0, 2, 1)
    rate_diff = tuple(float(np.degrees(np.interp(c.t_cross, t_fine, rate[c.track_b])
                                       - np.interp(c.t_cross, t_fine, rate[c.track_a])) * 60.0)
                      for c in crossings)
    return BearingScenario(
        track_id=tid[order].astype(np.int64), time=time[order],
        bearing_deg=meas[detected][order], true_bearing_deg=truth_bearing[detected][order],
        track_ids=np.arange(n, dtype=np.int64), truth_time=t_grid,
        truth_bearing_deg=truth_bearing, truth_bearing_rate_deg_per_s=truth_rate,
        ownship_xy=np.zeros((t_grid.size, 2)), target_xy=target_xy,
        crossings=tuple(crossings), non_crossing_pairs=non_crossing, near_miss_pairs=(),
        parallel_pairs=(), planned_crossing_pairs=(), planned_crossings=(),
        sample_period_s=period, noise_deg=float(np.median(noise)), duration_s=duration,
        seed=int(seed), track_noise_deg=noise, crossing_rate_diff_deg_per_min=rate_diff,
        gaps=(),
    )


def write_scenario(out_dir: Path, *, seed: int, vary: bool = False,
                   traffic: bool = False) -> list[Path]:
    """Write a bearing scenario: ``bearings.csv``, ``truth.json``, ``truth_bearings.csv``.

    A scenario writer (:mod:`fusion.simulate`: `out_dir`, `seed`, the written files returned).

    Parameters
    ----------
    vary : bool, optional
        Draw the physical assumptions from :data:`VARIED_RANGES` (:func:`varied_settings`)
        instead of the fixed scenario below; ``truth.json`` then records them under
        ``settings``.
    traffic : bool, optional
        Manoeuvring vessel traffic around a fixed sensor (:func:`simulate_traffic`) instead;
        not with `vary`.

    Notes
    -----
    The fixed scenario has 8 tracks over 1800 s sampled every 10 s with 0.5 deg noise: two
    crossing pairs (one through north), a near-miss pair, a parallel pair and two free tracks,
    plus clutter (0.2 detections of unknown origin per sample time).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if vary and traffic:
        raise ValueError("--traffic draws its own settings: not with --vary")
    if traffic:
        settings = {"traffic": True}
        sc = simulate_traffic(seed=seed)
    elif vary:
        settings = varied_settings(seed)
        sc = simulate_bearings(**settings)
    else:
        settings = None
        sc = simulate_bearings(
            seed=seed, n_tracks=8, n_crossing_pairs=2, n_wrap_crossings=1, n_near_miss_pairs=1,
            n_parallel_pairs=1, clutter_rate=0.2,
        )
    paths = [
        write_table(
            out_dir / "bearings.csv",
            {"track_id": sc.track_id, "time": sc.time, "bearing_deg": sc.bearing_deg},
        ),
        write_table(
            out_dir / "truth_bearings.csv",
            {
                "track_id": np.repeat(sc.track_ids, sc.truth_time.size),
                "time": np.tile(sc.truth_time, sc.n_tracks),
                "bearing_deg": sc.truth_bearing_deg.ravel(),
                "bearing_rate_deg_per_min": 60.0 * sc.truth_bearing_rate_deg_per_s.ravel(),
            },
        ),
        write_json(
            out_dir / "truth.json",
            {
                "kind": "bearings",
                "seed": sc.seed,
                "sample_period_s": sc.sample_period_s,
                "noise_deg": sc.noise_deg,
                "duration_s": sc.duration_s,
                "track_ids": sc.track_ids,
                "crossings": [c._asdict() for c in sc.crossings],
                "planned_crossings": [c._asdict() for c in sc.planned_crossings],
                "near_miss_pairs": [list(p) for p in sc.near_miss_pairs],
                "parallel_pairs": [list(p) for p in sc.parallel_pairs],
                "non_crossing_pairs": [list(p) for p in sc.non_crossing_pairs],
                "crossing_rate_diff_deg_per_min": list(sc.crossing_rate_diff_deg_per_min),
                "track_noise_deg": sc.track_noise_deg,
                "gaps": [list(g) for g in sc.gaps],
                "truth_file": "truth_bearings.csv",
                **({"settings": settings} if settings is not None else {}),
            },
        ),
    ]
    return paths
