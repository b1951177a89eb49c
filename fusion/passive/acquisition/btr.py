"""Program segments 26-28 of the acquisition method: the initialisation band (IBW) and its BTR.

The bins of the IBW around the operator's clicked frequency (:func:`ibw_bins`) and the
bearing-time record of their mean power per scan and beam (:func:`ibw_btr`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["ibw_bins", "ibw_btr"]


def ibw_bins(freqs: ArrayLike, freq_hz: float, ibw_hz: float | None = None) -> NDArray[np.intp]:
    """Indices of the bins of the initialisation band (IBW) centred on the clicked frequency.

    Parameters
    ----------
    freqs : array_like, shape (n_bins,)
        Bin centre frequencies, Hz, increasing.
    freq_hz : float
        Clicked frequency, Hz.
    ibw_hz : float, optional
        IBW width, Hz. Bins whose centre lies within ``ibw_hz / 2`` of `freq_hz` are in the band;
        the bin nearest `freq_hz` always is. None: that bin alone.

    Returns
    -------
    ndarray of int, shape (nbins_ibw,)
        Increasing bin indices.
    """
    f = np.asarray(freqs, dtype=float).reshape(-1)
    nearest = int(np.argmin(np.abs(f - freq_hz)))
    if ibw_hz is None:
        return np.array([nearest], dtype=np.intp)
    sel = np.abs(f - freq_hz) <= 0.5 * ibw_hz * (1.0 + 1e-9)
    sel[nearest] = True
    return np.flatnonzero(sel).astype(np.intp)


def ibw_btr(normalized_band: ArrayLike) -> NDArray[np.float64]:
    """IBW bearing-time record: the mean over the band's bins of each scan and beam.

    Parameters
    ----------
    normalized_band : array_like, shape (n_scans, n_beams, nbins_ibw)
        Normalised power of the IBW bins.

    Returns
    -------
    ndarray, shape (n_scans, n_beams)
        Estimates of normalised signal-plus-noise power in the IBW (program segment 28).
    """
    return np.asarray(normalized_band, dtype=float).mean(axis=-1)
