"""SCM2 features of TDOA validation: the smoothed autocorrelation's moments and spectral peak.

Eq. (7)-(10) of *Localization of Short Duration Periodic Signals* (Baggenstoss, NUWC 102089),
paragraphs [0036]-[0037]: the four features of the second-order smoothed click map (SCM2) at a
TDOA's lag that :class:`fusion.clicks.validate.TdoaValidator` scores. The module notes of
:mod:`fusion.clicks.validate` give the choices where the method text is silent; these names are
importable from there too.
"""

from __future__ import annotations

import functools
import logging

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray

from fusion._validation import check_positive

__all__ = ["FEATURE_NAMES", "default_freqs_hz", "scm2_features"]

logger = logging.getLogger(__name__)

#: Order of the features in ``z`` (eq. 10): specmax (Hz), mu1 (s^2), sqrt(mu2)/mu1, cbrt(mu3)/mu1.
FEATURE_NAMES: tuple[str, ...] = ("specmax", "mu1", "mu2", "mu3")

_BLOCK = 16  # series per FFT block in scm2_features


def default_freqs_hz() -> NDArray[np.float64]:
    """The default *specmax* search grid: 0.5 to 20 Hz in 0.05 Hz steps, Hz."""
    return np.round(np.arange(0.5, 20.0 + 1e-9, 0.05), 10)



