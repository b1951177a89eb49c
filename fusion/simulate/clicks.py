"""Beaked-whale-like click trains received on widely spaced bottom-mounted hydrophones.

The scenario is the one the click pipeline (``fusion localize``) is built for — the setting of
*Localization of Short Duration Periodic Signals* (Baggenstoss, NUWC 102089, paragraphs
[0028]–[0036]): hydrophones kilometres apart on the sea floor sampled at 96 kHz, Blainville's
beaked whales emitting short FM upswept clicks at an inter-click interval (ICI) near 0.37 s.

Default physics (the localizer's own model; every choice explicit, see :func:`simulate_clicks`):

* straight-line propagation at the array's constant sound speed; each click leaves the source
  at its emission time from the source's position at that time;
* spherical spreading (``1/r`` amplitude) and a frequency-flat absorption loss in dB/km;
* one surface-reflected path per click and sensor, from the image source ``(x, y, -z)`` with a
  reflection coefficient (default -0.9, a phase-inverting pressure-release surface);
* white ambient noise, band-limited to ``noise_band_hz``, at a stated in-band SNR;
* optional impulsive false transients (damped sinusoids) on single channels.

The world of a real range (the *range options* of :func:`simulate_clicks`, all off by default
and all drawn by ``fusion simulate clicks --vary``, ranges in
:data:`fusion.simulate.whale_range.varied.VARIED_RANGES`) adds what the localizer does not model:

* hydrophones 1-20 m above a plane sea floor (depth 500-2,000 m under the array centre,
  slope 0-5 deg), 3-10 of them on a jittered triangular grid of spacing 0.5-6 km;
* a sea-floor echo per sensor from the image of the source across the floor plane (0.2-10 ms
  after the direct path for typical geometry, coefficient -3 to -15 dB, sign positive or
  random) and a rough-surface echo (inverted, magnitude 0.5-0.95 per sensor); ``echo`` chooses
  ``none``, ``surface``, ``bottom`` or ``both``;
* a depth-dependent sound speed (Munk or thermocline profile) with straight-ray travel times
  ``L / (d2 - d1) * integral dd / c`` (:mod:`fusion.simulate.whale_range.propagation`), while
  ``array.json`` states one nominal speed (the profile's water-column mean): path speeds differ
  from it by up to about 1 %;
* per-whale FM upsweeps (20-50 kHz, 150-400 us), source levels (±6 dB) and ICIs (0.2-1 s);
  1-5 whales, some starting 20-100 m from another; interfering broadband clicks (20-80 us) of
  0-2 other sources, recorded apart from the whales;
* survey errors: ``array.json`` holds surveyed positions (true + N(0, 1-3 m) per axis), the
  truth the true ones, and the truth TDOAs are those of the true geometry and propagation.

Each click is synthesised analytically at its exact (continuous) arrival time, so the sampled
audio carries arrival times exact to well under a sample.

This module holds the simulator; its data classes (:mod:`fusion.simulate.whale_range.types`), building
blocks (:mod:`fusion.simulate.whale_range.synthesis`, :mod:`fusion.simulate.whale_range.world`,
:mod:`fusion.simulate.whale_range.propagation`) and file writers (:mod:`fusion.simulate.whale_range.files`)
are importable from here.

Examples
--------
>>> sc = simulate_clicks(seed=1, n_sensors=3, n_sources=1, duration_s=2.0)
>>> sc.audio.shape
(192000, 3)
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import SensorArray
from fusion.simulate.whale_range.files import (  # FILE_PEAK re-exported: benchmarks read it here
    FILE_PEAK,  # noqa: F401
    truth_document,
    write_click_scenario,
)
from fusion.simulate.whale_range.propagation import SoundSpeedProfile, path_times
from fusion.simulate.whale_range.sources import jsonable, simulate_whales
from fusion.simulate.whale_range.synthesis import (
    _add_band_noise,
    _layout,
    _render,
    _transient_shape,
    draw_emission_times,
)
from fusion.simulate.whale_range.types import ClickScenario, ClickWaveform, WhaleTrack
from fusion.simulate.whale_range.validate import validate_options, validate_range_options
from fusion.simulate.whale_range.world import (
    RANGE_DEFAULTS,
    RangeWorld,
    simulate_interferers,
    world_geometry,
)

__all__ = [
    "ClickScenario",
    "ClickWaveform",
    "SoundSpeedProfile",
    "WhaleTrack",
    "draw_emission_times",
    "simulate_clicks",
    "truth_document",
    "write_click_scenario",
    "write_scenario",
]

logger = logging.getLogger(__name__)

#: The range options of :func:`simulate_clicks` (None: off, the default scenario).
RANGE_OPTIONS = (
    "echo", "floor_depth_m", "floor_slope_deg", "floor_azimuth_deg", "height_above_floor_m",
    "sensor_spacing_m", "sound_speed_profile", "nominal_sound_speed", "position_error_m",
    "surface_reflection_range", "bottom_reflection_db", "bottom_reflection_sign", "whale_clicks",
    "click_band_hz", "click_duration_s", "source_level_spread_db", "ici_range_s",
    "close_pair_probability", "close_pair_distance_m", "n_interferers", "interferer_ici_s",
    "interferer_duration_s", "interferer_level_db", "interferer_freq_hz",
)


def simulate_clicks(
    *,
    seed: int,
    n_sensors: int = 5,
    n_sources: int = 2,
    duration_s: float = 30.0,
    fs: float = 96_000.0,
    snr_db: float = 30.0,
    n_transients: int = 8,
    sound_speed: float | None = None,
    array_radius_m: float = 1500.0,
    reference_range_m: float = 1000.0,
    absorption_db_per_km: float = 8.0,
    surface_reflection: float = -0.9,
    noise_band_hz: tuple[float, float] = (1_000.0, 46_000.0),
    click: ClickWaveform | None = None,
    ici_s: float = 0.37,
    ici_jitter_s: float = 0.03,
    level_jitter_db: float = 2.0,
    speed_range_mps: tuple[float, float] = (1.0, 2.0),
    max_turn_rate_deg_s: float = 0.5,
    depth_range_m: tuple[float, float] = (500.0, 1200.0),
    transient_amplitude_range: tuple[float, float] = (0.3, 3.0),
    echo: str | None = None,
    floor_depth_m: float | None = None,
    floor_slope_deg: float | None = None,
    floor_azimuth_deg: float | None = None,
    height_above_floor_m: tuple[float, float] | None = None,
    sensor_spacing_m: float | None = None,
    sound_speed_profile: SoundSpeedProfile | dict[str, Any] | None = None,
    nominal_sound_speed: float | None = None,
    position_error_m: float | None = None,
    surface_reflection_range: tuple[float, float] | None = None,
    bottom_reflection_db: tuple[float, float] | None = None,
    bottom_reflection_sign: str | None = None,
    whale_clicks: Sequence[ClickWaveform] | None = None,
    click_band_hz: tuple[float, float] | None = None,
    click_duration_s: tuple[float, float] | None = None,
    source_level_spread_db: float | None = None,
    ici_range_s: tuple[float, float] | None = None,
    close_pair_probability: float | None = None,
    close_pair_distance_m: tuple[float, float] | None = None,
    n_interferers: int | None = None,
    interferer_ici_s: tuple[float, float] | None = None,
    interferer_duration_s: tuple[float, float] | None = None,
    interferer_level_db: tuple[float, float] | None = None,
    interferer_freq_hz: tuple[float, float] | None = None,
) -> ClickScenario:
    """Simulate beaked-whale-like click trains received on bottom-mounted hydrophones.

    Parameters
    ----------
    seed : int
        Seed of every random draw (same seed and options -> identical scenario and audio).
    n_sensors : int, optional
        Hydrophones, 3 to 10. By default they lie on a jittered ring of radius
        `array_radius_m` (with one near the centre when ``n_sensors >= 5``) at depths
        1500–1700 m (z negative); with a floor (range options) above it.
    n_sources : int, optional
        Whales, 1 to 5. Each starts within 0.6 times the array radius of the array centre (with
        a `sensor_spacing_m`: within half the spacing of the centroid of a random hydrophone
        and its two nearest neighbours, where three can hear it) at a depth drawn from `depth_range_m`
        (above the floor when there is one), moves at a speed
        drawn from `speed_range_mps` on an arc turning at most `max_turn_rate_deg_s`, and
        drifts vertically by at most 0.2 m/s.
    duration_s : float, optional
        Audio length, s.
    fs : float, optional
        Sample rate, Hz; must exceed twice the highest click and noise frequency.
    snr_db : float, optional
        ``20 log10(A_ref / sigma_band)``: the peak amplitude ``A_ref`` of a nominal
        direct-path click received at `reference_range_m` over the standard deviation
        ``sigma_band`` of the ambient noise within the click band (of `click`). A click at
        range ``r`` has peak ``(r_ref / r) 10^(-a (r - r_ref) / 20000)`` with ``a`` =
        `absorption_db_per_km`, times the per-click level jitter. ``inf``: noise-free audio.
    n_transients : int, optional
        Impulsive false transients, each on one random channel at a uniform random time.
    sound_speed : float, optional
        Constant sound speed, m/s (default 1500); not with `sound_speed_profile`.
    array_radius_m : float, optional
        Radius of the default hydrophone ring, m.
    reference_range_m : float, optional
        Range of the SNR definition, m.
    absorption_db_per_km : float, optional
        Frequency-flat absorption, dB/km (about 8 dB/km at 35 kHz in deep water).
    surface_reflection : float, optional
        Pressure reflection coefficient of the surface echo, in ``[-1, 1]`` (0 disables it).
    noise_band_hz : (float, float), optional
        Band of the flat-spectrum ambient noise, Hz; must overlap the click band.
    click : ClickWaveform, optional
        The emitted click (default: 25–45 kHz upsweep, 250 us, Hann taper).
    ici_s, ici_jitter_s : float, optional
        Mean and standard deviation of the inter-click interval, s.
    level_jitter_db : float, optional
        Standard deviation of the per-click source level, dB.
    speed_range_mps, max_turn_rate_deg_s, depth_range_m : optional
        Source motion limits (see `n_sources`).
    transient_amplitude_range : (float, float), optional
        Peak amplitude range of the transients (log-uniform), relative to ``A_ref``.
    echo : {"none", "surface", "bottom", "both"}, optional
        Rendered echoes. Giving it puts the hydrophones on a floor (below); the same seed
        gives the same world for every choice, only the rendered echoes differ. Default with a
        world: ``both`` with a floor, else ``surface``.
    floor_depth_m, floor_slope_deg, floor_azimuth_deg : float, optional
        Plane sea floor: depth under the array centre (default 1600 m), slope (default 0) and
        downslope direction (default uniform), deg counter-clockwise from +x.
    height_above_floor_m : (float, float), optional
        Range of the hydrophone heights above the floor, drawn per sensor (default 1-20 m).
    sensor_spacing_m : float, optional
        Median nearest-neighbour distance of a jittered triangular hydrophone grid (default:
        no grid, the horizontal positions of the default ring).
    sound_speed_profile : SoundSpeedProfile or dict, optional
        Depth-dependent sound speed (``{"kind": ..., **params}``, see
        :class:`~fusion.simulate.whale_range.propagation.SoundSpeedProfile`); travel times integrate
        ``1/c`` along straight rays. None: constant `sound_speed`.
    nominal_sound_speed : float, optional
        Speed written into ``array.json`` (default: `sound_speed`, or the profile's mean over
        the water column rounded to 0.1 m/s).
    position_error_m : float, optional
        Survey error, standard deviation per axis, m: ``array.json`` gets true + error.
    surface_reflection_range : (float, float), optional
        Range of the surface coefficient magnitude drawn per sensor (sign inverted).
    bottom_reflection_db, bottom_reflection_sign : optional
        Floor coefficient per sensor: level uniform in the range (default -15 to -3 dB), sign
        ``"positive"`` (default) or ``"random"``.
    whale_clicks : sequence of ClickWaveform, optional
        One click per whale.
    click_band_hz, click_duration_s : (float, float), optional
        Draw each whale's upsweep: start in ``[lo, hi - 5 kHz]``, end in ``[start + 5 kHz,
        hi]``, duration in `click_duration_s`.
    source_level_spread_db : float, optional
        Each whale's level offset is uniform in ``±spread`` dB.
    ici_range_s : (float, float), optional
        Each whale's mean ICI is uniform in this range (replaces `ici_s`).
    close_pair_probability, close_pair_distance_m : optional
        Each whale after the first starts, with this probability, at a distance drawn from
        the range (default 20-100 m) from an earlier whale, heading with it.
    n_interferers : int, optional
        Broadband click trains of other species, 0 to 5, at fixed positions in the water
        column (``ClickScenario.world.interferers``), with ``interferer_ici_s`` (log-uniform,
        default 0.05-1 s), ``interferer_duration_s`` (20-80 us), ``interferer_level_db``
        (±6 dB re a nominal whale click) and ``interferer_freq_hz`` (carrier, 15-40 kHz).

    Returns
    -------
    ClickScenario
        With ``world`` (a :class:`~fusion.simulate.whale_range.world.RangeWorld`) when any range
        option is given; then ``sensors`` holds the surveyed positions and the nominal speed.

    Raises
    ------
    ValueError
        Any option out of range.

    Notes
    -----
    Emission ``k`` of a source at position ``p_k`` reaches sensor ``s_i`` along each path at
    ``t_e + T(path)``: by default ``T = |p_k - s_i| / c`` (direct) and ``|p_k' - s_i| / c`` with
    ``p_k' = (x, y, -z)`` the image source (surface echo, amplitude scaled by the reflection
    coefficient); with a floor also the image across the floor plane; with a profile ``T`` is
    the straight-ray integral of ``1/c`` over the path's segments. The click train starts
    before the audio so that arrivals are present from ``t = 0``; emissions none of whose
    arrivals fall inside ``[0, duration_s)`` are dropped. The range options draw from a second
    generator (``default_rng([seed, 1])``), so the default scenario is unchanged.

    Examples
    --------
    >>> sc = simulate_clicks(seed=0, n_sensors=4, n_sources=1, duration_s=3.0, snr_db=40.0)
    >>> sc.n_sensors, sc.sources[0].arrival_times.shape[1]
    (4, 4)
    """
    click = ClickWaveform() if click is None else click
    validate_options(
        n_sensors=n_sensors, n_sources=n_sources, duration_s=duration_s, fs=fs, snr_db=snr_db,
        n_transients=n_transients, sound_speed=sound_speed, array_radius_m=array_radius_m,
        reference_range_m=reference_range_m, absorption_db_per_km=absorption_db_per_km,
        surface_reflection=surface_reflection, noise_band_hz=noise_band_hz, click=click,
        ici_s=ici_s, ici_jitter_s=ici_jitter_s, level_jitter_db=level_jitter_db,
        speed_range_mps=speed_range_mps, max_turn_rate_deg_s=max_turn_rate_deg_s,
        depth_range_m=depth_range_m, transient_amplitude_range=transient_amplitude_range,
    )
    local = locals()
    opts = {name: local[name] for name in RANGE_OPTIONS}
    validate_range_options(opts, fs=fs, n_sources=n_sources)
    if sound_speed is not None and sound_speed_profile is not None:
        raise ValueError("give sound_speed (constant) or sound_speed_profile, not both "
                         "(nominal_sound_speed sets the speed array.json states)")
    rng = np.random.default_rng(seed)
    c = 1500.0 if sound_speed is None else float(sound_speed)
    world_on = any(v is not None for v in opts.values())
    world: dict[str, Any] = {}
    rng2 = np.random.default_rng([int(seed), 1]) if world_on else None  # the range physics
    if rng2 is not None:
        world = world_geometry(opts, n_sensors=n_sensors, rng=rng, rng2=rng2,
                               array_radius_m=array_radius_m, sound_speed=c,
                               surface_reflection=surface_reflection)
        pos_s, floor, profile, coef = (world[k] for k in ("sensors_true", "floor", "profile",
                                                          "coef"))
        sensors = SensorArray(world["surveyed"], world["nominal_sound_speed"])
        centre, radius = world["whale_centres"], world["whale_radius"]
    else:
        sensors = SensorArray(_layout(n_sensors, rng, radius_m=array_radius_m), c)
        pos_s, floor, profile = sensors.positions, None, None
        centre, radius = pos_s[:, :2].mean(axis=0), array_radius_m
        coef = {"direct": 1.0, "surface": surface_reflection}

    def propagate(src: NDArray[np.float64]) -> dict[str, tuple[NDArray, NDArray]]:
        return path_times(src, pos_s, profile=profile, sound_speed=c, floor=floor)

    n_samples = int(round(duration_s * fs))
    audio = np.zeros((n_samples, n_sensors), dtype=np.float32)

    def loss(r: NDArray[np.float64]) -> NDArray[np.float64]:
        # spherical spreading and absorption, unit at the reference range
        return (reference_range_m / r) * 10.0 ** (
            -absorption_db_per_km * (r - reference_range_m) / 20_000.0
        )

    tracks = simulate_whales(
        audio, rng=rng, rng2=rng2, opts=opts, n_sources=n_sources,
        centre=centre, radius=radius, floor=floor, propagate=propagate, loss=loss, coef=coef,
        click=click, duration_s=duration_s, fs=fs, depth_range_m=depth_range_m,
        speed_range_mps=speed_range_mps, max_turn_rate_deg_s=max_turn_rate_deg_s, ici_s=ici_s,
        ici_jitter_s=ici_jitter_s, level_jitter_db=level_jitter_db,
    )

    range_world = None
    if rng2 is not None:
        interferers = simulate_interferers(
            audio, rng2, n=int(n_interferers or 0),
            opts={k: RANGE_DEFAULTS[k] if opts[k] is None else opts[k]
                  for k in ("interferer_ici_s", "interferer_duration_s", "interferer_level_db",
                            "interferer_freq_hz")},
            sensors=pos_s, radius_m=world["radius"], floor=floor, propagate=propagate, loss=loss,
            coefficients=coef, duration_s=duration_s, fs=fs,
        )
        range_world = RangeWorld(
            echo=world["echo"], nominal_sound_speed=sensors.sound_speed, sensors_true=pos_s,
            position_error_m=float(position_error_m or 0.0), surface_coefficients=world["surface"],
            floor=floor, bottom_coefficients=world["bottom"], profile=profile,
            interferers=interferers, parameters=jsonable(opts),
        )

    # impulsive false transients, one channel each
    tr_t = rng.uniform(0.0, duration_s, n_transients)
    tr_ch = rng.integers(0, n_sensors, n_transients)
    lo, hi = np.log(transient_amplitude_range[0]), np.log(transient_amplitude_range[1])
    tr_a = np.exp(rng.uniform(lo, hi, n_transients))
    tr_f = rng.uniform(5_000.0, min(45_000.0, 0.45 * fs), n_transients)
    tr_d = rng.uniform(30e-6, 150e-6, n_transients)
    if n_transients:
        shape = _transient_shape(tr_f[:, None], tr_d[:, None])
        _render(audio, tr_t, tr_ch, tr_a, shape, 0.0, 8.0 * float(tr_d.max()), fs)

    # band-limited ambient noise at the requested in-band SNR
    f_lo, f_hi = noise_band_hz
    overlap = min(f_hi, click.f_end_hz) - max(f_lo, click.f_start_hz)
    noise_std_band = 0.0 if np.isinf(snr_db) else 10.0 ** (-snr_db / 20.0)
    # flat PSD: in-band variance = total variance * overlap / noise bandwidth
    noise_std = noise_std_band * np.sqrt((f_hi - f_lo) / overlap)
    if noise_std > 0:
        _add_band_noise(audio, fs, noise_band_hz, noise_std, rng)

    logger.debug(
        "simulated %d clicks from %d source(s) on %d sensors, %.1f s",
        sum(t.n_clicks for t in tracks), n_sources, n_sensors, duration_s,
    )
    return ClickScenario(
        seed=int(seed), sensors=sensors, fs=float(fs), duration_s=float(duration_s),
        sources=tuple(tracks), audio=audio, click=click, snr_db=float(snr_db),
        reference_range_m=float(reference_range_m), noise_std_band=float(noise_std_band),
        noise_std=float(noise_std), noise_band_hz=(float(f_lo), float(f_hi)),
        absorption_db_per_km=float(absorption_db_per_km),
        surface_reflection=float(surface_reflection), transient_times=tr_t,
        transient_channels=tr_ch, transient_amplitudes=tr_a, transient_freqs_hz=tr_f,
        world=range_world,
    )


def write_scenario(
    out_dir: Path,
    *,
    seed: int,
    vary: bool = False,
    vary_only: tuple[str, ...] | None = None,
    duration_s: float | None = None,
    n_sources: int | None = None,
    n_sensors: int | None = None,
    snr_db: float | None = None,
    echo: str | None = None,
) -> list[Path]:
    """``fusion simulate clicks``: a click scenario (:func:`simulate_clicks`) written out:
    ``audio.flac`` (96 kHz, channel i = sensor i), ``array.json``, ``truth.json``,
    ``tdoa_labels.csv``.

    A scenario writer (:mod:`fusion.simulate`: `out_dir`, `seed`, the written files returned).

    Parameters
    ----------
    vary : bool, optional
        Draw the physics of a real bottom-mounted range from
        :data:`fusion.simulate.whale_range.varied.VARIED_RANGES` (floor, profile, echoes, survey
        errors, click shapes, interferers, counts, ...); ``truth.json`` records the drawn
        settings under ``parameters`` (the world's resolved values beside them).
    vary_only : tuple of str, optional
        Draw only these groups of
        :data:`fusion.simulate.whale_range.varied.VARIED_GROUPS` (one physical effect at a
        time, e.g. ``("sound-speed",)``); the rest stay the default scenario's. Not with `vary`.
    duration_s, n_sources, n_sensors, snr_db, echo : optional
        Explicit values; they override the varied (or default) ones. Without any of them and
        without `vary` the files are those of the default scenario, byte for byte.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: output path exists and is not a folder")
    given = {k: v for k, v in (("duration_s", duration_s), ("n_sources", n_sources),
                               ("n_sensors", n_sensors), ("snr_db", snr_db), ("echo", echo))
             if v is not None}
    settings: dict[str, Any] = {"seed": seed}
    if vary and vary_only:
        raise ValueError("--vary draws every group; --vary-only draws the groups named")
    if vary or vary_only:
        from fusion.simulate.whale_range.varied import varied_settings

        settings = varied_settings(seed, only=tuple(vary_only) if vary_only else None)
    settings |= given
    scenario = simulate_clicks(**settings)
    if not (vary or vary_only):
        return write_click_scenario(out, scenario)
    return write_click_scenario(out, scenario, parameters=settings)
