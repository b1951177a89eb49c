"""The click front end's streaming part: audio blocks in, measured windows out.

:func:`measure_stream` is the per-window work of :class:`fusion.pipelines.clicks.ClickFrontEnd`
without the association across time: it detects clicks once per sample as consecutive audio
blocks arrive (each detection over the new audio plus a guard on both sides) and measures each
processing window (``measure_window``) as soon as its clicks are final, holding only the last
window plus two guards of audio. The association (:meth:`ClickFrontEnd.associate`) runs on its
output.

The stream can also start part-way through a recording (``start_sample``, ``final_from``) and
measure only some windows (``first_window``, ``stop_window``). Click detection is then cut at the
same samples as in a stream from the start, provided the blocks are cut on the same grid and
``final_from`` is one of the points where that stream's clicks become final; so a recording
measured piece by piece gives exactly (bit for bit) the windows of one stream over all of it.
:func:`stream_start` gives such a start for a window.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._validation import check_positive
from fusion.clicks.types import ChannelClicks
from fusion.clicks.window import WindowTdoa
from fusion.geometry import SensorArray

if TYPE_CHECKING:  # pragma: no cover
    from fusion.clicks.detect import ClickDetector

__all__ = ["MeasuredWindow", "WindowMeasurer", "measure_stream", "stream_start"]


@dataclass(frozen=True)
class MeasuredWindow:
    """One processing window measured, not yet associated across time.

    Attributes
    ----------
    index : int
        Window number in the recording (0 for the window starting at 0 s).
    t_start, t_end : float
        Window, s from the start of the audio.
    clicks : tuple of ChannelClicks
        Clicks detected on each channel within the window.
    tdoas : tuple of WindowTdoa
        The candidate TDOAs of :meth:`ClickFrontEnd.measure_window` (``confirmed`` False).
    """

    index: int
    t_start: float
    t_end: float
    clicks: tuple[ChannelClicks, ...]
    tdoas: tuple[WindowTdoa, ...]


class WindowMeasurer(Protocol):
    """What :func:`measure_stream` asks of the front end: detector, window, hop, measurement.

    :class:`fusion.pipelines.clicks.ClickFrontEnd` is one (this module does not import it: it is
    the module that imports this one).
    """

    detector: ClickDetector
    window_s: float
    hop_s: float

    def measure_window(self, clicks: Sequence[ChannelClicks], *, t0_s: float,
                       sensors: SensorArray, audio: NDArray | None = None,
                       audio_t0_s: float = 0.0, fs: float | None = None,
                       refiner: Any = None) -> list[WindowTdoa]: ...


def stream_start(window_start: int, *, block: int, guard: int) -> tuple[int, int]:
    """Where a stream must start to measure windows from `window_start` on exactly.

    Parameters
    ----------
    window_start : int
        First sample of the first window wanted.
    block : int
        Block size of the stream (samples): the blocks are ``[k block, (k + 1) block)``.
    guard : int
        The detector's guard, samples (``ceil(guard_s * fs)``).

    Returns
    -------
    start_sample : int
        First sample to read (a multiple of `block`).
    final_from : int
        Clicks are final from this sample on: one of the points ``k block - guard`` where a
        stream from sample 0 makes its clicks final, at or before `window_start`, with the
        detector's left margin (two guards) inside the audio read. ``(0, 0)`` when only the
        start of the recording qualifies.
    """
    if block < 1 or guard < 0:
        raise ValueError(f"block must be >= 1 and guard >= 0, got {block} and {guard}")
    k = (window_start + guard) // block - 1  # one block to spare before the window
    final_from = k * block - guard
    if k < 1 or final_from <= 0:  # the stream from 0 makes nothing final before k block - guard > 0
        return 0, 0
    start = max((final_from - 2 * guard) // block, 0) * block
    return start, final_from


class _AudioRing:
    """The most recent audio, contiguous in time, in one buffer (a sliding window).

    Blocks are copied in once; :meth:`cut` returns a view (no copy), valid until the next
    :meth:`append` (which may move the samples).
    """

    def __init__(self, start: int = 0) -> None:
        self._buf: NDArray[np.float32] | None = None  # (capacity, channels)
        self._base = start  # absolute index of _buf[0]
        self._lo = 0  # _buf[_lo:_hi] holds the samples kept
        self._hi = 0

    @property
    def end(self) -> int:
        return self._base + self._hi

    @property
    def start(self) -> int:
        return self._base + self._lo

    def append(self, first: int, x: NDArray) -> None:
        if first != self.end:
            raise ValueError(f"audio blocks must be contiguous: block at sample {first}, "
                             f"expected {self.end}")
        m = x.shape[0]
        if self._buf is None or self._buf.shape[1] != x.shape[1]:
            self._buf = np.empty((max(4 * m, 1), x.shape[1]), dtype=np.float32)
            self._base, self._lo, self._hi = first, 0, 0
        elif self._hi + m > self._buf.shape[0]:
            kept = self._hi - self._lo
            if 2 * (kept + m) > self._buf.shape[0]:  # grow: moves happen once per capacity
                buf = np.empty((2 * (kept + m), x.shape[1]), dtype=np.float32)
                buf[:kept] = self._buf[self._lo:self._hi]
                self._buf = buf
            else:  # move the kept samples to the front
                self._buf[:kept] = self._buf[self._lo:self._hi].copy()
            self._base += self._lo
            self._lo, self._hi = 0, kept
        self._buf[self._hi:self._hi + m] = x
        self._hi += m

    def drop_before(self, sample: int) -> None:
        self._lo = min(max(self._lo, sample - self._base), self._hi)

    def cut(self, a: int, b: int) -> tuple[int, NDArray]:
        """Samples ``[max(a, start), min(b, end))`` (a view) and the index of the first."""
        a, b = max(a, self.start), min(b, self.end)
        if self._buf is None or b <= a:
            raise ValueError(f"no audio held in [{a}, {b})")
        return a, self._buf[a - self._base:b - self._base]


def measure_stream(
    front: WindowMeasurer,
    blocks: Iterable[tuple[float, ArrayLike]] | Iterable[tuple[float, ArrayLike, float]],
    *,
    fs: float,
    sensors: SensorArray,
    duration_s: float | None = None,
    start_sample: int = 0,
    final_from: int = 0,
    first_window: int = 0,
    stop_window: int | None = None,
) -> Iterator[MeasuredWindow]:
    """Measure the processing windows of a stream of consecutive audio blocks, in order.

    Parameters
    ----------
    front : WindowMeasurer
        Detector, window length, hop and ``measure_window`` (a :class:`ClickFrontEnd`).
    blocks : iterable of (t0, samples) or (t0, samples, fs)
        Consecutive, non-overlapping blocks (n, n_sensors) in time order, the first at
        ``start_sample / fs``.
    fs : float
        Sample rate, Hz.
    sensors : SensorArray
        The array; channel i is sensor i.
    duration_s : float, optional
        Length of the recording, s (see :meth:`ClickFrontEnd.iter_windows`).
    start_sample : int, optional
        Index of the first sample of the first block.
    final_from : int, optional
        Clicks before this sample are not detected (a stream that does not start at 0: see
        :func:`stream_start`); at least two detector guards after `start_sample` unless that
        is 0 (the start of the recording).
    first_window, stop_window : int, optional
        Measure windows ``first_window <= k < stop_window`` only (default: all); reading stops
        once the last is measured.

    Yields
    ------
    MeasuredWindow
        Each window once its clicks are final.
    """
    check_positive("fs", fs)
    g = int(math.ceil(front.detector.guard_s(fs) * fs))
    if start_sample < 0 or final_from < 0 or first_window < 0:
        raise ValueError("start_sample, final_from and first_window must be >= 0")
    if start_sample and final_from - 2 * g < start_sample:
        raise ValueError(f"final_from {final_from} leaves less than two detector guards "
                         f"({2 * g} samples) after start_sample {start_sample}")
    if int(round(first_window * front.hop_s * fs)) < final_from:
        raise ValueError(f"window {first_window} starts before final_from {final_from}")
    margin = int(math.ceil(0.01 * fs))  # audio beyond the window for click cuts
    # one refiner for the stream: a click's cuts are measured once for all windows it is in
    stream_refiner = getattr(front, "stream_refiner", None)
    refiner = stream_refiner(fs) if stream_refiner is not None else None
    ring = _AudioRing(start_sample)
    final_until = final_from  # clicks before this sample are final
    clicks: list[list[ChannelClicks]] = [[] for _ in range(sensors.n_sensors)]
    next_k = first_window
    window_s, hop_s = front.window_s, front.hop_s

    def detect(a: int, b: int, keep_to: int) -> None:
        first, x = ring.cut(a, b)
        found = front.detector.detect(x, fs, t0=first / fs, span_s=(final_until / fs, keep_to / fs))
        for ch, c in enumerate(found):
            clicks[ch].append(c.between(final_until / fs, keep_to / fs))

    def merged(t0: float, t1: float) -> list[ChannelClicks]:
        out = []
        for ch, parts in enumerate(clicks):
            sel = [p.between(t0, t1) for p in parts if p.n_clicks]
            sel = [p for p in sel if p.n_clicks]
            if not sel:
                out.append(ChannelClicks(ch))
                continue
            out.append(ChannelClicks(ch, np.concatenate([p.times_s for p in sel]),
                                     np.concatenate([p.power for p in sel]),
                                     np.concatenate([p.centre_freq_hz for p in sel])))
        return out

    def process(k: int, t0: float, t1: float) -> MeasuredWindow:
        a, b = int(round(t0 * fs)) - margin, int(round(t1 * fs)) + margin
        first, x = ring.cut(a, b)
        window_clicks = merged(t0, t1)
        extra = {} if refiner is None else {"refiner": refiner}
        tdoas = front.measure_window(window_clicks, t0_s=t0, sensors=sensors, audio=x,
                                     audio_t0_s=first / fs, fs=fs, **extra)
        # forget clicks and audio no later window needs
        keep_from = t0 + hop_s
        ring.drop_before(int(round(keep_from * fs)) - margin - 2 * g)
        if refiner is not None and hasattr(refiner, "forget_before"):
            refiner.forget_before(int(round(keep_from * fs)) - margin - 2 * g)
        for ch in range(len(clicks)):
            clicks[ch] = [p for p in clicks[ch] if p.n_clicks and p.times_s[-1] >= keep_from]
        return MeasuredWindow(k, t0, t1, tuple(window_clicks), tuple(tdoas))

    def done() -> bool:
        return stop_window is not None and next_k >= stop_window

    def starts_ready() -> Iterator[tuple[int, float]]:
        nonlocal next_k
        while not done():
            t0 = next_k * hop_s
            t1 = t0 + window_s
            if duration_s is not None:
                starts = window_starts_count(duration_s, window_s, hop_s)
                if next_k >= starts:
                    return
                t1 = min(t1, duration_s)
            if t1 * fs <= final_until:
                next_k += 1
                yield next_k - 1, t0
            else:
                return

    n_sensors = sensors.n_sensors
    first_sample = start_sample
    for item in blocks:
        t_blk, x = float(item[0]), np.asarray(item[1])
        if len(item) == 3 and float(item[2]) != float(fs):
            raise ValueError(f"block at {t_blk} s has sample rate {item[2]}, expected {fs}")
        if x.ndim != 2 or x.shape[1] != n_sensors:
            raise ValueError(f"audio block has shape {x.shape}, expected (n, {n_sensors})")
        if x.shape[0] == 0:
            continue
        if not np.all(np.isfinite(x)):
            raise ValueError(f"audio block at {t_blk} s contains NaN or infinite samples")
        if abs(t_blk * fs - first_sample) > 0.5:
            raise ValueError(f"audio blocks must be consecutive: block at {t_blk} s, "
                             f"expected {first_sample / fs} s")
        ring.append(first_sample, x.astype(np.float32, copy=False))
        first_sample += x.shape[0]
        # clicks are final up to a guard before the end of the audio seen so far
        keep_to = ring.end - g
        if keep_to > final_until:
            detect(final_until - 2 * g, ring.end, keep_to)
            final_until = keep_to
        for k, t0 in list(starts_ready()):
            yield process(k, t0, t0 + window_s)
        if done():
            return
    if ring.end == start_sample:
        raise ValueError("no audio samples")
    if ring.end > final_until:
        detect(final_until - 2 * g, ring.end, ring.end + 1)
        final_until = ring.end + 1
    end_s = ring.end / fs
    total = duration_s if duration_s is not None else end_s
    n_windows = window_starts_count(total, window_s, hop_s)
    if stop_window is not None:
        n_windows = min(n_windows, stop_window)
    while next_k < n_windows:
        t0 = next_k * hop_s
        next_k += 1
        yield process(next_k - 1, t0, min(t0 + window_s, end_s))


def window_starts_count(duration_s: float, window_s: float, hop_s: float) -> int:
    """Number of windows ``[k hop, k hop + window)`` of a recording (at least one)."""
    n = int(math.floor((duration_s - window_s) / hop_s + 1e-9)) + 1
    return max(n, 1)
