"""The pieces of a simulated beam/frequency/time cube: its record, line spectrum, beam pattern, noise.

Shared by the fixed cube (:mod:`fusion.simulate.cube`) and the varied one
(:mod:`fusion.simulate.cube_varied`); importable from :mod:`fusion.simulate.cube`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtr

from fusion.io import Cube

__all__ = ["CubeScenario", "beam_pattern", "line_spectrum", "noisy_power"]


@dataclass(frozen=True)
class CubeScenario:
    """A simulated cube and its ground truth.

    Attributes
    ----------
    cube : fusion.io.Cube
        Power, shape (n_scans, n_beams, n_bins), noise mean 1; frequencies, scan period, aperture,
        sound speed.
    bearing_deg : ndarray, shape (n_scans,)
        True bearing from the forward axis at each scan time, deg, in ``[0, 180]``.
    shown_bearing_deg : ndarray, shape (n_scans,)
        Bearing the spectra show at each scan (the true bearing ``lag_s`` earlier), deg.
    beam_track : ndarray, shape (n_scans,)
        Fractional beam of the shown bearing at each scan (cosine spacing).
    bearing_rate_deg_per_min : float
        True bearing rate, deg/min.
    snr_db : float
        Per-bin SNR of the line (see :func:`simulate_cube`), dB.
    line_freq_hz : float
        Frequency of the line, Hz.
    click_beam : int
        Beam an operator would click at the latest scan: the beam nearest the shown bearing.
    click_freq : float
        Centre frequency of the bin an operator would click: the bin nearest the line, Hz.
    lag_s : float
        Spectral integration lag, s.
    parameters : dict
        Draws of a varied cube (:mod:`fusion.simulate.cube_varied`); empty otherwise. Truth,
        for diagnosis only.
    """

    cube: Cube
    bearing_deg: NDArray[np.float64]
    shown_bearing_deg: NDArray[np.float64]
    beam_track: NDArray[np.float64]
    bearing_rate_deg_per_min: float
    snr_db: float
    line_freq_hz: float
    click_beam: int
    click_freq: float
    lag_s: float
    parameters: dict = field(default_factory=dict)

    @property
    def latest_bearing_deg(self) -> float:
        """True bearing at the latest scan, deg."""
        return float(self.bearing_deg[-1])


def line_spectrum(
    freqs: NDArray[np.float64], *, bin_width_hz: float, line_freq_hz: float, freq_spread_hz: float
) -> NDArray[np.float64]:
    """Fraction of a narrowband line's power in each FFT bin.

    Parameters
    ----------
    freqs : ndarray, shape (n_bins,)
        Bin centre frequencies, Hz, equally spaced by `bin_width_hz`.
    bin_width_hz : float
        Bin spacing, Hz.
    line_freq_hz : float
        Line frequency, Hz.
    freq_spread_hz : float
        Standard deviation of the line's Gaussian spectral shape, Hz; 0 puts all the power in
        the bin whose centre is nearest the line.

    Returns
    -------
    ndarray, shape (n_bins,)
        The Gaussian integrated over each bin (sums to 1 when the line lies well inside the band).
    """
    if freq_spread_hz > 0:
        edges = np.concatenate([freqs - 0.5 * bin_width_hz, [freqs[-1] + 0.5 * bin_width_hz]])
        return np.diff(ndtr((edges - line_freq_hz) / freq_spread_hz))
    spectrum = np.zeros(freqs.size)
    spectrum[int(np.argmin(np.abs(freqs - line_freq_hz)))] = 1.0
    return spectrum


def beam_pattern(
    theta: NDArray[np.float64], *, n_beams: int, aperture_m: float, wavelength_m: float
) -> NDArray[np.float64]:
    """Power response of every beam of a uniformly weighted line array to sources at `theta`.

    Parameters
    ----------
    theta : ndarray, shape (n,)
        Source bearings from the forward axis, rad.
    n_beams : int
        Beams equally spaced in cosine, beam 0 at forward endfire.
    aperture_m, wavelength_m : float
        Aperture ``L`` and wavelength ``lambda``, m.

    Returns
    -------
    ndarray, shape (n, n_beams)
        ``sinc^2(L (u_b - cos theta) / lambda)`` with ``u_b = 1 - 2 b / (N - 1)``.
    """
    u_beams = 1.0 - 2.0 * np.arange(n_beams) / (n_beams - 1)
    return np.sinc(aperture_m / wavelength_m * (u_beams[None, :] - np.cos(theta)[:, None])) ** 2


def noisy_power(
    signal_powers: list[NDArray[np.float64]],
    *,
    rng: np.random.Generator,
    n_averages: int = 1,
    noise: bool = True,
) -> NDArray[np.float64]:
    """Cell power of narrowband lines in unit-power noise, averaged over periodogram looks.

    Parameters
    ----------
    signal_powers : list of ndarray, each shape (n_scans, n_beams, n_bins)
        Mean power of each line in every cell (noise power 1).
    rng : numpy.random.Generator
        Source of the phases and the noise; drawn in the same order whether or not `noise`.
    n_averages : int
        Periodogram looks averaged per cell.
    noise : bool
        False: the expected value ``1 + sum of the lines' powers`` (no randomness in the result).

    Returns
    -------
    ndarray, shape (n_scans, n_beams, n_bins)
        Each look is ``|sum_i sqrt(P_i) exp(j phi_i) + n|^2`` with an independent uniform phase per
        line and look and ``n`` circular complex Gaussian of unit power; the looks are averaged.
    """
    shape = (n_averages, *signal_powers[0].shape)
    field = np.zeros(shape, dtype=complex)
    for sig_power in signal_powers:
        phase = rng.uniform(0.0, 2.0 * np.pi, size=shape)
        field += np.sqrt(sig_power)[None] * np.exp(1j * phase)
    white = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2.0)
    if not noise:
        return 1.0 + np.sum(signal_powers, axis=0)
    return (np.abs(field + white) ** 2).mean(axis=0)
