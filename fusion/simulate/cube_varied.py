"""Varied narrowband cubes: the physics of :mod:`fusion.simulate.cube` under other plausible
assumptions, drawn per cube from the seed.

:func:`fusion.simulate.cube.simulate_cube` draws every cube the same way: white noise of unit
mean and known statistics (exponential for one look), a 300 Hz line. An
acquisition tuned on such cubes can come to depend on them, e.g. on being told the noise's
degrees of freedom. Here the cube keeps the same building blocks (the line's spectrum
:func:`~fusion.simulate.cube.line_spectrum`, the line array's beam pattern
:func:`~fusion.simulate.cube.beam_pattern`, periodogram looks
:func:`~fusion.simulate.cube.noisy_power`) and draws:

- **line frequency** 150-800 Hz (the wavelength, hence the beamwidth and the beam tolerance,
  change with it), its offset within its bin and its spectral spread 0.05-0.3 Hz;
- **bearing rate** uniform in 0-40 deg/min with a random sign, the start bearing so that the
  trace stays within 10-170 deg;
- **noise statistics**: 1-4 averaged periodogram looks (gamma noise with 2-8 degrees of
  freedom); on 30 % of the cubes a texture (each cell's power multiplied by a unit-mean gamma
  variable of shape 3-10, a K-distributed, heavier-tailed background);
- **noise level**: not unit: an overall scale of 10^(-2..2), a slope of -3..3 dB across the band,
  a smooth ripple of up to 2 dB across beams and a 0.5 dB fluctuation from scan to scan (the
  per-bin SNR is relative to the local noise level, so the line keeps its SNR).

There is no display lag (as in the fixed cube's default): the lag is a property of the
processing chain that the operator's system knows and corrects.

The per-bin SNR is the caller's (the benchmark's grid) or drawn in 3-9 dB. The drawn values are
returned in :attr:`fusion.simulate.cube.CubeScenario.parameters`; they are truth, not settings
for the acquisition.
"""

from __future__ import annotations

import logging

import numpy as np

from fusion.geometry import beam_from_bearing
from fusion.io import Cube
from fusion.simulate._cube_model import CubeScenario, beam_pattern, line_spectrum, noisy_power

__all__ = ["simulate_varied_cube"]

logger = logging.getLogger(__name__)


def simulate_varied_cube(
    seed: int,
    *,
    snr_db: float | None = None,
    n_beams: int = 64,
    n_scans: int = 60,
    n_bins: int = 16,
    scan_period_s: float = 1.0,
    aperture_m: float = 50.0,
    sound_speed: float = 1500.0,
    bin_width_hz: float = 1.0,
):
    """Simulate one varied cube (see the module docstring for the draws).

    Parameters
    ----------
    seed : int
        Seed; same arguments, same cube.
    snr_db : float, optional
        Per-bin SNR of the line relative to the local noise level, dB; drawn in [3, 9] when
        None.
    n_beams, n_scans, n_bins : int, optional
        Cube shape (scans x beams x bins).
    scan_period_s : float, optional
        Time between scans, s.
    aperture_m, sound_speed, bin_width_hz : float, optional
        Array aperture (m), sound speed (m/s), bin spacing (Hz).

    Returns
    -------
    fusion.simulate.cube.CubeScenario
        ``click_beam`` and ``click_freq`` are the exact click (nearest beam, nearest bin);
        :attr:`parameters` holds the draws.
    """
    rng = np.random.default_rng(seed)
    line_freq = float(rng.uniform(150.0, 800.0))
    offset = float(rng.uniform(-0.5, 0.5))
    spread = float(rng.uniform(0.05, 0.3))
    rate = float(rng.uniform(0.0, 40.0)) * (1.0 if rng.uniform() < 0.5 else -1.0)
    span = rate * (n_scans - 1) * scan_period_s / 60.0
    bearing0 = float(rng.uniform(10.0 - min(span, 0.0), 170.0 - max(span, 0.0)))
    snr = float(rng.uniform(3.0, 9.0)) if snr_db is None else float(snr_db)
    n_avg = int(rng.integers(1, 5))
    texture_shape = float(rng.uniform(3.0, 10.0)) if rng.uniform() < 0.3 else None
    scale_db = float(rng.uniform(-20.0, 20.0))
    slope_db = float(rng.uniform(-3.0, 3.0))
    ripple_db = float(rng.uniform(0.0, 2.0))
    lag = 0.0

    centre = line_freq - offset * bin_width_hz
    freqs = centre + (np.arange(n_bins) - n_bins // 2) * bin_width_hz
    spectrum = line_spectrum(freqs, bin_width_hz=bin_width_hz, line_freq_hz=line_freq,
                             freq_spread_hz=spread)
    t = np.arange(n_scans) * scan_period_s
    rate_rad = np.radians(rate) / 60.0
    theta0 = np.radians(bearing0)
    true_theta = np.arccos(np.cos(theta0 + rate_rad * t))
    shown_theta = np.arccos(np.cos(theta0 + rate_rad * (t - lag)))
    pattern = beam_pattern(shown_theta, n_beams=n_beams, aperture_m=aperture_m,
                           wavelength_m=sound_speed / line_freq)
    sig = 10.0 ** (snr / 10.0) * pattern[:, :, None] * spectrum[None, None, :]
    power = noisy_power([sig], rng=rng, n_averages=n_avg)
    if texture_shape is not None:
        power = power * rng.gamma(texture_shape, 1.0 / texture_shape, power.shape)
    # Noise level: overall scale, slope across the band, smooth ripple across beams, scan jitter.
    b = np.arange(n_beams) / (n_beams - 1)
    phases = rng.uniform(0.0, 2.0 * np.pi, 2)
    ripple = ripple_db * 0.5 * (np.sin(2 * np.pi * b + phases[0])
                                + np.sin(5 * np.pi * b + phases[1]))
    jitter = rng.normal(0.0, 0.5, n_scans)
    level_db = (scale_db + jitter[:, None, None] + ripple[None, :, None]
                + slope_db * (np.arange(n_bins) / (n_bins - 1) - 0.5)[None, None, :])
    power = power * 10.0 ** (level_db / 10.0)

    beam_track = np.asarray(beam_from_bearing(shown_theta, n_beams))
    params = {"line_freq_hz": line_freq, "line_offset_bins": offset, "freq_spread_hz": spread,
              "bearing0_deg": bearing0, "bearing_rate_deg_per_min": rate, "snr_db": snr,
              "n_averages": n_avg, "texture_shape": texture_shape, "level_scale_db": scale_db,
              "level_slope_db": slope_db, "beam_ripple_db": ripple_db, "lag_s": lag}
    logger.debug("varied cube seed %d: %s", seed, params)
    return CubeScenario(
        cube=Cube(power=power, freqs=freqs, scan_period=scan_period_s, aperture=aperture_m,
                  sound_speed=sound_speed),
        bearing_deg=np.degrees(true_theta),
        shown_bearing_deg=np.degrees(shown_theta),
        beam_track=beam_track,
        bearing_rate_deg_per_min=rate,
        snr_db=snr,
        line_freq_hz=line_freq,
        click_beam=int(np.clip(np.floor(beam_track[-1] + 0.5), 0, n_beams - 1)),
        click_freq=float(freqs[int(np.argmin(np.abs(freqs - line_freq)))]),
        lag_s=lag,
        parameters=params,
    )
