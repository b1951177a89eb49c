"""Waveform helpers of the replica stage: fractional delay, resampling about a centre sample,
and the peak normalised cross-correlation (public through :mod:`fusion.clicks.replica`)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import scipy.fft
import scipy.signal
from numpy.typing import ArrayLike, NDArray

__all__ = ["fourier_shift", "peak_correlation", "resample_replica"]


def fourier_shift(x: ArrayLike, shift: ArrayLike, *, axis: int = -1) -> NDArray[np.float64]:
    """Delay `x` by a (fractional) number of samples with a zero-padded Fourier phase ramp.

    Parameters
    ----------
    x : array_like, shape (..., n)
        Signals along `axis`.
    shift : float or array_like broadcastable to x without `axis`
        Delay, samples: ``out[k] ~ x[k - shift]`` (band-limited interpolation).
    axis : int, optional
        Time axis.

    Returns
    -------
    ndarray, same shape as `x`
        Shifted signals; samples shifted in from outside are zero (padding, not wrap-around).
    """
    a = np.moveaxis(np.asarray(x, dtype=float), axis, -1)
    s = np.asarray(shift, dtype=float)[..., None]
    n = a.shape[-1]
    pad = int(np.ceil(np.max(np.abs(s)))) + 1 if s.size else 1
    m = scipy.fft.next_fast_len(n + 2 * pad, real=True)
    spec = scipy.fft.rfft(a, m, axis=-1)
    f = np.arange(spec.shape[-1]) / m
    out = scipy.fft.irfft(spec * np.exp(-2j * np.pi * f * s), m, axis=-1)[..., :n]
    return np.moveaxis(out, -1, axis)


def resample_replica(samples: ArrayLike, fs_from: float, fs_to: float) -> NDArray[np.float64]:
    """Resample a replica to another sample rate, keeping its centre on the middle sample.

    Parameters
    ----------
    samples : array_like, shape (N,)
        Replica at `fs_from`, centred on sample ``(N - 1) // 2``.
    fs_from, fs_to : float
        Sample rates, Hz.

    Returns
    -------
    ndarray, shape (M,)
        Unit-energy replica at `fs_to`, M odd, centred on the middle sample.

    Notes
    -----
    Polyphase resampling (:func:`scipy.signal.resample_poly`, anti-alias filtered) at the
    rational ratio nearest ``fs_to / fs_from``, then a fractional Fourier shift that puts the
    original centre time on the middle output sample.
    """
    r = np.asarray(samples, dtype=float)
    for name, v in (("fs_from", fs_from), ("fs_to", fs_to)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be positive, got {v!r}")
    if r.ndim != 1 or r.size < 3 or not np.all(np.isfinite(r)):
        raise ValueError(f"replica must be 1-D, finite, >= 3 samples, got shape {r.shape}")
    h_in = (r.size - 1) // 2
    ratio = Fraction(fs_to / fs_from).limit_denominator(1000)
    if ratio == 1:
        out = r.copy()
    else:
        up, down = ratio.numerator, ratio.denominator
        y = scipy.signal.resample_poly(r, up, down)
        p = h_in * up / down  # output index of the input's centre time
        half = int(np.ceil(max(p, y.size - 1 - p)))
        buf = np.zeros(2 * half + 1)
        buf[: min(y.size, buf.size)] = y[: buf.size]
        out = fourier_shift(buf, half - p)
    return out / np.linalg.norm(out)


def peak_correlation(a: ArrayLike, b: ArrayLike, *, upsample: int = 16) -> float:
    """Peak of the normalised cross-correlation of two waveforms over sub-sample lags.

    Parameters
    ----------
    a, b : array_like, shape (n,), (m,)
        Waveforms at one sample rate.
    upsample : int, optional
        Lag resolution is ``1 / upsample`` sample (zero-padded cross-spectrum).

    Returns
    -------
    float
        ``max_tau sum_t a(t) b(t + tau) / (|a| |b|)``, in ``[-1, 1]``.
    """
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    na, nb = np.linalg.norm(x), np.linalg.norm(y)
    if x.ndim != 1 or y.ndim != 1 or na == 0 or nb == 0:
        raise ValueError("peak_correlation needs two non-zero 1-D waveforms")
    m = scipy.fft.next_fast_len(x.size + y.size, real=True)
    cross = np.conj(scipy.fft.rfft(x, m)) * scipy.fft.rfft(y, m)
    cc = scipy.fft.irfft(cross, m * upsample) * upsample
    return float(cc.max() / (na * nb))
