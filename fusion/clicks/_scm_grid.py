"""The synthetic grid of the smoothed click maps and the SCM1 itself (eq. 3-5).

Shared by the correlation of click maps (:mod:`fusion.clicks.scm`) and the second-order maps
(:mod:`fusion.clicks._scm2`); the public names are re-exported by :mod:`fusion.clicks.scm`.
The SCM1 spectra and series of a window's channels are kept, row by row, for the next request of
the same clicks in the same window (the correlation and the SCM2s of one window use the same
maps), keyed by content.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from threading import Lock

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray

from fusion._validation import check_positive
from fusion.clicks.types import ChannelClicks

__all__ = ["MAX_SCM_SAMPLES", "ScmConfig", "scm1", "scm1_spectrum", "window_weight"]

#: Relative size of the aliasing and truncation terms of the Gaussian gridding (see
#: :func:`scm1_spectrum`); the spectra agree with the literal sum of eq. 3 to about this.
_GRID_EPS_LOG = 32.0  # exp(-32) ~ 1.3e-14

#: Most synthetic samples ``N`` of a window (2**21: 699 s at the method's 3 kHz, 58 times its
#: 12 s). The maps of a window take a few ``N``-sample complex arrays per sensor pair, so a
#: longer window (``--window 1e9``) would ask for terabytes; it is refused instead.
MAX_SCM_SAMPLES = 1 << 21


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
        if self.window_s * self.fs_hz > MAX_SCM_SAMPLES:
            raise ValueError(f"a window of {self.window_s:g} s is longer than the "
                             f"{MAX_SCM_SAMPLES / self.fs_hz:.0f} s a smoothed click map may span "
                             f"at {self.fs_hz:g} Hz ({MAX_SCM_SAMPLES:,} samples); use a shorter "
                             "window")

    @property
    def n_samples(self) -> int:
        """``N``, synthetic samples per window."""
        return int(round(self.window_s * self.fs_hz))

    @property
    def half_width_bins(self) -> float:
        """``K``: the shading is zero from ``|k| = K`` on (``N / 8`` by default)."""
        return 0.5 * self.shading_width * self.n_samples

    @property
    def n_bins(self) -> int:
        """Bins ``0 .. n_bins - 1`` hold the whole (shaded) one-sided spectrum."""
        return min(int(np.ceil(self.half_width_bins)), self.n_samples // 2 + 1)

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
    spec = np.zeros((len(tl), cfg.n_samples // 2 + 1), dtype=complex)
    spec[:, : cfg.n_bins] = _spectra(tl, [windowed] * len(tl), t0_s=t0_s, config=cfg)
    return spec


def _spectra(tl: list[NDArray], windowed: list[bool], *, t0_s: float,
             config: ScmConfig) -> NDArray[np.complex128]:
    """Gridded SCM1 spectra of the time arrays `tl` (one row each), bins ``0 .. n_bins - 1``
    (the rest is zero), see :func:`scm1_spectrum`."""
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
    nb = config.n_bins
    return scipy.fft.rfft(g, axis=-1)[:, :nb] * deconv[:nb]


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
    tl = _as_time_list(times_s)
    spec = _spectra(tl, [windowed] * len(tl), t0_s=t0_s, config=cfg)
    return scipy.fft.irfft(spec, cfg.n_samples, axis=-1)


class _WindowMaps:
    """The SCM1 spectra (plain, and windowed once asked for) and the plain series of one
    window's channels, each row taken from the row cache when it holds it."""

    def __init__(self, tl: list[NDArray], t0_s: float, config: ScmConfig, windowed: bool) -> None:
        self.times = [t.copy() for t in tl]
        self.t0_s, self.config = float(t0_s), config
        self.plain = _cached_rows(self.times, False, self.t0_s, config)
        self._windowed: NDArray[np.complex128] | None = (
            _cached_rows(self.times, True, self.t0_s, config) if windowed else None)
        self._series: NDArray[np.float64] | None = None

    def matches(self, tl: list[NDArray], t0_s: float, config: ScmConfig) -> bool:
        """Whether these are the maps of the clicks `tl` in the window at `t0_s`."""
        return (float(t0_s) == self.t0_s and config == self.config and len(tl) == len(self.times)
                and all(a.shape == b.shape and np.array_equal(a, b)
                        for a, b in zip(tl, self.times, strict=True)))

    @property
    def windowed(self) -> NDArray[np.complex128]:
        """Windowed SCM1 spectra (eq. 5), (k, n_bins)."""
        if self._windowed is None:
            self._windowed = _cached_rows(self.times, True, self.t0_s, self.config)
        return self._windowed

    @property
    def series(self) -> NDArray[np.float64]:
        """Plain SCM1 series of every channel, (k, N)."""
        if self._series is None:
            self._series = np.stack([self.series_row(r) for r in range(len(self.times))])
        return self._series

    def series_row(self, r: int) -> NDArray[np.float64]:
        """Plain SCM1 series of channel `r`, (N,), read-only (cached by the channel's clicks)."""
        key = (self.t0_s, self.config, "series", self.times[r].tobytes())
        with _ROWS_LOCK:
            row = _ROWS.get(key)
        if row is None:
            row = scipy.fft.irfft(self.plain[r], self.config.n_samples)
            row.setflags(write=False)
            _remember(key, row)
        return row


