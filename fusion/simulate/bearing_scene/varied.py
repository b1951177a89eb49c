"""Physical assumptions of a varied bearing scenario (``fusion simulate bearings --vary``)."""

from __future__ import annotations

import numpy as np

__all__ = ["VARIED_RANGES", "varied_settings"]

#: Ranges of the physical assumptions of a varied scenario (:func:`varied_settings`). Scales
#: marked log-uniform in the comments are drawn uniformly in their logarithm; counts are integers
#: drawn uniformly, bounds included.
VARIED_RANGES: dict[str, tuple[float, float]] = {
    "sample_period_s": (1.0, 20.0),  # log-uniform, s
    "duration_s": (1800.0, 3600.0),  # s
    "n_crossing_pairs": (2, 4),
    "n_near_miss_pairs": (1, 2),
    "n_parallel_pairs": (0, 1),
    "n_free_tracks": (0, 3),
    "noise_deg": (0.2, 2.0),  # per track, log-uniform, deg
    "crossing_rate_deg_per_min": (0.3, 20.0),  # per planned crossing, log-uniform
    "miss_deg": (2.0, 8.0),  # closest approach of near misses, deg
    "gaps_per_hour": (0.0, 3.0),  # per track
    "gap_s": (10.0, 120.0),  # length of one gap, s
    "p_detect": (0.8, 1.0),
    "clutter_rate": (0.0, 0.5),  # detections of unknown origin per sample time
    "ownship_speed_mps": (0.0, 6.0),
    "target_speed_mps": (1.0, 10.0),
    "range_m": (1000.0, 15000.0),
}


def varied_settings(seed: int) -> dict:
    """Keyword arguments of :func:`simulate_bearings` drawn from :data:`VARIED_RANGES`.

    Parameters
    ----------
    seed : int
        Scenario seed; the settings come from their own generator seeded by ``(seed, 2)``, so the
        scenario drawn with them from ``seed`` does not share random numbers with them.

    Returns
    -------
    dict
        ``seed`` plus every option drawn: sample period, duration, track and pair counts
        (one wrap crossing in two scenarios), per-track noise, the interval of crossing rate
        differences, near-miss distance, gaps, detection probability, clutter, speeds and ranges.
    """
    rng = np.random.default_rng([int(seed), 2])
    r = VARIED_RANGES

    def log_uniform(lo_hi: tuple[float, float], size: int | None = None):
        return np.exp(rng.uniform(np.log(lo_hi[0]), np.log(lo_hi[1]), size))

    def count(name: str) -> int:
        lo, hi = r[name]
        return int(rng.integers(int(lo), int(hi) + 1))

    n_cross, n_near, n_par = count("n_crossing_pairs"), count("n_near_miss_pairs"), \
        count("n_parallel_pairs")
    n_tracks = 2 * (n_cross + n_near + n_par) + count("n_free_tracks")
    return {
        "seed": int(seed),
        "n_tracks": n_tracks,
        "n_crossing_pairs": n_cross,
        "n_wrap_crossings": int(rng.random() < 0.5),
        "n_near_miss_pairs": n_near,
        "n_parallel_pairs": n_par,
        "sample_period_s": float(log_uniform(r["sample_period_s"])),
        "duration_s": float(rng.uniform(*r["duration_s"])),
        "noise_deg": log_uniform(r["noise_deg"], n_tracks).tolist(),
        "crossing_rate_deg_per_min": r["crossing_rate_deg_per_min"],
        "miss_deg": r["miss_deg"],
        "gaps_per_hour": float(rng.uniform(*r["gaps_per_hour"])),
        "gap_s": r["gap_s"],
        "p_detect": float(rng.uniform(*r["p_detect"])),
        "clutter_rate": float(rng.uniform(*r["clutter_rate"])),
        "ownship_speed_mps": float(rng.uniform(*r["ownship_speed_mps"])),
        "target_speed_mps": r["target_speed_mps"],
        "range_m": r["range_m"],
        "min_range_m": 500.0,
    }
