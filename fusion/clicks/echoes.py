"""Bottom echoes decided from the data: are the hydrophones standing near the sea floor?

A hydrophone moored a few metres above the sea floor hears every click twice: directly and,
``2 h sin(theta) / c`` later (h its height above the floor, theta the grazing angle), reflected
by the floor -- a fraction of a millisecond to tens of milliseconds after the direct arrival,
a few dB to 15 dB weaker. The method text's step 32 separates such reflections from source
signals by a threshold time; this module measures that time from the recording itself instead
of assuming it.

For each channel, the strongest detected clicks (with no stronger detection within the lags on
either side: a detected echo is not a click here) are aligned on their direct arrival and the
band-passed envelope after each click (``lag_range_s``) is averaged over them, normalised by
each click's peak; the same is done before each click as a control. A floor echo, whose lag
changes only slowly as a whale moves, builds a peak in the average after the clicks; noise and
other sources' clicks fall alike before and after. A channel shows a bottom echo when that
peak stands :data:`ECHO_Z` robust standard deviations of the control above the control's
median and :data:`CONTROL_RATIO` times as high as the control's own peak, and the array is
near the floor when at least half of its channels with enough clicks do.

What ``fusion localize`` does with it: a click that follows a stronger one within
:func:`echo_window` is taken as its echo and dropped by the detector (the method's echo
suppression), and, when the user gave no sea floor, sources are searched above the deepest
sensor minus :data:`FLOOR_MARGIN_M`, which removes the mirror image of a whale through a
near-planar bottom array.

Examples
--------
>>> import numpy as np
>>> from fusion.clicks.detect import ClickDetector
>>> from fusion.simulate.clicks import simulate_clicks
>>> sc = simulate_clicks(seed=2, n_sensors=3, n_sources=1, duration_s=8.0, echo="bottom")
>>> echoes = bottom_echoes(sc.audio, sc.fs, ClickDetector().detect(sc.audio, sc.fs))
>>> bool(echoes.near_floor)
True
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.signal
from numpy.typing import ArrayLike, NDArray

from fusion.clicks.band import DEFAULT_BAND_HZ
from fusion.clicks.types import ChannelClicks

__all__ = ["CONTROL_RATIO", "ECHO_Z", "FLOOR_MARGIN_M", "WEAK_CONTROL_RATIO", "WEAK_ECHO_Z",
           "BottomEchoes", "bottom_echoes", "echo_window"]

#: A channel shows a bottom echo when the averaged envelope after its clicks peaks this many
#: robust standard deviations (of the same average before the clicks) above the control's median.
ECHO_Z = 8.0  # tuned on seeds 0-11 (none, surface, bottom, both, varied): 0 wrong of 60

#: ... and at least this many times the peak of the same average before the clicks.
CONTROL_RATIO = 2.0

#: Once one channel shows a bottom echo (:data:`ECHO_Z`), a channel whose averaged envelope
#: after its clicks peaks this many robust standard deviations above the control's median ...
WEAK_ECHO_Z = 5.0

#: ... and at least this many times the control's own peak is taken to hear its echo too: it
#: counts towards the array's majority and its lag widens the echo window (``weak=True``).
#: Tuning seeds 0-19 of ``--vary-only click-shape``: every such channel's lag within 0.2 ms of
#: the true bottom-echo lag (docs/localization.md section 11).
WEAK_CONTROL_RATIO = 1.5

#: Sources are searched above the deepest sensor minus this when bottom echoes show, m
#: (moored hydrophones stand 1-20 m above the floor; the mirror image of a whale through a
#: bottom array lies hundreds of metres below it).
FLOOR_MARGIN_M = 30.0


@dataclass(frozen=True)
class BottomEchoes:
    """The bottom-echo evidence of each channel.

    Attributes
    ----------
    z : ndarray, shape (n_channels,)
        Height of the averaged envelope's peak after the clicks above the control's median,
        in robust standard deviations of the control (NaN: too few clicks).
    control_z : ndarray, shape (n_channels,)
        The same for the average before the clicks (its peak: other sources' clicks fall
        before a click as often as after it).
    lag_s : ndarray, shape (n_channels,)
        Lag of that peak after the direct arrival, s.
    level_db : ndarray, shape (n_channels,)
        The peak relative to the clicks' own peak envelope, dB.
    n_clicks : ndarray of int, shape (n_channels,)
        Clicks averaged.
    threshold : float
        The `z` a channel needs (:data:`ECHO_Z`).
    """

    z: NDArray[np.float64]
    control_z: NDArray[np.float64]
    lag_s: NDArray[np.float64]
    level_db: NDArray[np.float64]
    n_clicks: NDArray[np.int64]
    threshold: float = ECHO_Z
    weak: bool = True

    @property
    def present(self) -> NDArray[np.bool_]:
        """Channels showing a bottom echo: `z` at least the threshold and
        :data:`CONTROL_RATIO` times the control's."""
        z = np.nan_to_num(self.z, nan=-np.inf)
        return (z >= self.threshold) & (z >= CONTROL_RATIO * np.nan_to_num(self.control_z))

    @property
    def heard(self) -> NDArray[np.bool_]:
        """Channels taken to hear a bottom echo: those that show one (:attr:`present`) and,
        with `weak` and at least one channel showing one, those whose peak stands
        :data:`WEAK_ECHO_Z` above the control's median and :data:`WEAK_CONTROL_RATIO` times
        the control's peak (weaker evidence, read once the array is known to hear echoes)."""
        strong = self.present
        if not (self.weak and strong.any()):
            return strong
        z = np.nan_to_num(self.z, nan=-np.inf)
        return strong | ((z >= WEAK_ECHO_Z)
                         & (z >= WEAK_CONTROL_RATIO * np.nan_to_num(self.control_z)))

    @property
    def near_floor(self) -> bool:
        """At least one channel shows a bottom echo and at least half of the measured channels
        (enough clicks) hear one (:attr:`heard`)."""
        measured = np.isfinite(self.z)
        return bool(self.present.any() and self.heard[measured].mean() >= 0.5)

    def describe(self) -> str:
        """One line for the user."""
        k, n = int(self.heard.sum()), int(np.isfinite(self.z).sum())
        if not k:
            return f"no bottom echo on any of the {n} sensors with enough clicks"
        lags = self.lag_s[self.heard] * 1e3
        return (f"bottom echoes {lags.min():.2g}-{lags.max():.2g} ms after the clicks on {k} of "
                f"{n} sensors ({np.median(self.level_db[self.heard]):.0f} dB)")