def scm2_features(
    series: ArrayLike,
    fs_syn: float,
    *,
    T: float | None = None,
    smooth_s: float = 0.02,
    freqs_hz: ArrayLike | None = None,
    decimate: int = 1,
) -> NDArray[np.float64]:
    """Validation features ``z = [specmax, mu1, mu2, mu3]`` of SCM2 series (eq. 7-10).

    Parameters
    ----------
    series : array_like, shape (N,) or (m, N)
        SCM2 time series (non-negative) on the synthetic grid, one per row.
    fs_syn : float
        Synthetic sample rate of the series, Hz (the method text's 3 kHz).
    T : float, optional
        Processing window, s; the ACF is integrated over lags ``0..T/4``. Default ``N / fs_syn``
        (12 s for the method text's 36000 samples at 3 kHz). ``T/4`` must be below the series
        length.
    smooth_s : float, optional
        Standard deviation of the Gaussian that smooths the ACF, s (0: no smoothing).
    freqs_hz : array_like, shape (n_f,), optional
        Positive frequencies searched for *specmax*, Hz; default :func:`default_freqs_hz`.
    decimate : int, optional
        Sum blocks of this many samples before the ACF (1: none). The smoothed ACF holds no
        energy above a few times ``1 / (2 pi smooth_s)``, so a block of up to about
        ``fs_syn * smooth_s / 6`` samples (10 at 3 kHz and 20 ms) changes the features by
        well under a percent while the FFTs shrink by the same factor.

    Returns
    -------
    ndarray, shape (4,) or (m, 4)
        ``[specmax (Hz), mu1 (s^2), sqrt(mu2)/mu1 (s^-1/2), cbrt(mu3)/mu1 (s^-1)]`` per series;
        a row of NaN for a series with no energy (all zero).

    Raises
    ------
    ValueError
        If `series` is not 1-D/2-D or holds non-finite values, or an option is out of range.

    Notes
    -----
    *Localization of Short Duration Periodic Signals*, eq. (7)-(10): with ``r(tau)`` the
    smoothed ACF normalised to ``r(0) = 1``, ``mu_p = int_0^{T/4} r(tau) tau^p dtau`` (trapezoid
    rule on the lag grid), and *specmax* = ``argmax_f int_0^{T/4} cos(2 pi f tau) r(tau) dtau``
    over `freqs_hz`. The ACF is computed for all rows at once by one zero-padded real FFT,
    long enough that the lags up to ``T/4`` and the smoothing's reach do not wrap around: the
    linear (non-circular) autocorrelation. On a uniform frequency grid ``f = m f_s / L`` (the
    default's), the cosine transform is the real part of a length-``L`` real FFT.
    """
    fs = check_positive("fs_syn", fs_syn)
    smooth = check_positive("smooth_s", smooth_s, allow_zero=True)
    x = np.asarray(series, dtype=float)
    if x.ndim not in (1, 2) or x.shape[-1] < 2:
        raise ValueError(f"series must have shape (N,) or (m, N) with N >= 2, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("series holds non-finite values")
    single = x.ndim == 1
    x2 = np.atleast_2d(x)
    d = int(decimate)
    if d < 1:
        raise ValueError(f"decimate must be a positive integer, got {decimate!r}")
    if d > 1:  # block sums: a box filter and a downsampling in one
        m = x2.shape[1] // d
        blocks = np.ascontiguousarray(x2[:, : m * d]).reshape(-1, d)
        x2 = (blocks @ np.ones(d)).reshape(x2.shape[0], m)  # a product: faster than .sum(axis)
        fs = fs / d
    n = x2.shape[1]
    window = n / fs if T is None else check_positive("T", T)
    n_lag = int(round(window / 4.0 * fs))  # lags 0..T/4 on the synthetic grid
    if not 1 <= n_lag < n:
        raise ValueError(f"T/4 = {window / 4.0} s must span 1..{n - 1} lags of the series")
    freqs = default_freqs_hz() if freqs_hz is None else np.asarray(freqs_hz, dtype=float).ravel()
    if freqs.size == 0 or not np.all(np.isfinite(freqs) & (freqs > 0)):
        raise ValueError("freqs_hz must be a non-empty array of positive frequencies")

    # zero padding: lags up to n_lag plus the smoothing's reach (10 standard deviations) must
    # not wrap around, which is all the linear autocorrelation needs here
    reach = int(np.ceil(10.0 * smooth * fs))
    nfft = scipy.fft.next_fast_len(min(n + n_lag + reach + 1, 2 * n - 1), real=True)
    taper = np.exp(-2.0 * (np.pi * smooth * scipy.fft.rfftfreq(nfft, 1.0 / fs)) ** 2)
    tau = np.arange(n_lag + 1) / fs
    w = np.full(n_lag + 1, 1.0 / fs)  # trapezoid weights on the lag grid
    w[[0, -1]] /= 2.0
    moment_w = w[:, None] * np.stack([tau, tau**2, tau**3], axis=1)  # eq. (7), p = 1, 2, 3
    grid = _uniform_grid(freqs, fs, n_lag)
    cosine_w = None if grid is not None else _cosine_weights(fs, n_lag, freqs.tobytes())  # eq. (9)

    empty = ~np.any(x2 != 0.0, axis=1)
    mu = np.empty((x2.shape[0], 3))
    specmax = np.empty(x2.shape[0])
    # (no thread-pool limit here: finding the BLAS libraries costs more than these small products)
    for i in range(0, x2.shape[0], _BLOCK):  # blocks keep the FFT work in cache
        r, r0 = _smoothed_acf(x2[i : i + _BLOCK], nfft, taper, n_lag)
        mu[i : i + _BLOCK] = r @ moment_w
        if grid is None:
            spec = r @ cosine_w
        else:  # eq. (9) on a uniform grid f = m df: a real FFT of length fs / df
            length, m_idx = grid
            spec = scipy.fft.rfft(r * w, length, axis=1).real[:, m_idx]
        specmax[i : i + _BLOCK] = freqs[np.argmax(spec, axis=1)]
        empty[i : i + _BLOCK] |= ~(r0 > 0.0)

    mu1 = mu[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.stack(
            [specmax, mu1, np.sqrt(np.maximum(mu[:, 1], 0.0)) / mu1, np.cbrt(mu[:, 2]) / mu1],
            axis=1,
        )  # eq. (8), (10)
    z[empty] = np.nan
    if np.any(empty):
        logger.debug("%d SCM2 series without energy get NaN features", int(empty.sum()))
    return z[0] if single else z


def _uniform_grid(freqs: NDArray, fs: float, n_lag: int) -> tuple[int, NDArray[np.int64]] | None:
    """``(L, m)`` when ``freqs = m fs / L`` for integers ``m <= L / 2`` and a length ``L`` of at
    least ``n_lag + 1`` (so that ``sum_tau x(tau) cos(2 pi f tau)`` is the real part of bins
    `m` of a length-``L`` real FFT); None otherwise."""
    if freqs.size < 2:
        return None
    df = freqs[1] - freqs[0]
    if not df > 0:
        return None
    length = fs / df
    m = freqs / df
    if (abs(length - round(length)) > 1e-6 or np.any(np.abs(m - np.round(m)) > 1e-6)
            or round(length) < n_lag + 1 or round(length) > 1 << 20):
        return None
    m_idx = np.round(m).astype(np.int64)
    if np.any(m_idx < 0) or np.any(m_idx > round(length) // 2):
        return None
    return int(round(length)), m_idx


@functools.lru_cache(maxsize=2)
def _cosine_weights(fs: float, n_lag: int, freqs_bytes: bytes) -> NDArray[np.float64]:
    """``cos(2 pi f tau) w(tau)``, shape (n_lag + 1, n_f), trapezoid weights ``w`` (cached, read-only)."""
    freqs = np.frombuffer(freqs_bytes, dtype=float)
    tau = np.arange(n_lag + 1) / fs
    w = np.full(n_lag + 1, 1.0 / fs)
    w[[0, -1]] /= 2.0
    out = np.cos(2.0 * np.pi * np.outer(tau, freqs)) * w[:, None]
    out.setflags(write=False)
    return out


def _smoothed_acf(x: NDArray[np.float64], nfft: int, taper: NDArray[np.float64],
                  n_lag: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """ACF of each row for lags ``0..n_lag``, smoothed, normalised to ``r(0) = 1``; and ``r(0)``."""
    power = np.abs(scipy.fft.rfft(x, nfft, axis=1)) ** 2  # padded: linear at the lags used
    acf = scipy.fft.irfft(power * taper, nfft, axis=1)[:, : n_lag + 1]
    r0 = acf[:, 0].copy()
    return acf / np.where(r0 > 0.0, r0, 1.0)[:, None], r0
