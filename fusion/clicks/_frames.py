"""Frame-grid helpers of the click detector: FIR kernel banks applied on a hop grid anchored at
absolute sample 0, and segment-median backgrounds on absolute time segments.

Anchoring frames and background segments to absolute sample indices (not to the start of the
block in hand) is what makes block-by-block detection equal whole-signal detection: a frame or a
segment that lies inside two overlapping blocks gets the same samples, so the same value, in both.

A *kernel bank* ``T`` (shape ``(Lk, ncol)``) with offset ``off`` maps frame ``J`` to::

    out[J, c] = sum_u T[u, c] x[hop J - off + u]

Rows of ``R = phases * hop`` samples turn that into ``out[r] = sum_q X[r + q] @ T_q``, where
row ``r`` of the output holds ``phases`` consecutive frames and ``T_q`` stacks the kernel
delayed by each phase: a few float32 matrix products over contiguous views (no frame copies),
large enough for BLAS to run near full speed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["KernelBank", "gather_frames", "framed_filter", "interp_nodes", "make_rows",
           "segment_medians"]

#: Frames per chunk of the detector's main pass (keeps the working set in cache).
CHUNK = 1024


@dataclass(frozen=True)
class KernelBank:
    """A kernel bank laid out for rows of ``phases`` frames.

    Frame ``J`` reads samples ``hop J - offset + u`` (``u < Lk``). A row buffer holds
    ``R = phases * hop`` samples per row, starting ``offset`` samples before a frame; row ``r``
    then yields frames ``phases * r + p`` for ``p < phases`` at once, as column block ``p``.

    Attributes
    ----------
    blocks : ndarray, shape (Q, R, phases * ncol), float32
        Kernel blocks: ``out[r] = sum_q rows[r + q] @ blocks[q]``.
    offset : int
        Samples the kernel reaches before the frame start.
    hop : int
        Frame hop, samples.
    phases : int
        Frames per row.
    """

    blocks: NDArray[np.float32]
    offset: int
    hop: int
    phases: int

    @staticmethod
    def layout(kernel: NDArray[np.float64], offset: int, hop: int, phases: int = 1) -> KernelBank:
        """Lay out `kernel` (Lk, ncol) that reads ``x[hop J - offset + u]``."""
        n_k, ncol = kernel.shape
        width = hop * phases
        n_q = -(-(hop * (phases - 1) + n_k) // width)
        big = np.zeros((n_q * width, phases * ncol))
        for p in range(phases):  # frame p of a row is the kernel delayed by p hops
            big[hop * p:hop * p + n_k, p * ncol:(p + 1) * ncol] = kernel
        return KernelBank(big.reshape(n_q, width, -1).astype(np.float32), int(offset), int(hop),
                          int(phases))

    @property
    def taps(self) -> int:
        """Samples one row of output reads (``Q R``)."""
        return self.blocks.shape[0] * self.blocks.shape[1]

    @property
    def ncol(self) -> int:
        """Outputs per frame."""
        return self.blocks.shape[2] // self.phases


def make_rows(
    x: NDArray[np.floating], s0: int, first: int, n_rows: int, width: int
) -> NDArray[np.float32]:
    """Row buffer (n_channels, n_rows, width) float32 of absolute samples ``first ..``, taken
    from `x` (n, n_channels) whose sample 0 is absolute sample `s0`; zero outside `x`."""
    n, n_ch = x.shape
    buf = np.zeros((n_ch, n_rows * width), dtype=np.float32)
    a, b = max(first, s0), min(first + n_rows * width, s0 + n)
    if b > a:
        buf[:, a - first:b - first] = x[a - s0:b - s0].T
    return buf.reshape(n_ch, n_rows, width)


def framed_filter(
    x: NDArray[np.floating], s0: int, first_frame: int, n_frames: int, bank: KernelBank
) -> NDArray[np.float32]:
    """The bank's output at consecutive absolute frames ``first_frame ..``.

    Parameters
    ----------
    x : ndarray, shape (n, n_channels)
        Samples; sample 0 is absolute sample `s0` (zero outside).
    first_frame, n_frames : int
        Absolute index of the first frame, and how many.
    bank : KernelBank

    Returns
    -------
    ndarray, shape (n_channels, n_frames, ncol), float32
    """
    m, n_q = bank.phases, bank.blocks.shape[0]
    width = bank.hop * m
    n_out = -(-n_frames // m)
    rows = make_rows(x, s0, bank.hop * first_frame - bank.offset, n_out + n_q - 1, width)
    out = rows[:, 0:n_out] @ bank.blocks[0]
    for q in range(1, n_q):
        out += rows[:, q:q + n_out] @ bank.blocks[q]
    return out.reshape(rows.shape[0], n_out * m, bank.ncol)[:, :n_frames]


def gather_frames(
    x: NDArray[np.floating], s0: int, frames: NDArray[np.int64], bank: KernelBank
) -> NDArray[np.float32]:
    """The output of a one-phase bank at selected absolute frames only.

    Parameters
    ----------
    x : ndarray, shape (n, n_channels)
        Samples; sample 0 is absolute sample `s0` (zero outside).
    frames : ndarray of int, shape (k,)
        Absolute frame indices, increasing.
    bank : KernelBank
        With ``phases == 1``.

    Returns
    -------
    ndarray, shape (n_channels, k, ncol), float32

    Notes
    -----
    Evenly spaced frames wholly inside `x` are read through a strided view (frames, taps,
    channels) contracted with the kernel over the taps (one matrix product after a copy that
    keeps each frame's samples together); the others gather their samples with zero padding.
    """
    if bank.phases != 1:
        raise ValueError("gather_frames needs a one-phase kernel bank")
    x = np.asarray(x, dtype=np.float32)
    n, n_ch = x.shape
    taps, ncol = bank.taps, bank.ncol
    first = bank.hop * frames - bank.offset - s0  # index in x of each frame's first tap
    inner = (first >= 0) & (first + taps <= n)
    out = np.empty((n_ch, frames.size, ncol), dtype=np.float32)
    kern = bank.blocks.reshape(taps, ncol)
    step = np.diff(first[inner])
    if inner.sum() > 1 and np.all(step == step[0]):
        i = np.flatnonzero(inner)
        view = np.lib.stride_tricks.as_strided(
            x[first[i[0]]:], shape=(i.size, taps, n_ch),
            strides=(step[0] * x.strides[0], x.strides[0], x.strides[1]), writeable=False)
        out[:, i] = np.tensordot(view, kern, axes=([1], [0])).transpose(1, 0, 2)  # (ch, k, ncol)
        rest = np.flatnonzero(~inner)
    else:
        rest = np.arange(frames.size)
    if rest.size:
        idx = first[rest, None] + np.arange(taps)[None, :]
        sel = x[np.clip(idx, 0, n - 1)]  # (k, taps, n_ch)
        sel *= ((idx >= 0) & (idx < n))[:, :, None]
        out[:, rest] = np.moveaxis(sel, 2, 0) @ kern
    return out


def segment_medians(
    values: NDArray[np.floating], frames: NDArray[np.int64], seg_len: int, min_count: int = 1
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Median of `values` over each absolute segment of `seg_len` frames.

    Parameters
    ----------
    values : ndarray, shape (n_channels, k, ...)
        Values at absolute frames `frames` (increasing).
    frames : ndarray of int, shape (k,)
        Absolute frame indices.
    seg_len : int
        Frames per segment; segment ``m`` holds frames ``m seg_len .. (m + 1) seg_len - 1``.
    min_count : int, optional
        Segments with fewer values (cut short by the ends of the audio) get no node; when none
        has enough, one node holds the median of all values.

    Returns
    -------
    nodes : ndarray, shape (m,)
        Absolute frame of each segment's centre.
    medians : ndarray, shape (n_channels, m, ...)
    """
    seg = np.floor_divide(frames, seg_len)
    cuts = np.flatnonzero(np.diff(seg)) + 1
    starts = np.concatenate([[0], cuts])
    ends = np.concatenate([cuts, [frames.size]])
    full = (ends - starts) >= min_count
    if not full.any():
        return np.array([float(frames.mean())]), np.median(values, axis=1)[:, None].astype(float)
    starts, ends = starts[full], ends[full]
    med = np.empty((values.shape[0], starts.size) + values.shape[2:])
    length = ends - starts
    for size in np.unique(length):  # segments of one length: one median call
        which = np.flatnonzero(length == size)
        a = starts[which]
        if np.all(np.diff(a) == size):  # consecutive: a reshape, no copy
            block = values[:, a[0]:a[-1] + size]
            block = block.reshape((values.shape[0], which.size, size) + values.shape[2:])
        else:
            idx = a[:, None] + np.arange(size)
            block = values[:, idx]
        med[:, which] = np.median(block, axis=2)
    nodes = seg[starts] * seg_len + 0.5 * (seg_len - 1)
    return nodes.astype(float), med


def interp_nodes(frames: NDArray[np.floating], nodes: NDArray[np.float64]) -> tuple[
        NDArray[np.int64], NDArray[np.float64]]:
    """Left node and weight for linear interpolation between node centres (constant beyond).

    Returns
    -------
    left : ndarray of int, shape (n,)
        Index of the left node (``right = min(left + 1, m - 1)``).
    weight : ndarray, shape (n,)
        Weight of the right node.
    """
    m = nodes.size
    if m == 1:
        return np.zeros(frames.shape, dtype=np.int64), np.zeros(frames.shape)
    pos = np.interp(frames, nodes, np.arange(m, dtype=float))
    left = np.minimum(np.floor(pos).astype(np.int64), m - 2)
    return left, pos - left
