"""Beaked-whale-like click trains received on widely spaced bottom-mounted hydrophones.

The scenario is the one the click pipeline (``fusion localize``) is built for — the setting of
*Localization of Short Duration Periodic Signals* (Baggenstoss, NUWC 102089, paragraphs
[0028]–[0036]): hydrophones kilometres apart on the sea floor sampled at 96 kHz, Blainville's
beaked whales emitting short FM upswept clicks at an inter-click interval (ICI) near 0.37 s.

Physics (every choice explicit, see :func:`simulate_clicks`):

* straight-line propagation at the array's constant sound speed; each click leaves the source
  at its emission time from the source's position at that time;
* spherical spreading (``1/r`` amplitude) and a frequency-flat absorption loss in dB/km;
* one surface-reflected path per click and sensor, from the image source ``(x, y, -z)`` with a
  reflection coefficient (default -0.9, a phase-inverting pressure-release surface);
* white ambient noise, band-limited to ``noise_band_hz``, at a stated in-band SNR;
* optional impulsive false transients (damped sinusoids) on single channels.

Each click is synthesised analytically at its exact (continuous) arrival time, so the sampled
audio carries arrival times exact to well under a sample.

This module holds the simulator; its data classes (:mod:`fusion.simulate._click_types`), building
blocks (:mod:`fusion.simulate._click_synthesis`) and file writers
(:mod:`fusion.simulate._click_files`) are importable from here.

Examples
--------
>>> sc = simulate_clicks(seed=1, n_sensors=3, n_sources=1, duration_s=2.0)
>>> sc.audio.shape
(192000, 3)
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import SensorArray
from fusion.simulate._click_files import (  # FILE_PEAK re-exported: benchmarks read it here
    FILE_PEAK,  # noqa: F401
    truth_document,
    write_click_scenario,
)
from fusion.simulate._click_synthesis import (
    _add_band_noise,
    _layout,
    _positions,
    _render,
    _transient_shape,
    draw_emission_times,
)
from fusion.simulate._click_types import ClickScenario, ClickWaveform, WhaleTrack

__all__ = [
    "ClickScenario",
    "ClickWaveform",
    "WhaleTrack",
    "draw_emission_times",
    "simulate_clicks",
    "truth_document",
    "write_click_scenario",
    "write_scenario",
]

logger = logging.getLogger(__name__)


def simulate_clicks(
    *,
    seed: int,
    n_sensors: int = 5,
    n_sources: int = 2,
    duration_s: float = 30.0,
    fs: float = 96_000.0,
    snr_db: float = 30.0,
    n_transients: int = 8,
    sound_speed: float = 1500.0,
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
) -> ClickScenario:
    """Simulate beaked-whale-like click trains received on bottom-mounted hydrophones.

    Parameters
    ----------
    seed : int
        Seed of every random draw (same seed and options -> identical scenario and audio).
    n_sensors : int, optional
        Hydrophones, 3 to 8. They lie on a jittered ring of radius `array_radius_m` (with one
        near the centre when ``n_sensors >= 5``) at depths 1500–1700 m (z negative).
    n_sources : int, optional
        Whales, 1 to 3. Each starts within ``0.6 * array_radius_m`` of the array centre at a
        depth drawn from `depth_range_m`, moves at a speed drawn from `speed_range_mps` on an arc
        turning at most `max_turn_rate_deg_s`, and drifts vertically by at most 0.2 m/s.
    duration_s : float, optional
        Audio length, s.
    fs : float, optional
        Sample rate, Hz; must exceed twice the highest click and noise frequency.
    snr_db : float, optional
        ``20 log10(A_ref / sigma_band)``: the peak amplitude ``A_ref`` of a nominal
        direct-path click received at `reference_range_m` over the standard deviation
        ``sigma_band`` of the ambient noise within the click band. A click at range ``r`` has
        peak ``(r_ref / r) 10^(-a (r - r_ref) / 20000)`` with ``a`` = `absorption_db_per_km`,
        times the per-click level jitter. ``inf`` gives noise-free audio.
    n_transients : int, optional
        Impulsive false transients, each on one random channel at a uniform random time.
    sound_speed : float, optional
        Constant sound speed, m/s.
    array_radius_m : float, optional
        Radius of the hydrophone ring, m.
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

    Returns
    -------
    ClickScenario

    Raises
    ------
    ValueError
        Any option out of range.

    Notes
    -----
    Emission ``k`` of a source at position ``p_k`` reaches sensor ``s_i`` at
    ``t_e + |p_k - s_i| / c`` (direct path) and at ``t_e + |p_k' - s_i| / c`` with
    ``p_k' = (x, y, -z)`` the image source (surface echo, amplitude scaled by the reflection
    coefficient). The click train starts before the audio so that arrivals are present from
    ``t = 0``; emissions none of whose arrivals fall inside ``[0, duration_s)`` are dropped.

    Examples
    --------
    >>> sc = simulate_clicks(seed=0, n_sensors=4, n_sources=1, duration_s=3.0, snr_db=40.0)
    >>> sc.n_sensors, sc.sources[0].arrival_times.shape[1]
    (4, 4)
    """
    click = ClickWaveform() if click is None else click
    _validate(
        n_sensors=n_sensors, n_sources=n_sources, duration_s=duration_s, fs=fs, snr_db=snr_db,
        n_transients=n_transients, sound_speed=sound_speed, array_radius_m=array_radius_m,
        reference_range_m=reference_range_m, absorption_db_per_km=absorption_db_per_km,
        surface_reflection=surface_reflection, noise_band_hz=noise_band_hz, click=click,
        ici_s=ici_s, ici_jitter_s=ici_jitter_s, level_jitter_db=level_jitter_db,
        speed_range_mps=speed_range_mps, max_turn_rate_deg_s=max_turn_rate_deg_s,
        depth_range_m=depth_range_m, transient_amplitude_range=transient_amplitude_range,
    )
    rng = np.random.default_rng(seed)
    c = float(sound_speed)
    sensors = SensorArray(_layout(n_sensors, rng, radius_m=array_radius_m), c)
    pos_s = sensors.positions
    centre = pos_s[:, :2].mean(axis=0)
    n_samples = int(round(duration_s * fs))
    audio = np.zeros((n_samples, n_sensors), dtype=np.float32)

    def loss(r: NDArray[np.float64]) -> NDArray[np.float64]:
        # spherical spreading and absorption, unit at the reference range
        return (reference_range_m / r) * 10.0 ** (
            -absorption_db_per_km * (r - reference_range_m) / 20_000.0
        )

    tracks = []
    for k in range(n_sources):
        rad = 0.6 * array_radius_m * np.sqrt(rng.uniform())
        phi = rng.uniform(0.0, 2.0 * np.pi)
        p0 = np.array([
            centre[0] + rad * np.cos(phi), centre[1] + rad * np.sin(phi),
            -rng.uniform(*depth_range_m),
        ])
        speed = rng.uniform(*speed_range_mps)
        heading = rng.uniform(0.0, 2.0 * np.pi)
        turn = np.radians(rng.uniform(-max_turn_rate_deg_s, max_turn_rate_deg_s))
        vz = rng.uniform(-0.2, 0.2)
        # start the train early enough that the slowest path at t = 0 is already arriving
        img0 = p0 * np.array([1.0, 1.0, -1.0])
        head_start_s = float(np.linalg.norm(img0 - pos_s, axis=1).max()) / c + click.duration_s
        t_em = draw_emission_times(
            ici_mean_s=ici_s, ici_jitter_s=ici_jitter_s, t_start_s=-head_start_s - ici_s,
            t_end_s=duration_s, rng=rng,
        )
        pos = _positions(t_em, p0, speed, heading, turn, vz)
        img = pos * np.array([1.0, 1.0, -1.0])  # image source across the surface z = 0
        r_dir = np.linalg.norm(pos[:, None, :] - pos_s[None, :, :], axis=2)  # (n_clicks, n_sens)
        r_img = np.linalg.norm(img[:, None, :] - pos_s[None, :, :], axis=2)
        t_dir = t_em[:, None] + r_dir / c
        t_img = t_em[:, None] + r_img / c
        # keep emissions with any arrival overlapping the audio
        first = np.minimum(t_dir.min(axis=1), t_img.min(axis=1) if surface_reflection else np.inf)
        last = np.maximum(t_dir.max(axis=1), t_img.max(axis=1) if surface_reflection else -np.inf)
        half = 0.5 * click.duration_s
        keep = (last + half > 0.0) & (first - half < duration_s)
        t_em, pos, r_dir, r_img, t_dir, t_img = (
            a[keep] for a in (t_em, pos, r_dir, r_img, t_dir, t_img)
        )
        src_amp = 10.0 ** (level_jitter_db * rng.standard_normal(t_em.size) / 20.0)
        a_dir = src_amp[:, None] * loss(r_dir)
        a_img = surface_reflection * src_amp[:, None] * loss(r_img)
        tracks.append(WhaleTrack(
            source_id=k, start_position=p0, speed_mps=float(speed), heading_rad=float(heading),
            turn_rate_rad_s=float(turn), vertical_rate_mps=float(vz), ici_mean_s=float(ici_s),
            ici_jitter_s=float(ici_jitter_s), emission_times=t_em, positions=pos,
            source_amplitudes=src_amp, arrival_times=t_dir, arrival_amplitudes=a_dir,
            echo_arrival_times=t_img, echo_amplitudes=a_img,
        ))
        ch = np.broadcast_to(np.arange(n_sensors), t_dir.shape).ravel()
        _render(audio, t_dir.ravel(), ch, a_dir.ravel(), click.evaluate, half, half, fs)
        if surface_reflection:
            _render(audio, t_img.ravel(), ch, a_img.ravel(), click.evaluate, half, half, fs)

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
    )


def _validate(**o: Any) -> None:
    def finite_pos(name: str) -> None:
        v = o[name]
        if isinstance(v, bool) or not np.isfinite(v) or v <= 0:
            raise ValueError(f"{name} must be a positive number, got {v!r}")

    def rng_pair(name: str, lo_min: float = 0.0) -> None:
        v = o[name]
        if len(v) != 2 or not all(np.isfinite(x) for x in v) or not lo_min <= v[0] <= v[1]:
            raise ValueError(f"{name} must be (low, high) with {lo_min} <= low <= high, got {v!r}")

    for name, lo, hi in (("n_sensors", 3, 8), ("n_sources", 1, 3)):
        v = o[name]
        if isinstance(v, bool) or int(v) != v or not lo <= v <= hi:
            raise ValueError(f"{name} must be an integer from {lo} to {hi}, got {v!r}")
    n_tr = o["n_transients"]
    if isinstance(n_tr, bool) or int(n_tr) != n_tr or n_tr < 0:
        raise ValueError(f"n_transients must be a non-negative integer, got {n_tr!r}")
    for name in ("duration_s", "fs", "sound_speed", "array_radius_m", "reference_range_m",
                 "ici_s"):
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
    click: ClickWaveform = o["click"]
    f_lo, f_hi = o["noise_band_hz"]
    nyq = 0.5 * o["fs"]
    if click.f_end_hz >= nyq or f_hi >= nyq:
        raise ValueError(
            f"fs={o['fs']} Hz is too low: the click band ends at {click.f_end_hz} Hz and the "
            f"noise band at {f_hi} Hz, both must stay below fs/2"
        )
    if min(f_hi, click.f_end_hz) - max(f_lo, click.f_start_hz) <= 0:
        raise ValueError(f"noise_band_hz {o['noise_band_hz']} does not overlap the click band")


def write_scenario(out_dir: Path, *, seed: int) -> list[Path]:
    """``fusion simulate clicks``: the default scenario (:func:`simulate_clicks`) written out.

    Parameters
    ----------
    out_dir : pathlib.Path
        Output folder.
    seed : int
        Scenario seed.

    Returns
    -------
    list of pathlib.Path
        ``audio.flac`` (96 kHz, channel i = sensor i), ``array.json``, ``truth.json``.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: output path exists and is not a folder")
    return write_click_scenario(out, simulate_clicks(seed=seed))
