"""Physical assumptions of a varied click scenario (``fusion simulate clicks --vary``).

:data:`VARIED_RANGES` lists every range; :func:`varied_settings` draws one scenario's keyword
arguments of :func:`fusion.simulate.clicks.simulate_clicks` from it. Scalars (counts, floor,
profile, SNR, ...) are drawn here; per-sensor and per-whale values (heights above the floor,
reflection coefficients, survey errors, click shapes, levels, ICIs, close pairs) are drawn by
the simulator from the ranges passed on, and every drawn value is written into ``truth.json``.

Ranges (uniform unless marked; counts are integers, bounds included):

==============================  =====================  ============================================
name                            range                  drawn / meaning
==============================  =====================  ============================================
duration_s                      20 - 60 s              per scenario
n_sources                       1 - 5                  whales
n_sensors                       3 - 10                 hydrophones
snr_db                          15 - 35 dB             nominal click at 1 km over in-band noise
floor_depth_m                   500 - 2,000 m          under the array centre
floor_slope_deg                 0 - 5 deg              direction uniform 0-360 deg
height_above_floor_m            1 - 20 m               per sensor
sensor_spacing_m                500 - 6,000 m          log-uniform, median nearest neighbour
position_error_m                1 - 3 m                survey error sigma per axis
profile kind                    munk | thermocline     equally likely
munk c_axis / axis depth        1480-1500 m/s, 600-1300 m; scale = axis depth x 0.9-1.3,
munk surface excess             25-55 m/s over c_axis (sets epsilon)
thermocline c0 / gradient       1478-1492 m/s, 0.014-0.018 1/s below a warm layer of
excess / depth / width          15-45 m/s, 50-300 m, 30-150 m
surface_reflection_range        0.5 - 0.95             magnitude per sensor, sign inverted
bottom_reflection_db            -15 - -3 dB            per sensor; sign positive or random (1:1)
click_band_hz                   20 - 50 kHz            per whale: start, end (capped at 0.47 fs)
click_duration_s                150 - 400 us           per whale
source_level_spread_db          6 dB                   per whale uniform in +-6 dB
level_jitter_db                 1 - 3 dB               per click
ici_range_s                     0.2 - 1.0 s            per whale mean ICI
close_pair_probability          0.3                    a whale starts 20-100 m from another
n_interferers                   0 - 2                  broadband trains of other species
interferer_ici_s                0.05 - 1.0 s           log-uniform, per interferer
interferer_duration_s           20 - 80 us             per interferer
interferer_level_db             -6 - +6 dB             per interferer, re a nominal whale click
n_transients                    0 - 20                 impulsive false transients
echo                            both                   (``--echo`` chooses another)
==============================  =====================  ============================================
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["VARIED_GROUPS", "VARIED_RANGES", "varied_settings"]

#: Ranges of a varied click scenario (see the module docstring for how each is drawn).
VARIED_RANGES: dict[str, Any] = {
    "duration_s": (20.0, 60.0),
    "n_sources": (1, 5),
    "n_sensors": (3, 10),
    "snr_db": (15.0, 35.0),
    "floor_depth_m": (500.0, 2000.0),
    "floor_slope_deg": (0.0, 5.0),
    "floor_azimuth_deg": (0.0, 360.0),
    "height_above_floor_m": (1.0, 20.0),
    "sensor_spacing_m": (500.0, 6000.0),  # log-uniform
    "position_error_m": (1.0, 3.0),
    "profile_kinds": ("munk", "thermocline"),
    "munk_c_axis": (1480.0, 1500.0),
    "munk_axis_depth_m": (600.0, 1300.0),
    "munk_scale_ratio": (0.9, 1.3),  # scale_m / axis_depth_m
    "munk_surface_excess_mps": (25.0, 55.0),  # c(0) - c_axis; sets epsilon
    "thermocline_c0": (1478.0, 1492.0),
    "thermocline_gradient": (0.014, 0.018),
    "thermocline_excess": (15.0, 45.0),
    "thermocline_depth_m": (50.0, 300.0),
    "thermocline_width_m": (30.0, 150.0),
    "surface_reflection_range": (0.5, 0.95),
    "bottom_reflection_db": (-15.0, -3.0),
    "bottom_reflection_signs": ("positive", "random"),
    "click_band_hz": (20_000.0, 50_000.0),  # upper end capped at 0.47 fs
    "click_duration_s": (150e-6, 400e-6),
    "source_level_spread_db": 6.0,
    "level_jitter_db": (1.0, 3.0),
    "ici_range_s": (0.2, 1.0),
    "close_pair_probability": 0.3,
    "close_pair_distance_m": (20.0, 100.0),
    "n_interferers": (0, 2),
    "interferer_ici_s": (0.05, 1.0),  # log-uniform
    "interferer_duration_s": (20e-6, 80e-6),
    "interferer_level_db": (-6.0, 6.0),
    "n_transients": (0, 20),
    "echo": "both",
}


#: The varied settings by physical effect, for varying one effect at a time (``fusion simulate
#: clicks --vary-only``); every drawn setting belongs to exactly one group.
VARIED_GROUPS: dict[str, tuple[str, ...]] = {
    "counts": ("duration_s", "n_sources", "n_sensors", "snr_db"),
    "floor": ("echo", "floor_depth_m", "floor_slope_deg", "floor_azimuth_deg",
              "height_above_floor_m", "surface_reflection_range", "bottom_reflection_db",
              "bottom_reflection_sign"),
    "spacing": ("sensor_spacing_m", "close_pair_probability", "close_pair_distance_m"),
    "sound-speed": ("sound_speed_profile",),
    "survey": ("position_error_m",),
    "click-shape": ("click_band_hz", "click_duration_s", "source_level_spread_db",
                    "level_jitter_db", "ici_range_s"),
    "interferers": ("n_interferers", "interferer_ici_s", "interferer_duration_s",
                    "interferer_level_db", "n_transients"),
}


def varied_settings(seed: int, *, fs: float = 96_000.0,
                    only: tuple[str, ...] | None = None) -> dict[str, Any]:
    """Keyword arguments of :func:`~fusion.simulate.clicks.simulate_clicks` drawn from
    :data:`VARIED_RANGES`.

    Parameters
    ----------
    seed : int
        Scenario seed; the settings come from their own generator seeded by ``(seed, 3)``, so
        the scenario drawn with them from ``seed`` shares no random numbers with them.
    fs : float, optional
        Sample rate, Hz (caps the click band at ``0.47 fs``).
    only : tuple of str, optional
        Names of :data:`VARIED_GROUPS`: only their settings are returned (drawn as with all of
        them, so a group's values are the same alone or with the others); the rest keep the
        default scenario's.

    Returns
    -------
    dict
        ``seed`` and every option of the varied world (or of the groups `only`),
        JSON-serialisable.
    """
    if only is not None:
        unknown = sorted(set(only) - set(VARIED_GROUPS))
        if unknown:
            raise ValueError(f"unknown varied group(s) {', '.join(unknown)}; choose from "
                             f"{', '.join(VARIED_GROUPS)}")
        every = varied_settings(seed, fs=fs)
        keep = {k for g in only for k in VARIED_GROUPS[g]}
        return {"seed": every["seed"], **{k: v for k, v in every.items() if k in keep}}
    rng = np.random.default_rng([int(seed), 3])
    r = VARIED_RANGES

    def uni(name: str) -> float:
        return float(rng.uniform(*r[name]))

    def count(name: str) -> int:
        lo, hi = r[name]
        return int(rng.integers(int(lo), int(hi) + 1))

    kind = str(r["profile_kinds"][int(rng.integers(len(r["profile_kinds"])))])
    if kind == "munk":
        c_axis, axis = uni("munk_c_axis"), uni("munk_axis_depth_m")
        scale = axis * uni("munk_scale_ratio")
        eta0 = -2.0 * axis / scale  # eta at the surface
        epsilon = uni("munk_surface_excess_mps") / (c_axis * (eta0 + np.exp(-eta0) - 1.0))
        profile = {"kind": "munk", "c_axis": c_axis, "axis_depth_m": axis, "scale_m": scale,
                   "epsilon": float(epsilon)}
    else:
        profile = {"kind": "thermocline", "c0": uni("thermocline_c0"),
                   "gradient": uni("thermocline_gradient"), "excess": uni("thermocline_excess"),
                   "thermocline_depth_m": uni("thermocline_depth_m"),
                   "thermocline_width_m": uni("thermocline_width_m")}
    lo_sp, hi_sp = r["sensor_spacing_m"]
    lo_ici, hi_ici = r["interferer_ici_s"]
    band_lo, band_hi = r["click_band_hz"]
    return {
        "seed": int(seed),
        "duration_s": uni("duration_s"),
        "n_sources": count("n_sources"),
        "n_sensors": count("n_sensors"),
        "snr_db": uni("snr_db"),
        "n_transients": count("n_transients"),
        "level_jitter_db": uni("level_jitter_db"),
        "echo": r["echo"],
        "floor_depth_m": uni("floor_depth_m"),
        "floor_slope_deg": uni("floor_slope_deg"),
        "floor_azimuth_deg": uni("floor_azimuth_deg"),
        "height_above_floor_m": list(r["height_above_floor_m"]),
        "sensor_spacing_m": float(np.exp(rng.uniform(np.log(lo_sp), np.log(hi_sp)))),
        "sound_speed_profile": profile,
        "position_error_m": uni("position_error_m"),
        "surface_reflection_range": list(r["surface_reflection_range"]),
        "bottom_reflection_db": list(r["bottom_reflection_db"]),
        "bottom_reflection_sign": str(r["bottom_reflection_signs"][int(rng.integers(2))]),
        "click_band_hz": [band_lo, min(band_hi, 0.47 * fs)],
        "click_duration_s": list(r["click_duration_s"]),
        "source_level_spread_db": float(r["source_level_spread_db"]),
        "ici_range_s": list(r["ici_range_s"]),
        "close_pair_probability": float(r["close_pair_probability"]),
        "close_pair_distance_m": list(r["close_pair_distance_m"]),
        "n_interferers": count("n_interferers"),
        "interferer_ici_s": [lo_ici, hi_ici],
        "interferer_duration_s": list(r["interferer_duration_s"]),
        "interferer_level_db": list(r["interferer_level_db"]),
    }