#: SCM1 spectrum and series rows by (window start, grid, kind, the channel's click times): the
#: correlation under the drift grid and the SCM2s of a window ask for the same channels' maps
#: many times (the SCM2s of a drift read the plain and the moved clicks the correlation
#: gridded). Each row is computed as in one batch (the real FFTs and the gridding's bin sums
#: treat the rows of a batch independently), so a cached row is the row recomputed, bit for bit.
_ROWS: OrderedDict[tuple, NDArray] = OrderedDict()
_ROWS_MAX = 192
_ROWS_LOCK = Lock()


def _remember(key: tuple, row: NDArray) -> None:
    with _ROWS_LOCK:
        _ROWS[key] = row
        while len(_ROWS) > _ROWS_MAX:
            _ROWS.popitem(last=False)


def _cached_rows(tl: list[NDArray], windowed: bool, t0_s: float, config: ScmConfig
                 ) -> NDArray[np.complex128]:
    """:func:`_spectra` of the channels `tl` (all plain or all windowed), rows from the cache
    where it holds them, the others computed in one batch."""
    keys = [(t0_s, config, bool(windowed), t.tobytes()) for t in tl]
    out = np.empty((len(tl), config.n_bins), dtype=complex)
    missing = []
    with _ROWS_LOCK:
        for r, key in enumerate(keys):
            row = _ROWS.get(key)
            if row is None:
                missing.append(r)
            else:
                out[r] = row
                _ROWS.move_to_end(key)
    if missing:
        spec = _spectra([tl[r] for r in missing], [windowed] * len(missing), t0_s=t0_s,
                        config=config)
        for r, row in zip(missing, spec, strict=True):
            out[r] = row
            kept = row.copy()
            kept.setflags(write=False)
            _remember(keys[r], kept)
    return out


def window_maps(tl: list[NDArray], *, t0_s: float, config: ScmConfig,
                windowed: bool = False) -> _WindowMaps:
    """The SCM1 maps of the channels `tl` in the window at `t0_s`, each channel's rows from
    the row cache when it saw the same clicks in the same window (else computed and kept)."""
    return _WindowMaps(tl, t0_s, config, windowed)


def parabolic(ym: NDArray, y0: NDArray, yp: NDArray) -> tuple[NDArray, NDArray]:
    """Offset (samples, in [-0.5, 0.5]) and value of the parabola through three samples."""
    den = ym - 2.0 * y0 + yp
    safe = np.where(den < 0, den, -1.0)
    d = np.clip(np.where(den < 0, 0.5 * (ym - yp) / safe, 0.0), -0.5, 0.5)
    return d, y0 - 0.25 * (ym - yp) * d


def local_maxima(y: NDArray, floor: float) -> NDArray[np.bool_]:
    """Interior samples above the left neighbour, not below the right one, and >= floor."""
    out = np.zeros(y.shape, dtype=bool)
    mid = y[..., 1:-1]
    out[..., 1:-1] = (mid > y[..., :-2]) & (mid >= y[..., 2:]) & (mid >= floor)
    return out
