"""The click band, from the averaged click (step 32: "a range of frequencies for the signal of
interest").

The method's detector sums the normalised spectrogram power over "the frequency bands in which
the beaked whale energy lies (14-40 kHz)", bands "selected for experimental data in the
initialization step" ([0030]). :func:`click_band` makes that selection from data: the band of an
averaged click (the replica estimated from the recording's high-SNR clicks by
:func:`fusion.clicks.replica.estimate_replica`) where its energy spectrum lies within `drop_db`
of its peak, from the lowest to the highest such frequency, bounded by the Nyquist frequency.
:func:`detection_band` widens that band, about its centre and within the same bounds, to at
least the width of the method's band (26 kHz): the detector's threshold
(:data:`fusion.clicks.detect.DEFAULT_THRESHOLD`) was set for a sum over that many spectrogram
bins, and a narrower sum of fewer bins has a heavier noise tail (a 38-46 kHz band, two bins of
the 24-point spectrogram at 96 kHz, passed about 20 noise peaks per channel-second in a test).

Examples
--------
>>> import numpy as np
>>> fs = 96_000.0
>>> t = np.arange(-48, 49) / fs
>>> tone = np.cos(np.pi * t / 1e-3) ** 2 * np.cos(2 * np.pi * 30_000.0 * t)
>>> lo, hi = click_band(tone, fs)
>>> bool(26_000 < lo < 30_000 < hi < 34_000)
True
"""

from __future__ import annotations

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike

__all__ = ["BAND_DROP_DB", "DEFAULT_BAND_HZ", "MIN_BAND_WIDTH_HZ", "NYQUIST_FRACTION",
           "click_band", "detection_band"]

#: Detection band without an estimate, Hz: the method's (beaked whales, [0030]).
DEFAULT_BAND_HZ = (14_000.0, 40_000.0)
#: Narrowest detection band, Hz: the width of :data:`DEFAULT_BAND_HZ`, for which the detection
#: threshold was set.
MIN_BAND_WIDTH_HZ = DEFAULT_BAND_HZ[1] - DEFAULT_BAND_HZ[0]
#: Level below the peak of the averaged click's energy spectrum that bounds its band, dB.
BAND_DROP_DB = 10.0
#: Highest upper band edge, as a fraction of the Nyquist frequency (the detector needs the upper
#: edge below fs / 2).
NYQUIST_FRACTION = 0.95
#: Frequency points of the zero-padded spectrum (at least).
_MIN_FFT = 4096


def click_band(
    samples: ArrayLike, fs: float, *, drop_db: float = BAND_DROP_DB,
    nyquist_fraction: float = NYQUIST_FRACTION,
) -> tuple[float, float]:
    """The band of a click: where its energy spectrum is within `drop_db` of its peak.

    Parameters
    ----------
    samples : array_like, shape (n,)
        The click (e.g. an estimated replica), at `fs`.
    fs : float
        Sample rate, Hz.
    drop_db : float, optional
        Level below the spectrum's peak that bounds the band, dB (> 0).
    nyquist_fraction : float, optional
        The upper edge is at most this fraction of ``fs / 2`` (in (0, 1)).

    Returns
    -------
    (float, float)
        ``(low, high)``, Hz: the lowest and highest frequencies (linearly interpolated between
        spectrum points) at which the energy spectrum reaches ``peak - drop_db``; every
        frequency between them counts, so a spectrum with a dip inside keeps one band.

    Raises
    ------
    ValueError
        Samples not 1-D, not finite or all zero; bad `fs`, `drop_db` or `nyquist_fraction`; a
        click whose band lies wholly above the bound.
    """
    x = np.asarray(samples, dtype=float)
    if x.ndim != 1 or x.size < 3:
        raise ValueError(f"samples must be 1-D with >= 3 samples, got shape {x.shape}")
    if not np.all(np.isfinite(x)) or not np.any(x):
        raise ValueError("samples must be finite and not all zero")
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"fs must be positive, got {fs!r}")
    if not (np.isfinite(drop_db) and drop_db > 0):
        raise ValueError(f"drop_db must be positive, got {drop_db!r}")
    if not 0 < nyquist_fraction < 1:
        raise ValueError(f"nyquist_fraction must lie in (0, 1), got {nyquist_fraction!r}")
    n = max(_MIN_FFT, scipy.fft.next_fast_len(8 * x.size))
    power = np.abs(scipy.fft.rfft(x, n)) ** 2
    freqs = np.arange(power.size) * fs / n
    level = power.max() * 10.0 ** (-drop_db / 10.0)
    above = np.flatnonzero(power >= level)
    i, j = int(above[0]), int(above[-1])

    def cross(a: int, b: int) -> float:  # frequency where power crosses level between a and b
        pa, pb = power[a], power[b]
        return float(freqs[a] + (level - pa) / (pb - pa) * (freqs[b] - freqs[a]))

    lo = float(freqs[i]) if i == 0 else cross(i - 1, i)
    hi = float(freqs[j]) if j == power.size - 1 else cross(j, j + 1)
    top = nyquist_fraction * 0.5 * fs
    if lo >= top:
        raise ValueError(f"the click's band starts at {lo:g} Hz, above {top:g} Hz "
                         f"({nyquist_fraction:g} of the Nyquist frequency)")
    return lo, min(hi, top)


def detection_band(
    samples: ArrayLike, fs: float, *, drop_db: float = BAND_DROP_DB,
    min_width_hz: float = MIN_BAND_WIDTH_HZ, nyquist_fraction: float = NYQUIST_FRACTION,
) -> tuple[float, float]:
    """The detection band of a click: its :func:`click_band`, widened to `min_width_hz`.

    A band narrower than `min_width_hz` is widened about its centre; where that passes
    ``nyquist_fraction * fs / 2`` (or 0 Hz) it is shifted down (up) to end there. A band the
    spectrum can hold no `min_width_hz` of is ``(0, nyquist_fraction * fs / 2)``.

    Parameters
    ----------
    samples, fs, drop_db, nyquist_fraction
        As :func:`click_band`.
    min_width_hz : float, optional
        Narrowest band, Hz (>= 0).

    Returns
    -------
    (float, float)
        ``(low, high)``, Hz.
    """
    if not (np.isfinite(min_width_hz) and min_width_hz >= 0):
        raise ValueError(f"min_width_hz must be >= 0, got {min_width_hz!r}")
    lo, hi = click_band(samples, fs, drop_db=drop_db, nyquist_fraction=nyquist_fraction)
    if hi - lo >= min_width_hz:
        return lo, hi
    top = nyquist_fraction * 0.5 * fs
    if min_width_hz >= top:
        return 0.0, top
    mid = 0.5 * (lo + hi)
    lo = min(max(mid - 0.5 * min_width_hz, 0.0), top - min_width_hz)
    return lo, lo + min_width_hz