def bottom_echoes(
    samples: ArrayLike,
    fs: float,
    clicks: Sequence[ChannelClicks],
    *,
    band_hz: tuple[float, float] = DEFAULT_BAND_HZ,
    lag_range_s: tuple[float, float] = (0.5e-3, 30e-3),
    max_clicks: int = 60,
    min_clicks: int = 8,
    threshold: float = ECHO_Z,
    weak: bool = True,
) -> BottomEchoes:
    """Measure, per channel, whether the clicks are followed by a bottom echo.

    Parameters
    ----------
    samples : array_like, shape (n, n_channels)
        Audio (raw, not replica-correlated), the clock of the click times starting at 0.
    fs : float
        Sample rate, Hz.
    clicks : sequence of ChannelClicks
        Detected clicks of each channel (:class:`fusion.clicks.detect.ClickDetector`).
    band_hz : (float, float), optional
        Band-pass of the envelope, Hz.
    lag_range_s : (float, float), optional
        Lags searched after (and, as the control, before) each click, s. The lower end must
        clear the click itself (a few hundred microseconds).
    max_clicks, min_clicks : int, optional
        The strongest clicks of a channel averaged; fewer than `min_clicks` give NaN.
    threshold : float, optional
        The robust z a channel needs.
    weak : bool, optional
        Once one channel shows an echo, also read the weaker evidence of the others
        (:attr:`BottomEchoes.heard`); False: every channel needs `threshold`.

    Returns
    -------
    BottomEchoes
    """
    x = np.asarray(samples, dtype=float)
    if x.ndim != 2 or x.shape[1] != len(clicks):
        raise ValueError(f"samples must have shape (n, {len(clicks)}), got {x.shape}")
    lo, hi = (float(v) for v in lag_range_s)
    if not 0 < lo < hi:
        raise ValueError(f"lag_range_s must be (low, high) with 0 < low < high, got {lag_range_s}")
    sos = scipy.signal.butter(4, [band_hz[0], min(band_hz[1], 0.45 * fs)], btype="bandpass",
                              fs=fs, output="sos")
    k_lo, k_hi = int(round(lo * fs)), int(round(hi * fs))
    half = max(1, int(round(0.2e-3 * fs)))  # the direct arrival's peak: +-0.2 ms
    n_ch = len(clicks)
    z = np.full(n_ch, np.nan)
    control = np.full(n_ch, np.nan)
    lag = np.full(n_ch, np.nan)
    level = np.full(n_ch, np.nan)
    used = np.zeros(n_ch, dtype=np.int64)
    for ch, c in enumerate(clicks):
        times = np.asarray(c.times_s, dtype=float)
        power = np.asarray(c.power, dtype=float)
        idx = np.round(times * fs).astype(np.int64)
        keep = (idx - k_hi >= 0) & (idx + k_hi < x.shape[0]) & _dominant(times, power, lo, hi)
        idx, power = idx[keep], power[keep]
        if idx.size < min_clicks:
            continue
        idx = idx[np.argsort(-power, kind="stable")[:max_clicks]]
        after = np.empty((idx.size, k_hi - k_lo))
        before = np.empty_like(after)
        for m, i in enumerate(idx):
            seg = np.abs(scipy.signal.hilbert(
                scipy.signal.sosfiltfilt(sos, x[i - k_hi - half:i + k_hi + half + 1, ch])))
            mid = k_hi + half
            peak = seg[mid - half:mid + half + 1].max()
            if peak <= 0:
                peak = 1.0
            after[m] = seg[mid + k_lo:mid + k_hi] / peak
            before[m] = seg[mid - k_hi + 1:mid - k_lo + 1][::-1] / peak
        a, b = after.mean(axis=0), before.mean(axis=0)
        med = float(np.median(b))
        spread = 1.4826 * float(np.median(np.abs(b - med)))
        j = int(np.argmax(a))
        spread = max(spread, 1e-12)
        z[ch] = (a[j] - med) / spread
        control[ch] = (b.max() - med) / spread
        lag[ch] = (k_lo + j) / fs
        level[ch] = 20.0 * np.log10(max(a[j], 1e-12))
        used[ch] = idx.size
    return BottomEchoes(z, control, lag, level, used, float(threshold), bool(weak))


