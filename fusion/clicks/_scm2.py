"""Second-order smoothed click maps (SCM2, [0036]): the click train a sensor pair shares at a delay.

Public names are re-exported by :mod:`fusion.clicks.scm`. :func:`scm2_many` builds the SCM2s of
every candidate delay of a window from each channel's SCM1 spectrum computed once (the delayed
map of sensor ``j`` is its spectrum times a phase ramp, one inverse FFT per candidate);
:func:`scm2` is one of them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray

from fusion.clicks._scm_grid import ScmConfig, _as_time_list, _grid, parabolic, window_maps
from fusion.clicks.types import ChannelClicks, frozen_array

__all__ = ["Scm2", "scm2", "scm2_many"]

_CHUNK = 8  # SCM2s built per inverse FFT batch (keeps the working set in cache)


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
        Delay ``t_i - t_j``, s (a candidate from :class:`fusion.clicks.scm.ClickMapCorrelator`).
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
    pulse half-width ``config.pulse_halfwidth_s`` of it. See :func:`scm2_many` for the
    computation.
    """
    res = scm2_many([times_i, times_j], [(0, 1)], [tau_s], t0_s=t0_s, config=config,
                    level=level)[0]
    return Scm2(**{**res.__dict__, "pair": (int(pair[0]), int(pair[1]))})


def scm2_many(
    times: Sequence[ArrayLike] | Sequence[ChannelClicks],
    pairs: ArrayLike,
    taus_s: ArrayLike,
    *,
    t0_s: float,
    config: ScmConfig | None = None,
    level: float = 0.5,
) -> list[Scm2]:
    """SCM2s of several candidate TDOAs of one window.

    Parameters
    ----------
    times : sequence of array_like or of ChannelClicks, length n_channels
        Click times of every channel, s from the start of the audio.
    pairs : array_like of int, shape (m, 2)
        Sensor pair ``(i, j)`` of each candidate (indices into `times`).
    taus_s : array_like, shape (m,)
        Delay ``t_i - t_j`` of each candidate, s.
    t0_s : float
        Start of the window, s.
    config : ScmConfig, optional
        The synthetic grid.
    level : float, optional
        Smallest normalised SCM2 peak counted as a source click (see :func:`scm2`).

    Returns
    -------
    list of Scm2
        ``scm2(times[i], times[j], tau, t0_s=t0_s, config=config, level=level, pair=(i, j))``
        for each candidate, in order; the series are rows of one read-only array.

    Notes
    -----
    Each channel's SCM1 spectrum (eq. 3) is computed once for the window (and shared with the
    correlation of :class:`fusion.clicks.scm.ClickMapCorrelator` when it saw the same clicks).
    Delaying sensor ``j``'s clicks by ``tau`` multiplies its spectrum by
    ``exp(-j 2 pi k tau f_s / N)``; the clicks that the delay moves across an edge of the
    window (eq. 3 keeps only ``0 <= u < N``, and is periodic) have their terms of eq. 3
    removed or added directly (prefix sums over the few clicks near the edges). One inverse
    FFT per candidate then gives the delayed SCM1, and the product with sensor ``i``'s SCM1
    (one inverse FFT per channel) the SCM2: the same as gridding the delayed clicks anew, to
    rounding.
    """
    cfg = ScmConfig() if config is None else config
    if not (np.isfinite(level) and 0 < level <= 1):
        raise ValueError(f"level must be in (0, 1], got {level!r}")
    taus = np.asarray(taus_s, dtype=float).ravel()
    if not np.all(np.isfinite(taus)):
        raise ValueError(f"tau_s must be finite, got {taus_s!r}")
    pr = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    if pr.shape[0] != taus.size:
        raise ValueError(f"{pr.shape[0]} pairs for {taus.size} delays")
    tl = _as_time_list(times)
    if pr.size and (pr.min() < 0 or pr.max() >= len(tl)):
        raise ValueError(f"pairs must index the {len(tl)} click channels")
    m = taus.size
    if m == 0:
        return []
    n, fs, nb = cfg.n_samples, cfg.fs_hz, cfg.n_bins
    p0 = cfg.pulse_peak
    maps = window_maps(tl, t0_s=t0_s, config=cfg)
    base = {i: maps.series_row(i) / p0**2 for i in np.unique(pr[:, 0]).tolist()}  # SCM1_i / p0^2
    shift = taus * fs  # delay in synthetic samples
    edge_rows, edges = _edge_terms(tl, pr[:, 1], t0_s, shift, cfg)
    series = np.empty((m, n))
    for a in range(0, m, _CHUNK):
        b = min(a + _CHUNK, m)
        spec = maps.plain[pr[a:b, 1]]
        for e in np.flatnonzero((edge_rows >= a) & (edge_rows < b)):
            spec[edge_rows[e] - a] -= edges[e]
        spec *= _phase(shift[a:b], nb, n)
        series[a:b] = scipy.fft.irfft(spec, n, axis=-1)
        for r in range(a, b):
            series[r] *= base[int(pr[r, 0])]
    series.setflags(write=False)
    rows, idx = _maxima(series, level)
    cut = np.searchsorted(rows, np.arange(m + 1))
    order = [np.argsort(t, kind="stable") for t in tl]
    srt = [t[o] for t, o in zip(tl, order, strict=True)]
    tol = cfg.pulse_halfwidth_s
    out = []
    for r in range(m):
        i, j = int(pr[r, 0]), int(pr[r, 1])
        k = idx[cut[r]:cut[r + 1]]
        s = series[r]
        d, v = parabolic(s[k - 1], s[k], s[k + 1])
        tc = t0_s + (k + d) / fs
        ni, di = _nearest(srt[i], order[i], tc)
        nj, dj = _nearest(srt[j] + taus[r], order[j], tc)
        index_i, index_j = _match(ni, di, nj, dj, v, tol)
        out.append(Scm2(
            pair=(i, j), tau_s=float(taus[r]), t0_s=float(t0_s), fs_hz=fs, series=s,
            click_times_s=frozen_array(tc), peak_values=frozen_array(v),
            index_i=frozen_array(index_i, np.int64), index_j=frozen_array(index_j, np.int64),
        ))
    return out


