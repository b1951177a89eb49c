"""The detection statistic of :class:`fusion.clicks.detect.ClickDetector` computed on frames.

The STFT band sum over the per-bin background (or the smoothed squared envelope) over chunks of
frames that stay in cache, the centre frequency of eq. (2) at given frames, and the finiteness
test of the input (*Localization of Short Duration Periodic Signals*, Baggenstoss, NUWC 102089,
paragraphs [0030]-[0031]). The detector's module notes give the formulation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fusion.clicks._frames import CHUNK, framed_filter, gather_frames
from fusion.clicks._kernels import DetectorKernels

__all__ = ["all_finite", "centre_frequency", "checked_input", "chunked_statistic",
           "smoothed_envelope"]


def chunked_statistic(
    x: NDArray[np.floating],
    s0: int,
    j_a: int,
    n_frames: int,
    k: DetectorKernels,
    coef: NDArray[np.float32] | None,
    left: NDArray[np.int64],
    wgt: NDArray[np.float64],
    *,
    nfft: int,
) -> NDArray[np.float32]:
    """Statistic over chunks of frames that stay in cache: the STFT band sum with per-bin
    weights `coef` (ch, nodes, 2 n_band) interpolated between nodes, or (``coef=None``) the
    smoothed squared envelope; (ch, n_frames) float32. `nfft` is the STFT size."""
    n_ch = x.shape[1]
    out = np.empty((n_ch, n_frames), dtype=np.float32)
    for a in range(0, n_frames, CHUNK):
        b = min(a + CHUNK, n_frames)
        if coef is None:
            out[:, a:b] = smoothed_envelope(x, s0, j_a + a, b - a, k, nfft=nfft)
            continue
        y = framed_filter(x, s0, j_a + a, b - a, k.stft)
        y *= y
        last = coef.shape[1] - 1
        i0, i1 = int(left[a]), int(min(left[b - 1] + 1, last))
        z = y @ np.swapaxes(coef[:, i0:i1 + 1], 1, 2)  # (ch, L, nodes in chunk)
        w = wgt[a:b].astype(np.float32)
        if i1 - i0 <= 1 and left[b - 1] == i0:  # one node interval: z_l + w (z_r - z_l)
            zl, zr = z[..., 0], z[..., i1 - i0]
            out[:, a:b] = zl + w * (zr - zl)
            continue
        rng = np.arange(b - a)
        zl = z[:, rng, left[a:b] - i0]
        zr = z[:, rng, np.minimum(left[a:b] + 1, last) - i0]
        out[:, a:b] = zl + w * (zr - zl)
    return out


def smoothed_envelope(x: NDArray[np.floating], s0: int, j0: int, count: int,
                      k: DetectorKernels, *, nfft: int) -> NDArray[np.float32]:
    """The smoothed squared envelope at `count` consecutive frames from `j0` (ch, count)."""
    hop = k.hop
    # y_b at full rate over the frames and their nfft-sample windows
    n_smp = hop * count + nfft
    y = framed_filter(x, s0, hop * j0, n_smp, k.env)[:, :, 0]
    y *= y
    # sum_n v_n y_b^2(hop J + n), with y_b^2 as a signal starting at the first frame
    return framed_filter(y.T, hop * j0, j0, count, k.smooth)[:, :, 0]


def centre_frequency(
    x: NDArray[np.floating],
    s0: int,
    frames: NDArray[np.int64],
    at: NDArray[np.int64],
    k: DetectorKernels,
    bg: NDArray[np.float64],
    left: NDArray[np.int64],
    wgt: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Eq. (2) at frames ``frames[at]`` of one channel `x` (n, 1): mean frequency weighted
    by the power above the (interpolated) per-bin background, bins inside (0, fs/2)."""
    spec = gather_frames(x, s0, frames[at], k.full)[0]
    p = spec[:, 0::2] ** 2 + spec[:, 1::2] ** 2  # (m, n_bins)
    right = np.minimum(left[at] + 1, bg.shape[0] - 1)
    w = wgt[at, None]
    b = bg[left[at]] * (1.0 - w) + bg[right] * w
    inner = (k.freqs > 0) & (k.freqs < 0.5 * k.fs)
    excess = np.maximum(p / b - 1.0, 0.0)[:, inner]
    tot = excess.sum(axis=1)
    fc = excess @ k.freqs[inner]  # eq. (2): sum |X_k|^2 f_k / sum |X_k|^2
    return np.divide(fc, tot, out=np.zeros_like(fc), where=tot > 0)


def all_finite(x: NDArray[np.number]) -> bool:
    """Whether every sample is finite (a finite sum decides it without a pass of its own over
    an array of flags; an overflowing sum falls back to the test of every sample)."""
    with np.errstate(over="ignore", invalid="ignore"):
        if np.isfinite(np.sum(x)):
            return True
    return bool(np.isfinite(x).all())


def checked_input(samples, t0: float, span_s: tuple[float, float] | None
                  ) -> tuple[NDArray, tuple[float, float] | None]:
    """The detector's input as (n, channels) and its span, checked (ValueError naming the
    fault: shape, NaN/inf samples, `t0`, `span_s`)."""
    x = np.asarray(samples)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] == 0 or x.shape[1] == 0:
        raise ValueError(f"samples must have shape (n,) or (n, channels) with n > 0, got "
                         f"{np.shape(samples)}")
    if not np.issubdtype(x.dtype, np.number) or not all_finite(x):
        raise ValueError("samples contain NaN or infinite values")
    if not np.isfinite(t0):
        raise ValueError(f"t0 must be finite, got {t0!r}")
    if span_s is not None:
        span_s = (float(span_s[0]), float(span_s[1]))
        if not (np.isfinite(span_s[0]) and np.isfinite(span_s[1]) and span_s[0] <= span_s[1]):
            raise ValueError(f"span_s must be (start, end) with start <= end, got {span_s!r}")
    return x, span_s
