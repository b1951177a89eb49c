"""The detection statistic of :class:`fusion.clicks.detect.ClickDetector` computed on frames.

The STFT band sum over the per-bin background (or the smoothed squared envelope) over chunks of
frames that stay in cache, the centre frequency of eq. (2) at given frames, and the finiteness
test of the input (*Localization of Short Duration Periodic Signals*, Baggenstoss, NUWC 102089,
paragraphs [0030]-[0031]). The detector's module notes give the formulation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fusion.clicks._frames import CHUNK, framed_filter, gather_frames, interp_nodes, segment_medians
from fusion.clicks._kernels import DetectorKernels

__all__ = ["all_finite", "centre_frequency", "checked_input", "chunked_statistic", "frame_statistic",
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


def frame_statistic(det, x: NDArray[np.floating], fs: float, s0: int, k: DetectorKernels,
                    frames: NDArray[np.int64], f_lo: int, f_hi: int) -> tuple[
                        NDArray[np.int64], NDArray[np.int64], NDArray[np.float64],
                        NDArray[np.float64], NDArray[np.float32]]:
    """The normalised detection statistic of `det` (a :class:`~fusion.clicks.detect.
    ClickDetector`) on ``frames[f_lo:f_hi]`` of `x` (n, ch) starting at absolute sample `s0`:
    per-bin medians on every D-th frame of absolute segments as the background, then the band
    sum over it (or the envelope over its own background). Returns the frames kept, their
    background node interpolation (``left``, ``wgt``), the per-bin background and the
    statistic (ch, frames)."""
    tiny = float(np.finfo(np.float32).tiny)
    n_frames = frames.size
    sub = np.flatnonzero(frames % det.background_decimation == 0)
    if sub.size == 0:
        sub = np.arange(n_frames)
    spec = gather_frames(x, s0, frames[sub], k.full)
    p_sub = spec[..., 0::2] ** 2 + spec[..., 1::2] ** 2  # (ch, k, n_bins)
    seg_len = det._seg_len(fs)
    # a segment cut to under a quarter by an end of the audio gets no node of its own
    min_count = max(1, -(-seg_len // det.background_decimation) // 4)
    nodes, med = segment_medians(p_sub, frames[sub], seg_len, min_count)
    bin_bg = np.maximum(med / np.log(2.0), tiny)  # mean = median / ln 2 (exponential)
    frames = frames[f_lo:f_hi]
    j_a, n_frames = int(frames[0]), frames.size
    left, wgt = interp_nodes(frames.astype(float), nodes)
    if det.method == "stft":
        # flat band weights over the per-bin background, on the re and im columns
        coef = np.repeat((1.0 / k.band.size) / bin_bg[:, :, k.band], 2, axis=2)
        stat = chunked_statistic(x, s0, j_a, n_frames, k, coef.astype(np.float32), left, wgt,
                                 nfft=det.nfft)
    else:
        env = chunked_statistic(x, s0, j_a, n_frames, k, None, left, wgt, nfft=det.nfft)
        _, env_bg = segment_medians(env[:, sub], frames[sub], seg_len, min_count)
        env_bg = np.maximum(env_bg / k.env_median_to_mean, tiny)  # mean-equivalent
        right = np.minimum(left + 1, nodes.size - 1)
        bg = env_bg[:, left] * (1.0 - wgt) + env_bg[:, right] * wgt
        stat = env / bg.astype(np.float32)
    return frames, left, wgt, bin_bg, stat
