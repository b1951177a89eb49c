"""Program segment 52 of the acquisition method: band noise level, IBW SNR and SNR in 1 Hz.

The band noise level is the mean BTR value off the best line (:func:`band_noise_level`); the
linear IBW SNR is ``(S+N - N) / N``; eq. 4 of the method text, whose factors were lost, is
reconstructed as SNR per bin ``~ snr_ibw * nbins_ibw`` (the target occupies about one of the
averaged bins) and SNR in 1 Hz ``= SNR_bin * dfbin * 1.3`` (Hamming equivalent noise bandwidth),
in dB (:func:`snr_1hz_db`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["HAMMING_ENBW", "band_noise_level", "snr_1hz_db"]

#: Equivalent noise bandwidth of a Hamming window, in bins (the method's eq. 4 factor).
HAMMING_ENBW = 1.3


def band_noise_level(
    btr_latest_first: ArrayLike,
    anchor: float,
    slope: float = 0.0,
    *,
    exclude_beams: float,
    track: ArrayLike | None = None,
) -> float:
    """Mean BTR value off the target's trace (program segment 52).

    Parameters
    ----------
    btr_latest_first : array_like, shape (n_scans, n_beams)
        IBW BTR, row 0 the latest update.
    anchor : float
        Anchor beam of the best line (ignored when `track` is given).
    slope : float
        Slope of the best line, beams per update going back in time (ignored when `track` is
        given).
    exclude_beams : float
        Cells within this many beams of the line (extended over every scan) are left out.
    track : array_like, shape (n_scans,), optional
        Fractional beam of the trace at every scan, latest first (a curved trace); default the
        straight line ``anchor + slope * iscan``.

    Returns
    -------
    float
        Band noise level (linear).

    Raises
    ------
    ValueError
        When no cell is left, or `track` has the wrong length.
    """
    btr = np.asarray(btr_latest_first, dtype=float)
    n_scans, n_beams = btr.shape
    if track is None:
        line = anchor + slope * np.arange(n_scans)
    else:
        line = np.asarray(track, dtype=float).reshape(-1)
        if line.size != n_scans:
            raise ValueError(f"track must have {n_scans} positions, got {line.size}")
    off = np.abs(np.arange(n_beams)[None, :] - line[:, None]) > exclude_beams
    if not off.any():
        raise ValueError(
            f"no BTR cell lies off the target's trace ({n_beams} beams, {exclude_beams:.1f} "
            "beams excluded each side): cannot estimate the band noise level"
        )
    return float(btr[off].mean())


def snr_1hz_db(snr_ibw: float, nbins_ibw: int, bin_width_hz: float) -> float:
    """SNR in a 1 Hz band from the linear IBW SNR (eq. 4 of the method text, reconstructed).

    Parameters
    ----------
    snr_ibw : float
        Linear SNR in the IBW, ``(S+N - N) / N`` (> 0).
    nbins_ibw : int
        Bins in the IBW.
    bin_width_hz : float
        Bin spacing, Hz.

    Returns
    -------
    float
        ``10 log10(snr_ibw * nbins_ibw * bin_width_hz * HAMMING_ENBW)``, dB.

    Examples
    --------
    >>> round(snr_1hz_db(4.0, 1, 1.0), 3)
    7.16
    """
    snr_1hz = snr_ibw * nbins_ibw * bin_width_hz * HAMMING_ENBW  # eq. 4 (reconstructed)
    return 10.0 * math.log10(snr_1hz)
