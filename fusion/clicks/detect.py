"""Click detection and screening (steps 38-42 of the localization method, eq. 2).

Implements paragraphs [0030] and [0031] of *Localization of Short Duration Periodic Signals*
(Baggenstoss, NUWC 102089): the replica-correlated signal (step 36, eq. 1) goes through a
Hann-weighted, 75 %-overlapped short-time Fourier transform of size 24 (0.0625 ms hop at
96 kHz); every bin is normalised by a median-based background; the normalised powers are summed
over the band of the clicks; local maxima above a threshold are candidate clicks, timed by
parabolic interpolation; clicks whose power-weighted mean frequency (eq. 2) lies below a limit,
and weak peaks within 2.5 ms of a much louder click (ringing), are removed.

Choices the text leaves open (each an option of :class:`ClickDetector`):

* **Computation.** Replica correlation and the STFT are both linear, so each STFT bin is one FIR
  filter of the raw input, ``Y_k(J) = sum_m G_k[m] x[hop J - h + m]`` with
  ``G_k = (w e^{-i w_k n}) * r``; the band bins are computed that way on a hop grid anchored at
  absolute sample 0 (float32 matrix products over rows of ``nfft`` samples), which is exact and
  never materialises the correlated signal.
* **Envelope variant** (``method="envelope"``): the input correlated with the replica whitened
  over the band (its own phase, flat magnitude: what per-bin normalisation does to the matched
  filter in white noise), squared and smoothed by the STFT's effective window ``w^2`` on the same
  frames, with one background per channel. It is not faster here (both run near 190x real time
  on 5 channels at 96 kHz) and agrees with the STFT on about 96 % of detections within 0.1 ms
  (``benchmarks/bench_click_detection.py``), with lower recall near threshold, so ``"stft"``,
  the method's own formulation, is the default.
* **Background.** Medians over absolute time segments of `background_s`, taken on every
  `background_decimation`-th frame, placed at the segment centres and interpolated linearly
  between them (constant beyond the first and last; a segment cut to under a quarter by an end
  of the audio has no node of its own). Each bin's power is exponential in Gaussian noise, so
  its mean is estimated as ``median / ln 2``; the STFT statistic (flat weights summing to 1)
  then has unit mean in noise. The envelope statistic's median is turned into a mean with the
  median-to-mean ratio of the gamma law that fits it in white noise (Satterthwaite), so both
  share the threshold scale.
* **Timing.** Parabolic interpolation of the *logarithm* of the power (exact for a Gaussian
  peak): on the 6-sample hop the linear-power parabola is biased by up to half a sample, the
  log-power one by under 0.05 sample.
* **Centre frequency (eq. 2)** is computed from the *normalised* spectrogram at the frame
  nearest the click, as the mean frequency weighted by the power in excess of the background,
  over the bins strictly between 0 and fs/2. The raw spectrogram of the correlated signal would
  put a loud 5 kHz transient near 26 kHz, since correlation with the replica strips its low
  band; the normalised one keeps it near 7 kHz.
* **Ringing suppression** drops a click with a `suppress_ratio` times stronger one within `suppress_s`.

Click times refer to the replica's centre: a replica unlike the clicks (the generic one) shifts
every time by a constant (about 14 us on the simulated clicks), which cancels in time
differences; an estimated replica (:func:`fusion.clicks.replica.estimate_replica`) removes it.
The statistic is an energy detector over a quarter millisecond: at the default threshold it
finds half the clicks at a per-click SNR (peak over in-band noise standard deviation) of about
12 dB and nearly all above 15 dB.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterable
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from fusion._validation import check_positive
from fusion.clicks._click_peaks import local_maxima, not_echo, not_ringing
from fusion.clicks._detect_statistic import centre_frequency, checked_input, frame_statistic
from fusion.clicks._kernels import DetectorKernels
from fusion.clicks._noise_threshold import noise_threshold
from fusion.clicks.band import DEFAULT_BAND_HZ
from fusion.clicks.replica import Replica, ReplicaEstimate, estimate_replica, load_replica
from fusion.clicks.types import ChannelClicks

__all__ = ["ClickDetector", "DEFAULT_THRESHOLD"]

logger = logging.getLogger(__name__)

#: Default detection threshold (band power over the mean background): the lowest of the sweep
#: on tuning seeds 0-9 of ``benchmarks/bench_click_detection.py`` with at most 100 noise false
#: alarms per channel-hour (5.5 / 6.0 / 6.5: 338 / 96 / 22, recalls 0.863 / 0.843 / 0.817 for
#: direct-path clicks of per-click SNR >= 10 dB).
DEFAULT_THRESHOLD = 6.0

_TINY = float(np.finfo(np.float32).tiny)


class ClickDetector:
    """Detect clicks in multichannel audio (steps 38-42 of the localization method).

    Parameters
    ----------
    replica : Replica, optional
        Replica the audio is correlated with (eq. 1); default the shipped generic replica.
        Resampled to the audio's rate.
    method : {"stft", "envelope"}, optional
        ``"stft"``: the method text's per-bin normalised spectrogram; ``"envelope"``: the
        squared, smoothed output of correlation with the band-whitened replica, one background
        per channel (see the module notes).
    nfft : int, optional
        STFT size, samples (Hann window of this length).
    overlap : float, optional
        Fraction of overlap between frames; ``nfft (1 - overlap)`` must be an integer dividing
        `nfft` (the hop).
    band_hz : (float, float), optional
        Band whose normalised power is summed, Hz; its upper edge must lie below ``fs / 2``.
    threshold : float, optional
        Detection threshold on the band power over the background (noise mean 1).
    false_alarms_per_s : float, optional
        If given, the threshold instead: the level of this many clicks a second in white noise
        (:func:`fusion.clicks._noise_threshold.noise_threshold`, once per sample rate).
    background_s : float, optional
        Length of the background segments, s. Block-wise detection needs blocks overlapping by
        about three times this (:meth:`guard_s`).
    background_decimation : int, optional
        The background median is taken over every this-many-th frame.
    min_centre_freq_hz : float, optional
        Clicks whose centre frequency (eq. 2) is below this are removed, Hz.
    suppress_s : float, optional
        Ringing window, s: a click with a candidate `suppress_ratio` times more powerful within
        this time is removed.
    suppress_ratio : float, optional
        Power ratio of the ringing test (> 1).
    min_separation_s : float, optional
        Two local maxima closer than this are one click (the larger is kept), s.
    interpolation : {"log", "linear"}, optional
        Parabolic interpolation of the log power (default) or of the power.
    echo_window_s : (float, float), optional
        Echo suppression (step 32's threshold time): a click with a stronger click this many
        seconds before it is taken as that click's echo and removed. Default None: none (set
        from the recording's bottom echoes by ``fusion localize``,
        :func:`fusion.clicks.echoes.bottom_echoes`).

    Notes
    -----
    Steps 38-42 of *Localization of Short Duration Periodic Signals*, paragraphs [0030] and
    [0031], with eq. (2) for the centre frequency; eq. (1), the replica correlation, is folded
    into the STFT's filters. The module notes list the choices the text leaves open.

    Examples
    --------
    >>> from fusion.simulate.clicks import simulate_clicks
    >>> sc = simulate_clicks(seed=0, n_sensors=3, n_sources=1, duration_s=2.0, snr_db=30.0)
    >>> clicks = ClickDetector().detect(sc.audio, sc.fs)
    >>> len(clicks), clicks[0].channel
    (3, 0)
    """

    def __init__(
        self,
        *,
        replica: Replica | None = None,
        method: Literal["stft", "envelope"] = "stft",
        nfft: int = 24,
        overlap: float = 0.75,
        band_hz: tuple[float, float] = DEFAULT_BAND_HZ,
        threshold: float = DEFAULT_THRESHOLD,
        background_s: float = 0.5,
        background_decimation: int = 32,
        min_centre_freq_hz: float = 20_000.0,
        suppress_s: float = 2.5e-3,
        suppress_ratio: float = 10.0,
        min_separation_s: float = 0.25e-3,
        interpolation: Literal["log", "linear"] = "log",
        echo_window_s: tuple[float, float] | None = None,
        false_alarms_per_s: float | None = None,
    ) -> None:
        if replica is not None and not isinstance(replica, Replica):
            raise ValueError(f"replica must be a Replica, got {type(replica).__name__}")
        if method not in ("stft", "envelope"):
            raise ValueError(f"method must be 'stft' or 'envelope', got {method!r}")
        if interpolation not in ("log", "linear"):
            raise ValueError(f"interpolation must be 'log' or 'linear', got {interpolation!r}")
        for name, v in (("nfft", nfft), ("background_decimation", background_decimation)):
            if isinstance(v, bool) or int(v) != v or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        if not 0.0 <= overlap < 1.0:
            raise ValueError(f"overlap must lie in [0, 1), got {overlap!r}")
        hop = nfft * (1.0 - overlap)
        if abs(hop - round(hop)) > 1e-9 or round(hop) < 1 or nfft % round(hop):
            raise ValueError(f"nfft * (1 - overlap) = {hop} must be an integer dividing nfft")
        lo, hi = (float(v) for v in band_hz)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
            raise ValueError(f"band_hz must be (low, high) with 0 <= low < high, got {band_hz!r}")
        self.replica = load_replica() if replica is None else replica
        self.method = method
        self.nfft, self.hop = int(nfft), int(round(hop))
        self.band_hz = (lo, hi)
        self.threshold = check_positive("threshold", threshold)
        self.false_alarms_per_s = (None if false_alarms_per_s is None else
                                   check_positive("false_alarms_per_s", false_alarms_per_s))
        self._noise_thresholds: dict[float, float] = {}
        self.background_s = check_positive("background_s", background_s)
        self.background_decimation = int(background_decimation)
        self.min_centre_freq_hz = check_positive("min_centre_freq_hz", min_centre_freq_hz,
                                                 allow_zero=True)
        self.suppress_s = check_positive("suppress_s", suppress_s, allow_zero=True)
        self.suppress_ratio = check_positive("suppress_ratio", suppress_ratio)
        if self.suppress_ratio <= 1.0:
            raise ValueError(f"suppress_ratio must exceed 1, got {suppress_ratio!r}")
        self.min_separation_s = check_positive("min_separation_s", min_separation_s)
        self.interpolation = interpolation
        if echo_window_s is not None:
            e_lo, e_hi = (float(v) for v in echo_window_s)
            if not (np.isfinite(e_lo) and np.isfinite(e_hi) and 0 <= e_lo < e_hi <= 1.0):
                raise ValueError(f"echo_window_s must be (low, high) with 0 <= low < high <= 1 s, "
                                 f"got {echo_window_s!r}")
            echo_window_s = (e_lo, e_hi)
        self.echo_window_s = echo_window_s
        self._kernels: dict[float, DetectorKernels] = {}

    # ----------------------------------------------------------------------------------------
    def _bank(self, fs: float) -> DetectorKernels:
        if not (np.isfinite(fs) and fs > 0):
            raise ValueError(f"fs must be positive, got {fs!r}")
        if self.band_hz[1] >= 0.5 * fs:
            raise ValueError(
                f"sample rate {fs} Hz is too low for the band {self.band_hz} Hz: its upper edge "
                f"must lie below fs/2"
            )
        if fs not in self._kernels:
            self._kernels[fs] = DetectorKernels(self.replica.at(fs), fs, nfft=self.nfft, hop=self.hop,
                                                band_hz=self.band_hz)
        return self._kernels[fs]

    def threshold_at(self, fs: float) -> float:
        """The threshold at `fs`: `threshold`, or the noise level of `false_alarms_per_s`."""
        if self.false_alarms_per_s is None:
            return self.threshold
        if fs not in self._noise_thresholds:
            self._noise_thresholds[fs] = noise_threshold(self, fs, self.false_alarms_per_s)
        return self._noise_thresholds[fs]

    def _seg_len(self, fs: float) -> int:
        return max(1, int(round(self.background_s * fs / self.hop)))

    def guard_s(self, fs: float) -> float:
        """Time at each end of a block that :meth:`detect_blocks` needs as margin, s.

        Consecutive blocks must overlap by at least twice this.
        """
        k = self._bank(fs)
        sep = max(1, int(round(self.min_separation_s * fs / self.hop)))
        samples = 1.5 * self._seg_len(fs) * self.hop + 2 * k.span + self.nfft + (sep + 4) * self.hop
        echo = 0.0 if self.echo_window_s is None else self.echo_window_s[1]
        return float(samples / fs + self.suppress_s + echo)

    # ----------------------------------------------------------------------------------------
    def detect(
        self, samples: ArrayLike, fs: float, *, t0: float = 0.0,
        span_s: tuple[float, float] | None = None,
    ) -> list[ChannelClicks]:
        """Detect clicks on every channel.

        Parameters
        ----------
        samples : array_like, shape (n,) or (n, n_channels)
            Audio (not replica-correlated: correlation is part of detection).
        fs : float
            Sample rate, Hz.
        t0 : float, optional
            Time of the first sample, s (a block's start within a recording).
        span_s : (float, float), optional
            Report only the clicks with ``span_s[0] <= time < span_s[1]`` (s, on the clock of
            `t0`): the clicks of detection over all of `samples` in that span, with the
            statistic evaluated only near it (the background still comes from all of
            `samples`). A block detected this way gives the clicks of whole-signal detection
            when it reaches :meth:`guard_s` beyond the span on both sides.

        Returns
        -------
        list of ChannelClicks
            One per channel, times in s on the clock of `t0`.

        Raises
        ------
        ValueError
            Empty input, wrong dimensions, NaN/inf samples, or a sample rate too low for the
            band.
        """
        return self._run(samples, fs, t0=t0, timings=None, span_s=span_s)

    def statistic(self, samples: ArrayLike, fs: float, *, t0: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
        """The normalised detection statistic itself (noise mean 1), the one :meth:`detect`
        thresholds: the times of its frames (s, on the clock of `t0`; the replica's centre,
        as click times) and its values (channels, frames), float32."""
        x, _ = checked_input(samples, t0, None)
        k = self._bank(float(fs))
        s0 = int(round(t0 * fs))
        j_a = -((k.centre - s0) // self.hop)
        j_b = (s0 + x.shape[0] - 1 - k.centre) // self.hop
        if j_b - j_a + 1 < 3:
            return np.zeros(0), np.zeros((x.shape[1], 0), dtype=np.float32)
        frames = np.arange(j_a, j_b + 1)
        frames, *_, stat = frame_statistic(self, x, float(fs), s0, k, frames, 0, frames.size)
        return t0 + (self.hop * frames + k.centre - s0) / float(fs), stat

    def with_recording_replica(
        self, samples: ArrayLike, fs: float, *, max_clicks: int = 300, min_clicks: int = 20,
    ) -> tuple[ClickDetector, ReplicaEstimate | None]:
        """This detector with its replica estimated from a recording (step 32).

        The strongest `max_clicks` clicks it finds in `samples` (n, channels), by band power,
        are aligned and averaged, starting from its replica, for at most six passes or until a
        pass changes it by less than 0.03 (:func:`fusion.clicks.replica.estimate_replica`).
        Returns the new detector (this one when fewer than `min_clicks` clicks were found or
        the estimate did not settle) and the estimate (None without one).
        """
        x = np.asarray(samples, dtype=float)
        clicks = self.detect(x, fs)
        power = np.concatenate([c.power for c in clicks])
        if power.size < min_clicks:
            return self, None
        channel = np.concatenate([np.full(c.times_s.size, k) for k, c in enumerate(clicks)])
        times = np.concatenate([c.times_s for c in clicks])
        top = np.argsort(-power, kind="stable")[:max_clicks]
        per_channel = [np.sort(times[top][channel[top] == k]) for k in range(len(clicks))]
        est = estimate_replica(x, fs, per_channel if x.ndim == 2 else per_channel[0],
                               initial=self.replica, n_iter=6, tol=0.03)
        if not est.converged:
            return self, est
        return self._copy(replica=est.replica, _kernels={}, _noise_thresholds={}), est

    def with_echo_window(self, echo_window_s: tuple[float, float] | None) -> ClickDetector:
        """This detector with another echo suppression window (see the class parameters)."""
        probe = ClickDetector(echo_window_s=echo_window_s)  # checks the window
        return self._copy(echo_window_s=probe.echo_window_s)

    def with_false_alarms(self, false_alarms_per_s: float | None) -> ClickDetector:
        """This detector with another `false_alarms_per_s` (see the class parameters)."""
        probe = ClickDetector(false_alarms_per_s=false_alarms_per_s)  # checks the rate
        return self._copy(false_alarms_per_s=probe.false_alarms_per_s, _noise_thresholds={})

    def with_band(self, band_hz: tuple[float, float]) -> ClickDetector:
        """This detector summing the power over another band, Hz (see the class parameters)."""
        probe = ClickDetector(band_hz=band_hz)  # checks the band
        return self._copy(band_hz=probe.band_hz, _kernels={}, _noise_thresholds={})

    def _copy(self, **changes) -> ClickDetector:
        new = ClickDetector.__new__(ClickDetector)
        new.__dict__.update(self.__dict__)
        new.__dict__.update(changes)
        return new

    def detect_blocks(
        self, blocks: Iterable[tuple], fs: float
    ) -> list[ChannelClicks]:
        """Detect clicks in a stream of overlapping blocks.

        Parameters
        ----------
        blocks : iterable of (t0, samples) or (t0, samples, fs)
            Blocks in time order (e.g. :func:`fusion.io.iter_audio_blocks`): start time, s, and
            samples (n, n_channels). Consecutive blocks must overlap by at least
            ``2 * guard_s(fs)``.
        fs : float
            Sample rate, Hz (a third tuple element, if given, must equal it).

        Returns
        -------
        list of ChannelClicks
            One per channel: the clicks of whole-signal detection on the same audio.

        Notes
        -----
        Each block keeps the clicks between the midpoints of its overlaps with its neighbours;
        at least a guard of :meth:`guard_s` lies between any kept click and the block's edges,
        so its frames, background segments and neighbouring candidates are the ones whole-signal
        detection sees. A block that ends within the previous one (the short remainder a block
        reader yields at the end of a file) adds nothing and is skipped.
        """
        guard = self.guard_s(fs)
        kept: list[list[ChannelClicks]] = []
        prev: tuple[float, float, list[ChannelClicks], float] | None = None
        n_ch = None
        for item in blocks:
            if len(item) not in (2, 3):
                raise ValueError("each block must be (t0, samples) or (t0, samples, fs)")
            t0, x = float(item[0]), np.asarray(item[1])
            if len(item) == 3 and float(item[2]) != float(fs):
                raise ValueError(f"block at t0={t0} has fs={item[2]}, expected {fs}")
            if x.ndim == 1:
                x = x[:, None]
            if n_ch is not None and x.ndim == 2 and x.shape[1] != n_ch:
                raise ValueError(f"block at t0={t0} has {x.shape[1]} channels, expected {n_ch}")
            end = t0 + x.shape[0] / fs
            if prev is not None and t0 <= prev[0]:
                raise ValueError(f"blocks must start in increasing time, got {t0} after {prev[0]}")
            if prev is not None and end <= prev[1]:
                # inside the previous block (a stream's short last block): nothing new
                logger.debug("block at t0=%.6g lies inside the previous one; skipped", t0)
                continue
            clicks = self.detect(x, fs, t0=t0)
            n_ch = x.shape[1]
            lo = -np.inf
            if prev is not None:
                p_t0, p_end, p_clicks, p_lo = prev
                if p_end - t0 < 2.0 * guard:
                    raise ValueError(
                        f"blocks overlap by {p_end - t0:.4g} s, need >= {2 * guard:.4g} s "
                        f"(twice the detector's guard)"
                    )
                lo = 0.5 * (p_end + t0)
                kept.append([c.between(p_lo, lo) for c in p_clicks])
            prev = (t0, end, clicks, lo)
        if prev is None:
            raise ValueError("detect_blocks got no blocks")
        kept.append([c.between(prev[3], np.inf) for c in prev[2]])
        return [
            ChannelClicks(
                ch,
                np.concatenate([blk[ch].times_s for blk in kept]),
                np.concatenate([blk[ch].power for blk in kept]),
                np.concatenate([blk[ch].centre_freq_hz for blk in kept]),
            )
            for ch in range(n_ch)
        ]

    # ----------------------------------------------------------------------------------------
    def _run(
        self, samples: ArrayLike, fs: float, *, t0: float, timings: dict[str, float] | None,
        span_s: tuple[float, float] | None = None,
    ) -> list[ChannelClicks]:
        """:meth:`detect`, optionally adding the time of each stage (s) to `timings`."""
        clock = time.process_time()

        def lap(name: str) -> None:
            nonlocal clock
            if timings is not None:
                now = time.process_time()
                timings[name] = timings.get(name, 0.0) + now - clock
                clock = now

        x, span_s = checked_input(samples, t0, span_s)
        x32 = np.asarray(x, dtype=np.float32)  # once: the frame gathers read float32
        k = self._bank(float(fs))
        fs = float(fs)
        hop, n_ch, n = self.hop, x.shape[1], x.shape[0]
        s0 = int(round(t0 * fs))
        j_a = -((k.centre - s0) // hop)  # ceil((s0 - centre) / hop)
        j_b = (s0 + n - 1 - k.centre) // hop
        n_frames = j_b - j_a + 1
        if n_frames < 3:
            return [ChannelClicks(c) for c in range(n_ch)]
        frames = np.arange(j_a, j_b + 1)
        sep = max(1, int(round(self.min_separation_s * fs / hop)))
        # the frames whose statistic can decide a click in the span: its peak frame, the
        # neighbours and minimum-separation rivals of the candidates near it, and every
        # candidate within the ringing window
        f_lo, f_hi = 0, n_frames
        if span_s is not None and self.method == "stft":  # the envelope's background needs all
            echo = 0.0 if self.echo_window_s is None else self.echo_window_s[1]
            reach = int(np.ceil((self.suppress_s + echo) * fs / hop)) + 2 * sep + 8
            lo = (span_s[0] - t0) * fs + s0 - k.centre  # sample offsets of the span's ends
            hi = (span_s[1] - t0) * fs + s0 - k.centre
            f_lo = max(0, int(np.floor(lo / hop)) - reach - j_a)
            f_hi = min(n_frames, int(np.ceil(hi / hop)) + reach + 1 - j_a)
            if f_hi - f_lo < 3:
                return [ChannelClicks(c) for c in range(n_ch)]
        lap("prepare")
        frames, left, wgt, bin_bg, stat = frame_statistic(self, x, fs, s0, k, frames, f_lo, f_hi)
        j_a, n_frames = int(frames[0]), frames.size
        lap("statistic")

        out = []
        threshold = self.threshold_at(fs)
        for c in range(n_ch):
            s = stat[c]
            peaks = local_maxima(s, threshold, sep)
            if peaks.size == 0:
                out.append(ChannelClicks(c))
                continue
            a, b, d = (s[peaks - 1].astype(float), s[peaks].astype(float),
                       s[peaks + 1].astype(float))
            if self.interpolation == "log":
                a, b, d = (np.log(np.maximum(v, _TINY)) for v in (a, b, d))
            den = a - 2.0 * b + d
            delta = np.where(den < 0, 0.5 * (a - d) / np.where(den < 0, den, -1.0), 0.0)
            delta = np.clip(delta, -0.5, 0.5)
            pos = hop * (frames[peaks] + delta) + k.centre  # absolute sample
            times = t0 + (pos - s0) / fs
            power = s[peaks].astype(float)
            near = np.clip(np.round(peaks + delta), 0, n_frames - 1).astype(np.int64)
            fc = centre_frequency(x32[:, c:c + 1], s0, frames, near, k, bin_bg[c], left, wgt)
            ok = fc >= self.min_centre_freq_hz
            times, power, fc = times[ok], power[ok], fc[ok]
            keep = not_ringing(times, power, self.suppress_s, self.suppress_ratio)
            if self.echo_window_s is not None:
                keep &= not_echo(times, power, *self.echo_window_s)
            clicks = ChannelClicks(c, times[keep], power[keep], fc[keep])
            out.append(clicks if span_s is None else clicks.between(*span_s))
        lap("peaks")
        return out
