"""Simulated passive narrowband beam/frequency/time cubes with one moving narrowband line.

The cube is what a line array's narrowband processor shows an operator: ``n_scans`` updates of
``n_beams`` beam spectra (beams equally spaced in cosine, beam 0 at forward endfire) over ``n_bins``
FFT bins, normalised so that noise alone has unit mean. One target radiates a narrowband line whose
bearing moves at a constant rate, so its trace crosses beams along a curve that is straight in
bearing and bent in beam number.

Model
-----
- Bearing ``theta(t) = theta_0 + rate * t`` (rad), folded into ``[0, pi]`` as a line array sees it
  (cone angle ``arccos(cos theta)``). With a spectral integration lag ``lag_s`` the scan at time
  ``t_k`` shows the bearing ``theta(t_k - lag_s)``.
- Beam response of a uniformly weighted line array in cosine space,
  ``B(u) = sinc^2(L (u - cos theta) / lambda)`` with ``u_b = 1 - 2 b / (N - 1)`` the steering cosine
  of beam ``b``: main lobe ``0.886 lambda / L`` wide at half power, sidelobes at -13 dB.
- Spectral shape: a Gaussian of standard deviation ``freq_spread_hz`` integrated over each bin, so the
  line's power summed over bins is its full power.
- Noise: each cell is the mean of ``n_averages`` periodogram looks ``|s + n|^2`` with ``n`` circular
  complex Gaussian of unit power and ``s`` the signal amplitude with a random phase per look, so
  noise alone is exponential (chi-square, 2 degrees of freedom) of unit mean for one look and gamma
  with ``2 n_averages`` degrees of freedom, unit mean, when looks are averaged.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from fusion.geometry import beam_from_bearing
from fusion.io import Cube, write_cube, write_json
from fusion.simulate._cube_model import CubeScenario, beam_pattern, line_spectrum, noisy_power
from fusion.simulate.cube_varied import simulate_varied_cube

__all__ = [
    "CubeScenario",
    "beam_pattern",
    "line_spectrum",
    "noisy_power",
    "simulate_cube",
    "write_scenario",
]

logger = logging.getLogger(__name__)


def simulate_cube(
    *,
    seed: int,
    n_beams: int = 64,
    n_scans: int = 60,
    n_bins: int = 16,
    scan_period_s: float = 1.0,
    aperture_m: float = 50.0,
    sound_speed: float = 1500.0,
    line_freq_hz: float = 300.0,
    bin_width_hz: float = 1.0,
    line_offset_bins: float | None = None,
    freq_spread_hz: float = 0.15,
    bearing0_deg: float = 60.0,
    bearing_rate_deg_per_min: float = 30.0,
    snr_db: float = 6.0,
    n_averages: int = 1,
    lag_s: float = 0.0,
    noise: bool = True,
) -> CubeScenario:
    """Simulate a normalised cube with one narrowband line moving in bearing.

    Parameters
    ----------
    seed : int
        Seed of ``np.random.default_rng``; same arguments, same cube.
    n_beams, n_scans, n_bins : int
        Cube shape (scans x beams x bins).
    scan_period_s : float
        Time between scans, s.
    aperture_m : float
        Line-array aperture ``L``, m.
    sound_speed : float
        Sound speed, m/s (wavelength ``lambda = c / line_freq_hz``).
    line_freq_hz : float
        Line frequency, Hz.
    bin_width_hz : float
        FFT bin spacing, Hz.
    line_offset_bins : float, optional
        Offset of the line from the centre of its bin, in bins, in ``[-0.5, 0.5]``; drawn uniformly
        when None. The bins are ``line_freq_hz - offset * bin_width_hz + (j - n_bins // 2) *
        bin_width_hz``.
    freq_spread_hz : float
        Standard deviation of the line's Gaussian spectral shape, Hz (>= 0).
    bearing0_deg : float
        True bearing at the first scan (time 0), deg from the forward axis.
    bearing_rate_deg_per_min : float
        Constant bearing rate, deg/min (either sign).
    snr_db : float
        Per-bin SNR, dB: the line's power summed over bins, at the peak of the main lobe, over the
        mean noise power of one bin (``10 log10(S / 1)`` since the noise has unit mean). A line
        that falls entirely in one bin on the beam steered at it raises that cell's mean from 1 to
        ``1 + S``.
    n_averages : int
        Periodogram looks averaged per cell (noise gamma with ``2 n_averages`` degrees of freedom).
    lag_s : float
        Spectral integration lag, s: the scan at time ``t`` shows the bearing at ``t - lag_s``.
    noise : bool
        False: every cell is its expected value ``1 + signal`` (a noise-free cube, already at unit
        noise mean, for known-answer checks; the random draws are made all the same, so the line's
        bin offset matches the noisy cube of the same seed).

    Returns
    -------
    CubeScenario

    Raises
    ------
    ValueError
        Non-positive sizes or physical parameters, non-finite values, an offset outside
        ``[-0.5, 0.5]``.

    Examples
    --------
    >>> sc = simulate_cube(seed=1, bearing0_deg=70.0, bearing_rate_deg_per_min=30.0)
    >>> sc.cube.power.shape
    (60, 64, 16)
    """
    for name, v in (("n_beams", n_beams), ("n_scans", n_scans), ("n_bins", n_bins),
                    ("n_averages", n_averages)):
        if int(v) != v or v < 1:
            raise ValueError(f"{name} must be a positive integer, got {v!r}")
    if n_beams < 2 or n_scans < 2:
        raise ValueError(f"need n_beams >= 2 and n_scans >= 2, got {n_beams}, {n_scans}")
    for name, v in (("scan_period_s", scan_period_s), ("aperture_m", aperture_m),
                    ("sound_speed", sound_speed), ("line_freq_hz", line_freq_hz),
                    ("bin_width_hz", bin_width_hz)):
        if not np.isfinite(v) or v <= 0:
            raise ValueError(f"{name} must be positive, got {v!r}")
    for name, v in (("freq_spread_hz", freq_spread_hz), ("lag_s", lag_s)):
        if not np.isfinite(v) or v < 0:
            raise ValueError(f"{name} must be >= 0, got {v!r}")
    for name, v in (("bearing0_deg", bearing0_deg),
                    ("bearing_rate_deg_per_min", bearing_rate_deg_per_min), ("snr_db", snr_db)):
        if not np.isfinite(v):
            raise ValueError(f"{name} must be finite, got {v!r}")
    rng = np.random.default_rng(seed)
    if line_offset_bins is None:
        line_offset_bins = float(rng.uniform(-0.5, 0.5))
    elif not (np.isfinite(line_offset_bins) and -0.5 <= line_offset_bins <= 0.5):
        raise ValueError(f"line_offset_bins must be in [-0.5, 0.5], got {line_offset_bins!r}")

    # frequency grid: the line sits line_offset_bins from the centre of bin n_bins // 2
    centre = line_freq_hz - line_offset_bins * bin_width_hz
    freqs = centre + (np.arange(n_bins) - n_bins // 2) * bin_width_hz
    if freqs[0] - 0.5 * bin_width_hz <= 0:
        raise ValueError("line_freq_hz too low for n_bins * bin_width_hz (non-positive bins)")
    spectrum = line_spectrum(freqs, bin_width_hz=bin_width_hz, line_freq_hz=line_freq_hz,
                             freq_spread_hz=freq_spread_hz)  # fraction of the power per bin

    # bearing track, true and as shown (lagged); folded into [0, pi] (cone angle)
    t = np.arange(n_scans) * scan_period_s
    rate = np.radians(bearing_rate_deg_per_min) / 60.0  # rad/s
    theta0 = np.radians(bearing0_deg)
    true_theta = np.arccos(np.cos(theta0 + rate * t))
    shown_theta = np.arccos(np.cos(theta0 + rate * (t - lag_s)))

    # beam pattern of a line array in cosine space: sinc^2(L (u_b - cos theta) / lambda)
    pattern = beam_pattern(shown_theta, n_beams=n_beams, aperture_m=aperture_m,
                           wavelength_m=sound_speed / line_freq_hz)  # (n_scans, n_beams)

    s_lin = 10.0 ** (snr_db / 10.0)
    sig_power = s_lin * pattern[:, :, None] * spectrum[None, None, :]  # (scans, beams, bins)
    power = noisy_power([sig_power], rng=rng, n_averages=n_averages, noise=noise)

    cube = Cube(power=power, freqs=freqs, scan_period=scan_period_s, aperture=aperture_m,
                sound_speed=sound_speed)
    beam_track = np.asarray(beam_from_bearing(shown_theta, n_beams))
    click_beam = int(np.clip(np.floor(beam_track[-1] + 0.5), 0, n_beams - 1))
    click_freq = float(freqs[int(np.argmin(np.abs(freqs - line_freq_hz)))])
    logger.debug("simulated cube %s, click beam %d at %.2f Hz", power.shape, click_beam, click_freq)
    return CubeScenario(
        cube=cube,
        bearing_deg=np.degrees(true_theta),
        shown_bearing_deg=np.degrees(shown_theta),
        beam_track=beam_track,
        bearing_rate_deg_per_min=float(bearing_rate_deg_per_min),
        snr_db=float(snr_db),
        line_freq_hz=float(line_freq_hz),
        click_beam=click_beam,
        click_freq=click_freq,
        lag_s=float(lag_s),
    )


def write_scenario(out_dir: Path, *, seed: int, vary: bool = False) -> list[Path]:
    """Write a high bearing-rate cube scenario: ``cube.npz`` and ``truth.json``.

    The scenario (a 35 deg/min line at 6 dB per-bin SNR, start bearing drawn from the seed) is the
    input of ``fusion acquire --cube cube.npz --beam B --freq-hz F`` with the click in ``truth.json``.

    A scenario writer (:mod:`fusion.simulate`: `out_dir`, `seed`, the written files returned).

    Parameters
    ----------
    vary : bool, optional
        A varied cube instead (:func:`fusion.simulate.cube_varied.simulate_varied_cube`: line
        frequency, rate, SNR, noise statistics and level, lag drawn from the seed); its draws go
        to ``truth.json`` under ``parameters``.
    """
    out_dir = Path(out_dir)
    if vary:
        sc = simulate_varied_cube(seed)
    else:
        rng = np.random.default_rng(seed)
        rate = 35.0 * (1.0 if rng.uniform() < 0.5 else -1.0)
        span = abs(rate) * 59.0 / 60.0  # degrees covered by 60 one-second scans
        start = rng.uniform(20.0 + (span if rate < 0 else 0.0),
                            160.0 - (span if rate > 0 else 0.0))
        sc = simulate_cube(seed=seed, bearing0_deg=start, bearing_rate_deg_per_min=rate,
                           snr_db=6.0)
    cube_path = write_cube(out_dir / "cube.npz", sc.cube)
    truth = {
        "bearing_deg": sc.latest_bearing_deg,
        "bearing_rate_deg_per_min": sc.bearing_rate_deg_per_min,
        "snr_db_per_bin": sc.snr_db,
        "line_freq_hz": sc.line_freq_hz,
        "click_beam": sc.click_beam,
        "click_freq": sc.click_freq,
        "lag_s": sc.lag_s,
        "bearing_per_scan_deg": sc.bearing_deg.tolist(),
        **({"vary": True, "parameters": sc.parameters} if vary else {}),
    }
    truth_path = write_json(out_dir / "truth.json", truth)
    return [cube_path, truth_path]
