"""Checks of the click simulator's options (:func:`fusion.simulate.clicks.simulate_clicks`):
one ValueError naming the first option out of range."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["validate_options", "validate_range_options"]

ECHO_CHOICES = ("none", "surface", "bottom", "both")
#: Limits of the sensor and whale counts.
MAX_SENSORS, MAX_SOURCES = 10, 5


def validate_options(**o: Any) -> None:
    """ValueError naming the first option of the default physics out of range."""
    def finite_pos(name: str) -> None:
        v = o[name]
        if isinstance(v, bool) or not np.isfinite(v) or v <= 0:
            raise ValueError(f"{name} must be a positive number, got {v!r}")

    def rng_pair(name: str, lo_min: float = 0.0) -> None:
        v = o[name]
        if len(v) != 2 or not all(np.isfinite(x) for x in v) or not lo_min <= v[0] <= v[1]:
            raise ValueError(f"{name} must be (low, high) with {lo_min} <= low <= high, got {v!r}")

    for name, lo, hi in (("n_sensors", 3, MAX_SENSORS), ("n_sources", 1, MAX_SOURCES)):
        v = o[name]
        if isinstance(v, bool) or int(v) != v or not lo <= v <= hi:
            raise ValueError(f"{name} must be an integer from {lo} to {hi}, got {v!r}")
    n_tr = o["n_transients"]
    if isinstance(n_tr, bool) or int(n_tr) != n_tr or n_tr < 0:
        raise ValueError(f"n_transients must be a non-negative integer, got {n_tr!r}")
    for name in ("duration_s", "fs", "sound_speed", "array_radius_m", "reference_range_m",
                 "ici_s"):
        if not (name == "sound_speed" and o[name] is None):
            finite_pos(name)
    if np.isnan(o["snr_db"]) or o["snr_db"] == -np.inf:
        raise ValueError(f"snr_db must be a number or +inf, got {o['snr_db']!r}")
    for name in ("absorption_db_per_km", "ici_jitter_s", "level_jitter_db", "max_turn_rate_deg_s"):
        v = o[name]
        if not np.isfinite(v) or v < 0:
            raise ValueError(f"{name} must be >= 0, got {v!r}")
    if not np.isfinite(o["surface_reflection"]) or abs(o["surface_reflection"]) > 1:
        raise ValueError(f"surface_reflection must be in [-1, 1], got {o['surface_reflection']!r}")
    for name in ("noise_band_hz", "speed_range_mps", "depth_range_m"):
        rng_pair(name)
    rng_pair("transient_amplitude_range", 1e-12)
    click = o["click"]
    f_lo, f_hi = o["noise_band_hz"]
    nyq = 0.5 * o["fs"]
    if click.f_end_hz >= nyq or f_hi >= nyq:
        raise ValueError(
            f"fs={o['fs']} Hz is too low: the click band ends at {click.f_end_hz} Hz and the "
            f"noise band at {f_hi} Hz, both must stay below fs/2"
        )
    if min(f_hi, click.f_end_hz) - max(f_lo, click.f_start_hz) <= 0:
        raise ValueError(f"noise_band_hz {o['noise_band_hz']} does not overlap the click band")


def validate_range_options(o: dict[str, Any], *, fs: float, n_sources: int) -> None:
    """ValueError naming the first range option out of range (None values are skipped)."""

    def given(name: str) -> bool:
        return o.get(name) is not None

    def number(name: str, lo: float, hi: float) -> None:
        v = o[name]
        if given(name) and (isinstance(v, bool) or not np.isfinite(v) or not lo <= v <= hi):
            raise ValueError(f"{name} must be a number in [{lo:g}, {hi:g}], got {v!r}")

    def pair(name: str, lo: float, hi: float) -> None:
        v = o[name]
        if not given(name):
            return
        ok = len(v) == 2 and all(np.isfinite(x) for x in v) and lo <= v[0] <= v[1] <= hi
        if not ok:
            raise ValueError(f"{name} must be (low, high) with {lo:g} <= low <= high <= {hi:g}, "
                             f"got {v!r}")

    if given("echo") and o["echo"] not in ECHO_CHOICES:
        raise ValueError(f"echo must be one of {', '.join(ECHO_CHOICES)}, got {o['echo']!r}")
    number("floor_depth_m", 50.0, 11_000.0)
    number("floor_slope_deg", 0.0, 30.0)
    number("floor_azimuth_deg", -360.0, 360.0)
    pair("height_above_floor_m", 0.0, 1000.0)
    number("sensor_spacing_m", 10.0, 50_000.0)
    number("position_error_m", 0.0, 100.0)
    number("nominal_sound_speed", 1300.0, 1700.0)
    pair("surface_reflection_range", 0.0, 1.0)
    pair("bottom_reflection_db", -80.0, 0.0)
    if given("bottom_reflection_sign") and o["bottom_reflection_sign"] not in ("positive", "random"):
        raise ValueError("bottom_reflection_sign must be 'positive' or 'random', "
                         f"got {o['bottom_reflection_sign']!r}")
    pair("click_band_hz", 1_000.0, 0.5 * fs)
    if given("click_band_hz") and o["click_band_hz"][1] - o["click_band_hz"][0] < 5_000.0:
        raise ValueError(f"click_band_hz must span at least 5 kHz, got {o['click_band_hz']!r}")
    if given("click_band_hz") and o["click_band_hz"][1] >= 0.5 * fs:
        raise ValueError(f"click_band_hz {o['click_band_hz']!r} must end below fs/2 = {0.5 * fs:g}")
    pair("click_duration_s", 1e-6, 0.01)
    number("source_level_spread_db", 0.0, 40.0)
    pair("ici_range_s", 1e-3, 60.0)
    if given("ici_range_s") and o["ici_range_s"][0] <= 0:
        raise ValueError(f"ici_range_s must be positive, got {o['ici_range_s']!r}")
    number("close_pair_probability", 0.0, 1.0)
    pair("close_pair_distance_m", 0.0, 10_000.0)
    n_int = o["n_interferers"]
    if given("n_interferers") and (isinstance(n_int, bool) or int(n_int) != n_int
                                   or not 0 <= n_int <= 5):
        raise ValueError(f"n_interferers must be an integer from 0 to 5, got {n_int!r}")
    pair("interferer_ici_s", 1e-3, 60.0)
    if given("interferer_ici_s") and o["interferer_ici_s"][0] <= 0:
        raise ValueError(f"interferer_ici_s must be positive, got {o['interferer_ici_s']!r}")
    pair("interferer_duration_s", 1e-6, 0.01)
    pair("interferer_level_db", -60.0, 60.0)
    pair("interferer_freq_hz", 100.0, 0.5 * fs)
    clicks = o["whale_clicks"]
    if given("whale_clicks"):
        if len(clicks) != n_sources:
            raise ValueError(f"whale_clicks has {len(clicks)} clicks for {n_sources} whales")
        for c in clicks:
            if c.f_end_hz >= 0.5 * fs:
                raise ValueError(f"a whale click ends at {c.f_end_hz} Hz, above fs/2")
        if given("click_band_hz") or given("click_duration_s"):
            raise ValueError("give whale_clicks or click_band_hz/click_duration_s, not both")
    if given("click_band_hz") != given("click_duration_s"):
        raise ValueError("click_band_hz and click_duration_s go together (draw range of each "
                         "whale's click)")