def _phase(shift: NDArray, n_bins: int, n: int) -> NDArray[np.complex128]:
    """``exp(-j 2 pi k shift / N)`` for ``k < n_bins``, one row per shift: ``k = 64 a + b``,
    a product of two small tables of exponentials (error of a few ulp)."""
    ang = -2.0 * np.pi * shift / n
    lo = np.exp(1j * np.multiply.outer(ang, np.arange(64)))
    hi = np.exp(1j * np.multiply.outer(ang, 64 * np.arange(-(-n_bins // 64))))
    return (hi[:, :, None] * lo[:, None, :]).reshape(shift.size, -1)[:, :n_bins]


def _edge_terms(tl: list[NDArray], chan: NDArray, t0_s: float, shift: NDArray,
                cfg: ScmConfig) -> tuple[NDArray[np.int64], NDArray[np.complex128]]:
    """Terms of eq. 3, at the clicks' own (undelayed) positions, to remove from channel
    ``chan[r]``'s spectrum before it is delayed by ``shift[r]`` samples: the clicks the delay
    moves out of the window, minus those it brings in. Returns the candidates that have such
    clicks, increasing, and their terms (one row each).

    The window keeps ``0 <= u < N`` before and ``-shift <= u < N - shift`` after the delay:
    two ranges of the sorted clicks, which differ near the ends only. The terms of the clicks
    there are summed by prefix sums.
    """
    n, nb = cfg.n_samples, cfg.n_bins
    shading, _, c, _, _, _ = _grid(n, cfg.half_width_bins)
    rows, terms = [], []
    for ch in np.unique(chan):
        x = np.sort((tl[ch] - t0_s) * cfg.fs_hz)
        r = np.flatnonzero(chan == ch)
        o0, o1 = np.searchsorted(x, [0.0, float(n)])  # the window before the delay
        n0 = np.searchsorted(x, -shift[r])  # and after it
        n1 = np.searchsorted(x, n - shift[r])
        moved = (n0 != o0) | (n1 != o1)
        if not moved.any():
            continue
        r, n0, n1 = r[moved], n0[moved], n1[moved]
        d = np.zeros((r.size, nb), dtype=complex)
        for a_old, a_new, sgn in ((o1, n1, 1.0), (o0, n0, -1.0)):
            lo, hi = min(a_old, int(a_new.min())), max(a_old, int(a_new.max()))
            if hi == lo:
                continue
            prefix = np.zeros((hi - lo + 1, nb), dtype=complex)
            np.cumsum(_phase(x[lo:hi], nb, n), axis=0, out=prefix[1:])
            # sum over [a_new, a_old) (a negative range when a_new > a_old)
            d += sgn * (prefix[a_old - lo] - prefix[a_new - lo])
        rows.append(r)
        terms.append(d)
    if not rows:
        return np.zeros(0, dtype=np.int64), np.zeros((0, nb), dtype=complex)
    row, d = np.concatenate(rows), np.concatenate(terms)
    by_row = np.argsort(row)
    return row[by_row], d[by_row] * (c * shading[:nb])


def _maxima(series: NDArray, level: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Row and column of the interior samples of each row at or above `level` that exceed the
    left neighbour and are not below the right one (the few samples above the level are
    tested, not the whole array); in row-major order."""
    n = series.shape[1]
    flat = series.ravel()
    at = np.flatnonzero(flat >= level)
    col = at % n
    at = at[(col > 0) & (col < n - 1)]
    v = flat[at]
    at = at[(v > flat[at - 1]) & (v >= flat[at + 1])]
    return at // n, at % n


def _nearest(s: NDArray, order: NDArray, t: NDArray) -> tuple[NDArray, NDArray]:
    """Index (into the unsorted array) of the element nearest each `t`, and the distance,
    from the sorted values `s` and the sorting permutation `order`."""
    if s.size == 0:
        return np.zeros(t.size, dtype=np.int64), np.full(t.size, np.inf)
    top = s.size - 1
    k = np.minimum(np.maximum(np.searchsorted(s, t), 1), max(top, 1))
    lo = np.minimum(k - 1, top)
    hi = np.minimum(k, top)
    pick = np.where(np.abs(s[hi] - t) < np.abs(s[lo] - t), hi, lo)
    return order[pick], np.abs(s[pick] - t)


def _match(ni: NDArray, di: NDArray, nj: NDArray, dj: NDArray, v: NDArray,
           tol: float) -> tuple[NDArray, NDArray]:
    """Clicks of i and of (shifted) j nearest each SCM2 peak (`ni`, `nj` at distances `di`,
    `dj`), both within `tol`, each used once (the strongest peak keeps a shared click)."""
    ok = np.flatnonzero((di <= tol) & (dj <= tol))
    ok = ok[np.argsort(v[ok])[::-1]]  # strongest peak first keeps a shared click
    _, first_i = np.unique(ni[ok], return_index=True)
    ok = ok[np.sort(first_i)]
    _, first_j = np.unique(nj[ok], return_index=True)
    ok = np.sort(ok[np.sort(first_j)])
    return ni[ok], nj[ok]
