"""Smoothed click maps (SCM1), their correlation, TDOA candidate peaks and SCM2.

Implements steps 44-48 and the SCM2 of *Localization of Short Duration Periodic Signals*
(Baggenstoss, NUWC 102089; the project's method text ``localization-short-periodic-signals``,
paragraphs [0032]-[0036], eq. 3-6):

=====  ======================================================  ===============================
step   method                                                   here
=====  ======================================================  ===============================
44     click map of impulses at the click times, smoothed by    :func:`scm1_spectrum` (eq. 3, 4)
       frequency-domain Hann shading (SCM1)
46     time-windowed SCM1 against wrap-around                   ``windowed=True`` (eq. 5)
48     correlation of a windowed and a plain SCM1               :meth:`ClickMapCorrelator.correlate`
                                                                (eq. 6)
--     candidate TDOAs: local maxima within the physically      :class:`TdoaPeak`
       possible delay of the pair (added)
50     SCM2: product of the SCM1 of sensor i and the SCM1 of    :func:`scm2`
       sensor j delayed by tau; its peaks are the clicks the
       pair matched
=====  ======================================================  ===============================

Sign convention: with sensor ``a = i`` windowed and ``b = j`` plain in eq. 6 the correlation
peaks at ``tau = t_i - t_j``, the TDOA of pair ``(i, j)`` as in the file formats.

The correlation value approximates the number of clicks the two maps share, each weighted by
the time window of eq. 5 at its time (1 at the window centre, 0.37 at a quarter window from it,
0.45 on average over the window) and by the correlation pulse at its residual mismatch (1 at no
mismatch, 0.5 at about 5 synthetic samples, 1.7 ms). A single click correlated with itself
gives exactly 1 (eq. 4).

Examples
--------
>>> import numpy as np
>>> cfg = ScmConfig()
>>> ti = np.array([5.4, 5.77, 6.14, 6.51])  # four clicks near the window centre
>>> c = ClickMapCorrelator(config=cfg).correlate_times([ti, ti - 0.2], t0_s=0.0, max_delay_s=[1.0])
>>> round(c.peaks[0].tau_s, 6), round(c.peaks[0].value, 2)
(0.2, 4.0)
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray

from fusion._validation import check_positive
from fusion.clicks.types import ChannelClicks, frozen_array
from fusion.geometry import SensorArray

__all__ = [
    "ClickMapCorrelator",
    "Scm2",
    "ScmConfig",
    "ScmCorrelation",
    "TdoaPeak",
    "scm1",
    "scm1_spectrum",
    "scm2",
    "window_weight",
]

logger = logging.getLogger(__name__)

#: Relative size of the aliasing and truncation terms of the Gaussian gridding (see
#: :func:`scm1_spectrum`); the spectra agree with the literal sum of eq. 3 to about this.
_GRID_EPS_LOG = 32.0  # exp(-32) ~ 1.3e-14


@dataclass(frozen=True)
class ScmConfig:
    """The synthetic grid of the smoothed click maps.

    Attributes
    ----------
    window_s : float
        Window length ``T``, s (the method's 12 s).
    fs_hz : float
        Synthetic sample rate ``f_s``, Hz (the method's 3 kHz); ``N = round(T f_s)`` samples.
    shading_width : float
        Total width of the frequency-domain Hann shading ``W_k`` as a fraction of ``N`` (the
        method's ``N / 4``: zero at ``k = +-N / 8``); at most 0.5.
    """

    window_s: float = 12.0
    fs_hz: float = 3000.0
    shading_width: float = 0.25

    def __post_init__(self) -> None:
        check_positive("window_s", self.window_s)
        check_positive("fs_hz", self.fs_hz)
        check_positive("shading_width", self.shading_width)
        if self.shading_width > 0.5:
            raise ValueError(f"shading_width must be <= 0.5, got {self.shading_width!r}")
        if self.n_samples < 64:
            raise ValueError(f"window_s * fs_hz must give >= 64 samples, got {self.n_samples}")

    @property
    def n_samples(self) -> int:
        """``N``, synthetic samples per window."""
        return int(round(self.window_s * self.fs_hz))

    @property
    def half_width_bins(self) -> float:
        """``K``: the shading is zero from ``|k| = K`` on (``N / 8`` by default)."""
        return 0.5 * self.shading_width * self.n_samples

    @property
    def pulse_peak(self) -> float:
        """Peak of one click's SCM1 pulse, ``c w_0`` (0.408 by default)."""
        return _grid(self.n_samples, self.half_width_bins)[3]

    @property
    def pulse_halfwidth_s(self) -> float:
        """Time from a click's SCM1 pulse peak to its first zero, ``N / (K f_s)``, s."""
        return self.n_samples / self.half_width_bins / self.fs_hz


@lru_cache(maxsize=16)
def _grid(n: int, k_half: float) -> tuple[NDArray, NDArray, float, float, float, int]:
    """Shading, deconvolved shading, c, pulse peak, Gaussian width and half-support."""
    k = np.arange(n // 2 + 1)
    # eq. 3 shading: Hann of total width 2K bins, zero at |k| = K
    shading = np.where(k < k_half, 0.5 * (1.0 + np.cos(np.pi * k / k_half)), 0.0)
    w = scipy.fft.irfft(shading, n)  # w_t, the smoothing pulse
    c = 1.0 / np.sqrt(np.sum(w * w))  # eq. 4
    # Gaussian gridding kernel exp(-x^2 / (2 s^2)) (x in samples): its transform
    # s sqrt(2 pi) exp(-2 pi^2 s^2 nu^2) aliases from |nu| >= 1 - K/N onto |nu| <= K/N with
    # relative size exp(-2 pi^2 s^2 (1 - 2 K/N)); choose s so that this is exp(-_GRID_EPS_LOG).
    nu_max = k_half / n
    s2 = _GRID_EPS_LOG / (2.0 * np.pi**2 * (1.0 - 2.0 * nu_max))
    half_support = int(np.ceil(np.sqrt(2.0 * _GRID_EPS_LOG * s2)))
    kernel_ft = np.sqrt(2.0 * np.pi * s2) * np.exp(-2.0 * np.pi**2 * s2 * (k / n) ** 2)
    deconv = np.where(shading > 0, c * shading / kernel_ft, 0.0)
    for a in (shading, deconv):
        a.setflags(write=False)
    return shading, deconv, float(c), float(c * w[0]), float(s2), half_support


def window_weight(t_rel_s: ArrayLike, window_s: float) -> NDArray[np.float64]:
    """The time window of eq. 5, ``exp(-(t - T/2)^4 / (T/4)^4)``.

    Parameters
    ----------
    t_rel_s : array_like, any shape
        Times from the start of the window, s.
    window_s : float
        Window length ``T``, s.

    Returns
    -------
    ndarray, same shape as `t_rel_s`
        Weights in ``(0, 1]``, 1 at the window centre.
    """
    x = (np.asarray(t_rel_s, dtype=float) - 0.5 * window_s) / (0.25 * window_s)
    return np.exp(-(x**4))


def _as_time_list(times: Sequence[ArrayLike] | Sequence[ChannelClicks]) -> list[NDArray]:
    out = []
    for t in times:
        a = np.asarray(t.times_s if isinstance(t, ChannelClicks) else t, dtype=float).ravel()
        if not np.all(np.isfinite(a)):
            raise ValueError("click times must be finite")
        out.append(a)
    return out


def scm1_spectrum(
    times_s: Sequence[ArrayLike] | Sequence[ChannelClicks],
    *,
    t0_s: float,
    config: ScmConfig | None = None,
    windowed: bool = False,
) -> NDArray[np.complex128]:
    """One-sided spectra of the SCM1 of several channels (eq. 3, or eq. 5 when `windowed`).

    Parameters
    ----------
    times_s : sequence of array_like or of ChannelClicks, length n_channels
        Click times of each channel, s from the start of the audio. Clicks outside
        ``[t0_s, t0_s + T)`` are ignored.
    t0_s : float
        Start of the window, s from the start of the audio.
    config : ScmConfig, optional
        The synthetic grid (default :class:`ScmConfig`).
    windowed : bool, optional
        Weight each click by the time window of eq. 5 (:func:`window_weight`).

    Returns
    -------
    ndarray of complex, shape (n_channels, N // 2 + 1)
        ``X_k`` for ``k = 0 .. N/2`` (the negative-frequency half is the conjugate).

    Notes
    -----
    ``X_k = c W_k sum_n a_n exp(-j 2 pi k u_n / N)`` with ``u_n = (t_n - t0) f_s`` (eq. 3;
    ``a_n = 1``, or the window weight of eq. 5). The constant ``c`` multiplies eq. 5 as well,
    so that a click at the window centre correlates to exactly 1 with itself (the text's
    eq. 5 omits it). The sum is not evaluated term by term: each click is spread onto the grid
    with a Gaussian of width ``s`` samples at its fractional position (``2 h + 2`` samples per
    click), the grid is transformed with one real FFT, and the Gaussian's transform is divided
    out, which is exact up to aliasing and truncation terms of relative size 1e-14 because
    the shading confines the spectrum to ``|k| < N/8`` (a type-1 non-uniform FFT by gridding:
    Dutt and Rokhlin, *SIAM J. Sci. Comput.* 14, 1993; Greengard and Lee, *SIAM Rev.* 46,
    2004).
    """
    cfg = ScmConfig() if config is None else config
    tl = _as_time_list(times_s)
    return _spectra(tl, [windowed] * len(tl), t0_s=t0_s, config=cfg)


def _spectra(tl: list[NDArray], windowed: list[bool], *, t0_s: float,
             config: ScmConfig) -> NDArray[np.complex128]:
    """Gridded SCM1 spectra of the time arrays `tl` (one row each), see :func:`scm1_spectrum`."""
    n, fs = config.n_samples, config.fs_hz
    _, deconv, _, _, s2, h = _grid(n, config.half_width_bins)
    rows, pos, amp = [], [], []
    for r, (t, win) in enumerate(zip(tl, windowed, strict=True)):
        u = (t - t0_s) * fs
        u = u[(u >= 0) & (u < n)]
        rows.append(np.full(u.size, r))
        pos.append(u)
        amp.append(window_weight(u / fs, config.window_s) if win else np.ones(u.size))
    row, u, a = np.concatenate(rows), np.concatenate(pos), np.concatenate(amp)
    m = np.floor(u).astype(np.int64)[:, None] + np.arange(-h, h + 2)  # grid points near each click
    vals = a[:, None] * np.exp(-((m - u[:, None]) ** 2) / (2.0 * s2))
    flat = (row[:, None] * n + np.mod(m, n)).ravel()  # eq. 3 is N-periodic: wrap
    g = np.bincount(flat, vals.ravel(), minlength=len(tl) * n).reshape(len(tl), n)
    return scipy.fft.rfft(g, axis=-1) * deconv


def scm1(
    times_s: Sequence[ArrayLike] | Sequence[ChannelClicks],
    *,
    t0_s: float,
    config: ScmConfig | None = None,
    windowed: bool = False,
) -> NDArray[np.float64]:
    """SCM1 time series of several channels on the synthetic grid.

    Parameters
    ----------
    times_s, t0_s, config, windowed
        As in :func:`scm1_spectrum`.

    Returns
    -------
    ndarray, shape (n_channels, N)
        Sample ``m`` is at ``t0_s + m / f_s``; each click is a pulse of height
        ``config.pulse_peak`` (times its window weight), zero ``pulse_halfwidth_s`` away.
    """
    cfg = ScmConfig() if config is None else config
    spec = scm1_spectrum(times_s, t0_s=t0_s, config=cfg, windowed=windowed)
    return scipy.fft.irfft(spec, cfg.n_samples, axis=-1)


def _parabolic(ym: NDArray, y0: NDArray, yp: NDArray) -> tuple[NDArray, NDArray]:
    """Offset (samples, in [-0.5, 0.5]) and value of the parabola through three samples."""
    den = ym - 2.0 * y0 + yp
    safe = np.where(den < 0, den, -1.0)
    d = np.clip(np.where(den < 0, 0.5 * (ym - yp) / safe, 0.0), -0.5, 0.5)
    return d, y0 - 0.25 * (ym - yp) * d


def _local_maxima(y: NDArray, floor: float) -> NDArray[np.bool_]:
    """Interior samples above the left neighbour, not below the right one, and >= floor."""
    out = np.zeros(y.shape, dtype=bool)
    mid = y[..., 1:-1]
    out[..., 1:-1] = (mid > y[..., :-2]) & (mid >= y[..., 2:]) & (mid >= floor)
    return out


@dataclass(frozen=True)
class TdoaPeak:
    """A candidate TDOA: a local maximum of the SCM correlation of one sensor pair.

    Attributes
    ----------
    pair : (int, int)
        Sensor indices ``(i, j)``.
    tau_s : float
        Delay ``t_i - t_j`` of the peak (parabolic-interpolated on the synthetic grid), s.
    value : float
        Interpolated correlation value: about the window-weighted number of matched clicks.
    """

    pair: tuple[int, int]
    tau_s: float
    value: float


@dataclass(frozen=True)
class ScmCorrelation:
    """SCM correlations (eq. 6) of the sensor pairs of one window and their candidate peaks.

    Attributes
    ----------
    t0_s : float
        Start of the window, s from the start of the audio.
    pairs : ndarray of int, shape (n_pairs, 2)
        Sensor pairs ``(i, j)``.
    lags_s : ndarray, shape (n_lags,)
        Delays ``tau`` of the correlation samples, ``-T/4 .. T/4`` on the synthetic grid, s.
    values : ndarray, shape (n_pairs, n_lags)
        ``c(tau)`` of eq. 6 for each pair.
    max_delay_s : ndarray, shape (n_pairs,)
        Largest ``|tau|`` searched for peaks in each pair, s.
    peaks : tuple of TdoaPeak
        Candidate TDOAs, pair by pair in the order of `pairs`, strongest first within a pair.
    """

    t0_s: float
    pairs: NDArray[np.int64]
    lags_s: NDArray[np.float64]
    values: NDArray[np.float64]
    max_delay_s: NDArray[np.float64]
    peaks: tuple[TdoaPeak, ...]

    def peaks_of(self, pair: tuple[int, int]) -> tuple[TdoaPeak, ...]:
        """The candidate peaks of one pair, strongest first."""
        key = (int(pair[0]), int(pair[1]))
        return tuple(p for p in self.peaks if p.pair == key)


class ClickMapCorrelator:
    """Correlate the SCM1s of every sensor pair in a window and pick candidate TDOAs.

    Parameters
    ----------
    config : ScmConfig, optional
        The synthetic grid (window ``T``, rate ``f_s``, shading); default :class:`ScmConfig`.
    delay_margin : float, optional
        Relative allowance on the largest physical delay ``d_ij / c`` (sound-speed and
        position errors), default 0.05.
    delay_guard_s : float, optional
        Absolute allowance added to it, s; default 2 ms (about the half-width of the
        correlation pulse, so that a peak at the physical limit is still a local maximum).
    min_peak : float, optional
        Smallest correlation value of a candidate, default 1.5: two matched clicks within
        about 2.2 s of the window centre (window weight >= 0.75 each), or three to four spread
        over the window. A single click pair (<= 1) never qualifies.
    max_peaks : int, optional
        At most this many candidates per pair (the strongest), default 3.

    Notes
    -----
    The correlation of eq. 6 is evaluated as ``irfft(Xw_i * conj(X_j), N)``: with the windowed
    SCM1 of sensor ``i`` (eq. 5) and the plain SCM1 of sensor ``j`` (eq. 3) it peaks at
    ``tau = t_i - t_j`` and is free of wrap-around for ``|tau| <= T/4`` ([0035]). Peaks are
    searched within ``|tau| <= min(T/4, d_ij / c (1 + delay_margin) + delay_guard_s)``, the
    delays a source can produce, and located by parabolic interpolation.
    """

    def __init__(
        self,
        *,
        config: ScmConfig | None = None,
        delay_margin: float = 0.05,
        delay_guard_s: float = 0.002,
        min_peak: float = 1.5,
        max_peaks: int = 3,
    ) -> None:
        self.config = ScmConfig() if config is None else config
        self.delay_margin = check_positive("delay_margin", delay_margin, allow_zero=True)
        self.delay_guard_s = check_positive("delay_guard_s", delay_guard_s, allow_zero=True)
        self.min_peak = check_positive("min_peak", min_peak)
        if isinstance(max_peaks, bool) or int(max_peaks) != max_peaks or max_peaks < 1:
            raise ValueError(f"max_peaks must be an integer >= 1, got {max_peaks!r}")
        self.max_peaks = int(max_peaks)

    def correlate(
        self,
        clicks: Sequence[ChannelClicks] | Sequence[ArrayLike],
        *,
        t0_s: float,
        sensors: SensorArray,
        pairs: ArrayLike | None = None,
    ) -> ScmCorrelation:
        """SCM correlations and candidate TDOAs of one window.

        Parameters
        ----------
        clicks : sequence of ChannelClicks or of array_like, length n_sensors
            Click times of every channel (channel ``k`` is ``sensors.positions[k]``), s.
        t0_s : float
            Start of the window, s from the start of the audio.
        sensors : SensorArray
            Sensor positions and sound speed (for the physically possible delays).
        pairs : array_like of int, shape (n_pairs, 2), optional
            Sensor pairs ``(i, j)``; default every pair ``i < j``.

        Returns
        -------
        ScmCorrelation
        """
        if len(clicks) != sensors.n_sensors:
            raise ValueError(f"{len(clicks)} click channels for {sensors.n_sensors} sensors")
        pr = np.asarray(sensors.pairs() if pairs is None else pairs, dtype=np.int64).reshape(-1, 2)
        if pr.size and (pr.min() < 0 or pr.max() >= sensors.n_sensors or np.any(pr[:, 0] == pr[:, 1])):
            raise ValueError(f"pairs must hold two different sensor indices < {sensors.n_sensors}")
        sep = np.linalg.norm(sensors.positions[pr[:, 0]] - sensors.positions[pr[:, 1]], axis=1)
        max_delay = sep / sensors.sound_speed * (1.0 + self.delay_margin) + self.delay_guard_s
        return self.correlate_times(clicks, t0_s=t0_s, max_delay_s=max_delay, pairs=pr)

    def correlate_times(
        self,
        clicks: Sequence[ChannelClicks] | Sequence[ArrayLike],
        *,
        t0_s: float,
        max_delay_s: ArrayLike,
        pairs: ArrayLike | None = None,
    ) -> ScmCorrelation:
        """As :meth:`correlate`, with the largest delay of each pair given directly.

        Parameters
        ----------
        clicks : sequence of ChannelClicks or of array_like
            Click times of every channel, s.
        t0_s : float
            Start of the window, s.
        max_delay_s : array_like, shape (n_pairs,)
            Largest ``|tau|`` searched in each pair, s (capped at ``T/4``).
        pairs : array_like of int, shape (n_pairs, 2), optional
            Default ``[(0, 1)]``.

        Returns
        -------
        ScmCorrelation
        """
        cfg = self.config
        n = cfg.n_samples
        pr = np.asarray([(0, 1)] if pairs is None else pairs, dtype=np.int64).reshape(-1, 2)
        max_delay = np.broadcast_to(np.asarray(max_delay_s, dtype=float), (pr.shape[0],))
        if pr.size and pr.max() >= len(clicks):
            raise ValueError(f"pairs refer to channel {pr.max()} but only {len(clicks)} are given")
        if np.any(~np.isfinite(max_delay)) or np.any(max_delay <= 0):
            raise ValueError("max_delay_s must be positive")
        tl = _as_time_list(clicks)
        used = np.unique(pr)
        row = {int(ch): r for r, ch in enumerate(used)}
        sel = [tl[ch] for ch in used]
        # rows 0 .. u-1: plain SCM1 (eq. 3); rows u .. 2u-1: windowed SCM1 (eq. 5); one FFT
        spec = _spectra(sel + sel, [False] * len(sel) + [True] * len(sel), t0_s=t0_s, config=cfg)
        ia = np.array([row[int(i)] for i in pr[:, 0]], dtype=np.int64)
        ib = np.array([row[int(j)] for j in pr[:, 1]], dtype=np.int64)
        # eq. 6: c(m) = (1/N) sum_k Xw_i(k) conj(X_j(k)) e^{j 2 pi k m / N}, peak at m = (t_i - t_j) fs
        corr = scipy.fft.irfft(spec[len(used) + ia] * np.conj(spec[ib]), n, axis=-1)
        q = n // 4  # |tau| <= T/4: no wrap-around
        lags = np.arange(-q, q + 1)
        values = corr[:, np.mod(lags, n)]
        limit = np.minimum(max_delay, q / cfg.fs_hz)
        peaks = self._peaks(values, lags, limit, pr)
        return ScmCorrelation(
            t0_s=float(t0_s), pairs=frozen_array(pr, np.int64), lags_s=frozen_array(lags / cfg.fs_hz),
            values=frozen_array(values), max_delay_s=frozen_array(limit), peaks=peaks,
        )

    def _peaks(self, values: NDArray, lags: NDArray, limit: NDArray, pairs: NDArray) -> tuple:
        fs = self.config.fs_hz
        is_max = _local_maxima(values, self.min_peak)
        is_max &= np.abs(lags)[None, :] <= limit[:, None] * fs
        out: list[TdoaPeak] = []
        for p in range(pairs.shape[0]):
            idx = np.flatnonzero(is_max[p])
            idx = idx[np.argsort(values[p, idx])[::-1][: self.max_peaks]]
            d, v = _parabolic(values[p, idx - 1], values[p, idx], values[p, idx + 1])
            pair = (int(pairs[p, 0]), int(pairs[p, 1]))
            order = np.argsort(v)[::-1]
            out += [TdoaPeak(pair, float((lags[idx[k]] + d[k]) / fs), float(v[k])) for k in order]
        return tuple(out)


@dataclass(frozen=True)
class Scm2:
    """Second-order smoothed click map of a sensor pair at one delay ([0036]).

    Attributes
    ----------
    pair : (int, int)
        Sensor indices ``(i, j)`` (informational).
    tau_s : float
        The delay ``t_i - t_j`` applied, s.
    t0_s : float
        Time of sample 0, s from the start of the audio (sensor ``i``'s clock).
    fs_hz : float
        Synthetic sample rate, Hz.
    series : ndarray, shape (N,)
        ``SCM1_i(t) SCM1_j(t - tau) / p0^2`` with ``p0`` the peak of one click's SCM1 pulse:
        a click matched with no residual mismatch gives a peak of 1.
    click_times_s : ndarray, shape (m,)
        Source click estimates: local maxima of `series` at or above the level,
        parabolic-interpolated, s from the start of the audio, referenced to sensor ``i``.
    peak_values : ndarray, shape (m,)
        `series` at those maxima.
    index_i, index_j : ndarray of int, shape (m_matched,)
        The click pairs SCM2 matched: positions in the input time arrays of sensor ``i`` and
        of sensor ``j`` (each click used at most once; the strongest SCM2 peak wins).
    """

    pair: tuple[int, int]
    tau_s: float
    t0_s: float
    fs_hz: float
    series: NDArray[np.float64]
    click_times_s: NDArray[np.float64]
    peak_values: NDArray[np.float64]
    index_i: NDArray[np.int64]
    index_j: NDArray[np.int64]

    @property
    def times_s(self) -> NDArray[np.float64]:
        """Times of the samples of `series`, s from the start of the audio."""
        return self.t0_s + np.arange(self.series.size) / self.fs_hz


def scm2(
    times_i: ArrayLike,
    times_j: ArrayLike,
    tau_s: float,
    *,
    t0_s: float,
    config: ScmConfig | None = None,
    level: float = 0.5,
    pair: tuple[int, int] = (0, 1),
) -> Scm2:
    """SCM2 of a pair at delay `tau_s`: the source click train seen by both sensors.

    Parameters
    ----------
    times_i, times_j : array_like, shape (n_i,), (n_j,)
        Click times on sensors ``i`` and ``j``, s from the start of the audio.
    tau_s : float
        Delay ``t_i - t_j``, s (a candidate from :class:`ClickMapCorrelator`).
    t0_s : float
        Start of the window, s (sensor ``i``'s clock).
    config : ScmConfig, optional
        The synthetic grid.
    level : float, optional
        Smallest normalised SCM2 peak counted as a source click, in ``(0, 1]``; default 0.5:
        the two clicks agree to within about 5.6 synthetic samples (1.9 ms at 3 kHz).
    pair : (int, int), optional
        Sensor indices, recorded in the result.

    Returns
    -------
    Scm2

    Notes
    -----
    Sensor ``j``'s clicks are placed at ``t_j + tau`` (its SCM1 delayed by ``tau``), so that a
    click of one source sits at the same time ``t_i`` in both maps; the SCM2 is their product
    on the plain (not time-windowed) SCM1s, referenced to sensor ``i`` ([0036]). A peak is
    matched to the nearest click of ``i`` and of ``j`` (shifted) when both lie within the
    pulse half-width ``config.pulse_halfwidth_s`` of it.
    """
    cfg = ScmConfig() if config is None else config
    if not (np.isfinite(level) and 0 < level <= 1):
        raise ValueError(f"level must be in (0, 1], got {level!r}")
    if not np.isfinite(tau_s):
        raise ValueError(f"tau_s must be finite, got {tau_s!r}")
    ti, tj = _as_time_list([times_i, times_j])
    maps = scm1([ti, tj + tau_s], t0_s=t0_s, config=cfg)
    series = maps[0] * maps[1] / cfg.pulse_peak**2
    idx = np.flatnonzero(_local_maxima(series, level))
    d, v = _parabolic(series[idx - 1], series[idx], series[idx + 1])
    tc = t0_s + (idx + d) / cfg.fs_hz
    index_i, index_j = _match(tc, v, ti, tj + tau_s, cfg.pulse_halfwidth_s)
    return Scm2(
        pair=(int(pair[0]), int(pair[1])), tau_s=float(tau_s), t0_s=float(t0_s),
        fs_hz=cfg.fs_hz, series=frozen_array(series), click_times_s=frozen_array(tc),
        peak_values=frozen_array(v), index_i=frozen_array(index_i, np.int64),
        index_j=frozen_array(index_j, np.int64),
    )


def _nearest(sorted_or_not: NDArray, t: NDArray) -> tuple[NDArray, NDArray]:
    """Index of the element of `sorted_or_not` nearest each `t`, and the distance."""
    if sorted_or_not.size == 0:
        return np.zeros(t.size, dtype=np.int64), np.full(t.size, np.inf)
    order = np.argsort(sorted_or_not, kind="stable")
    s = sorted_or_not[order]
    k = np.clip(np.searchsorted(s, t), 1, max(s.size - 1, 1))
    lo = np.clip(k - 1, 0, s.size - 1)
    hi = np.clip(k, 0, s.size - 1)
    pick = np.where(np.abs(s[hi] - t) < np.abs(s[lo] - t), hi, lo)
    return order[pick], np.abs(s[pick] - t)


def _match(tc: NDArray, v: NDArray, ti: NDArray, tj_shift: NDArray,
           tol: float) -> tuple[NDArray, NDArray]:
    """Clicks of i and of (shifted) j nearest each SCM2 peak, both within `tol`, used once."""
    ni, di = _nearest(ti, tc)
    nj, dj = _nearest(tj_shift, tc)
    ok = np.flatnonzero((di <= tol) & (dj <= tol))
    ok = ok[np.argsort(v[ok])[::-1]]  # strongest peak first keeps a shared click
    _, first_i = np.unique(ni[ok], return_index=True)
    ok = ok[np.sort(first_i)]
    _, first_j = np.unique(nj[ok], return_index=True)
    ok = np.sort(ok[np.sort(first_j)])
    return ni[ok], nj[ok]
