"""Kernel design of the click detector: one FIR per STFT bin of the replica-correlated signal,
the whitened replica of the envelope formulation and the STFT window's smoothing.

Replica correlation (eq. 1) followed by a Hann-windowed DFT is linear, so bin ``k`` of frame
``J`` is a single FIR of the raw input, ``Y_k(J) = sum_m G_k[m] x[hop J - h + m]`` with
``G_k = (w e^{-i 2 pi k n / nfft}) * r`` (full convolution, ``h`` the replica's centre).
"""

from __future__ import annotations

import numpy as np
import scipy.signal
import scipy.stats
from numpy.typing import NDArray

from fusion.clicks._frames import KernelBank

__all__ = ["DetectorKernels"]


class DetectorKernels:
    """Kernel banks and constants of one detector at one sample rate.

    Parameters
    ----------
    r : ndarray, shape (N,)
        Replica at `fs`, centred on sample ``(N - 1) // 2``.
    fs : float
        Sample rate, Hz.
    nfft, hop : int
        STFT size and hop, samples (`hop` divides `nfft`).
    band_hz : (float, float)
        Band of the detection statistic, Hz.
    """

    def __init__(self, r: NDArray[np.float64], fs: float, *, nfft: int, hop: int,
                 band_hz: tuple[float, float]) -> None:
        h = (r.size - 1) // 2
        n = np.arange(nfft)
        win = scipy.signal.get_window("hann", nfft)  # periodic: centre at nfft / 2
        self.fs, self.hop, self.centre = fs, hop, nfft // 2
        self.freqs = np.arange(nfft // 2 + 1) * fs / nfft
        lo, hi = band_hz
        self.band = np.flatnonzero((self.freqs >= lo) & (self.freqs <= hi))
        if self.band.size == 0:
            raise ValueError(f"band_hz {band_hz} holds no STFT bin at fs={fs} Hz, nfft={nfft}")
        # one FIR per bin: G_k = (w e^{-i w_k n}) * r, frame J reads x[hop J - h + m]
        cols = []
        for k in range(self.freqs.size):
            g = np.convolve(win * np.exp(-2j * np.pi * k * n / nfft), r)
            cols += [g.real, g.imag]
        full = np.column_stack(cols)
        band_cols = np.ravel(np.column_stack([2 * self.band, 2 * self.band + 1]))
        # envelope: whitened band-limited replica, all hop phases of a row
        kern = _whitened_replica(r, fs, (lo, hi), fs / nfft, r.size + nfft)
        h_env = (kern.size - 1) // 2
        phases = nfft // hop  # frames per row: rows of nfft samples
        self.full = KernelBank.layout(full, h, hop)
        self.stft = KernelBank.layout(full[:, band_cols], h, hop, phases)
        self.env = KernelBank.layout(kern[:, None], h_env, 1, nfft)  # full-rate y_b
        v = win**2 / np.sum(win**2)
        self.smooth = KernelBank.layout(v[:, None], 0, hop, phases)  # sum_n v_n y_b^2
        self.env_median_to_mean = _median_to_mean(kern, v)
        self.span = max(self.full.taps, self.stft.taps, self.env.taps + nfft) + h_env  # samples


def _whitened_replica(
    r: NDArray[np.float64], fs: float, band: tuple[float, float], edge_hz: float, length: int
) -> NDArray[np.float64]:
    """The replica with a flat magnitude over `band` (raised-cosine edges `edge_hz` wide) and
    its own phase: correlating with it is the matched filter followed by the whitening that
    per-bin normalisation applies to white noise. Odd `length`, centred, Tukey-tapered."""
    length += 1 - length % 2
    m = 4096
    h = (r.size - 1) // 2
    spec = np.fft.rfft(np.roll(np.pad(r, (0, m - r.size)), -h))  # phase about the centre
    f = np.fft.rfftfreq(m, 1.0 / fs)
    lo, hi = band
    ramp = lambda u: np.sin(0.5 * np.pi * np.clip(u, 0.0, 1.0)) ** 2  # noqa: E731
    mask = ramp((f - lo + edge_hz) / edge_hz) * ramp((hi + edge_hz - f) / edge_hz)
    mag = np.abs(spec)
    phase = np.divide(spec, mag, out=np.zeros_like(spec), where=mag > 0)
    k = np.roll(np.fft.irfft(mask * phase, m), length // 2)[:length]
    k *= scipy.signal.windows.tukey(length, 0.5)
    return k / np.linalg.norm(k)


def _median_to_mean(kern: NDArray[np.float64], v: NDArray[np.float64]) -> float:
    """Median over mean of ``sum_n v_n y_n^2`` for y = white noise correlated with `kern`: a
    gamma law with the Satterthwaite shape ``(sum lambda)^2 / sum lambda^2`` of the quadratic
    form's eigenvalues."""
    n = v.size
    acf = np.correlate(kern, kern, "full")[kern.size - 1:]
    lag = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    cov = np.where(lag < acf.size, acf[np.minimum(lag, acf.size - 1)], 0.0)
    sv = np.sqrt(v)
    lam = np.linalg.eigvalsh(sv[:, None] * cov * sv[None, :])
    shape = lam.sum() ** 2 / np.sum(lam**2)
    return float(scipy.stats.gamma(shape).median() / shape)