def _dominant(times: NDArray[np.float64], power: NDArray[np.float64], lo: float,
              hi: float) -> NDArray[np.bool_]:
    """Clicks with no stronger detection ``lo`` to ``hi`` before or after them.

    A detected echo has its (stronger) direct arrival before it and is left out, so it does
    not bring that arrival into the control; the rule is the same on both sides, so other
    sources' clicks leave the average and the control alike.
    """
    order = np.argsort(times, kind="stable")
    t, pw = times[order], power[order]
    keep = np.ones(t.size, dtype=bool)
    for side in (-1.0, 1.0):
        a = np.searchsorted(t, t + side * (hi if side < 0 else lo), side="left")
        b = np.searchsorted(t, t + side * (lo if side < 0 else hi), side="right")
        for m in range(t.size):
            if b[m] > a[m] and pw[a[m]:b[m]].max() > pw[m]:
                keep[m] = False
    out = np.empty_like(keep)
    out[order] = keep
    return out


def echo_window(echoes: BottomEchoes, *, floor_s: float = 0.25e-3,
                cap_s: float = 30e-3) -> tuple[float, float]:
    """Lags after a click within which a weaker click is taken as its echo, s.

    From `floor_s` (the detector's minimum separation) to twice the longest bottom-echo lag
    measured on a channel hearing one (:attr:`BottomEchoes.heard`; a moving whale changes the
    grazing angle, and with it the lag, over a recording), at most `cap_s`.
    """
    lags = echoes.lag_s[echoes.heard]
    if not lags.size:
        raise ValueError("no channel shows a bottom echo")
    return float(floor_s), float(min(cap_s, max(2.0 * float(lags.max()), 2.0 * floor_s)))
