"""Acquisition of narrowband targets with high bearing rates: best trace through an IBW BTR.

Implements *Acquisition system particularly suited for tracking targets having high bearing rates*
(US 6,980,486; the project's method text ``acquisition-high-bearing-rate``). An operator clicks a
beam and a frequency on a gram; from the last ``numscans`` normalised beam spectra the method
estimates the target's bearing, bearing rate and SNR to initialise a narrowband tracker:

====  ==========================================================  =================================
step  program segment of the method                               here
====  ==========================================================  =================================
22    normalise each beam spectrum to unit noise mean             :func:`normalize_spectra`
24    store the beam/frequency/time history                       the :class:`fusion.io.Cube`
26    retrieve the initialisation band (IBW) around the click     :func:`ibw_bins`
28    BTR: mean over the IBW bins per scan and beam               :func:`ibw_btr`
40    approximate beamwidth of the clicked beam                   :func:`beamwidth_deg`
42    beam tolerance (beams within half a beamwidth, >= 2)        :func:`fusion.geometry.beam_tolerance`
44    anchor beams ``click - tol .. click + tol``                 :meth:`Acquisition.acquire`
46    best line in a fan (``rateest``, segments 62-70)            :func:`best_traces_in_fans`
                                                                  (``trace="beam"``:
                                                                  :func:`best_lines_in_fans`)
48    best line in every other fan                                the same, all fans at once
50    overall best line                                           :meth:`Acquisition.acquire`
52    band noise level, IBW SNR, defaults, SNR in 1 Hz (eq. 4)    :func:`band_noise_level`
--    sub-beam refinement of the best line (added)                :func:`refine_trace`
54    beam -> bearing, beam rate -> bearing rate (eqs. 5-11),     :mod:`fusion.geometry`,
      lag correction                                              :meth:`Acquisition.acquire`
====  ==========================================================  =================================

The fans' lines are constant-bearing-rate traces by default (:func:`constant_rate_traces`): the
method's straight lines in beam number, generalised to the cosine beam spacing the method itself
assumes (eqs. 5-11), in which a target at a constant bearing rate draws a curve; each trace is read
at the nearest beam, as ``rateest`` reads its lines. ``trace="beam"`` keeps the literal straight
lines. Where the text is silent or garbled the choices are documented on :class:`Acquisition`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import integrate, stats

from fusion.geometry import (
    beam_tolerance,
    beamwidth_cos,
    bearing_from_beam,
    bearing_rate_from_beam_rate,
)
from fusion.io import Cube

__all__ = [
    "Acquisition",
    "AcquisitionResult",
    "BestLine",
    "FanSearch",
    "RefinedTrace",
    "TraceFanSearch",
    "acquire",
    "band_noise_level",
    "beamwidth_deg",
    "best_lines_in_fans",
    "best_traces_in_fans",
    "constant_rate_traces",
    "expected_median_fraction",
    "ibw_bins",
    "ibw_btr",
    "matched_trace_score",
    "normalize_spectra",
    "refine_trace",
    "slope_grid",
]

logger = logging.getLogger(__name__)

#: Equivalent noise bandwidth of a Hamming window, in bins (the method's eq. 4 factor).
HAMMING_ENBW = 1.3


# --------------------------------------------------------------------------------------------
# program segment 22: normalisation
# --------------------------------------------------------------------------------------------
@lru_cache(maxsize=256)
def expected_median_fraction(n: int, dof: float = 2.0) -> float:
    """Expected sample median of `n` unit-mean chi-square noise values.

    Parameters
    ----------
    n : int
        Sample size (>= 1).
    dof : float
        Degrees of freedom of the noise (2 for one periodogram look: exponential).

    Returns
    -------
    float
        ``E[median]`` of `n` independent gamma variables of shape ``dof / 2`` and unit mean; the
        median of an even sample is the mean of its two middle order statistics.

    Notes
    -----
    The ``k``-th order statistic of ``n`` values with distribution ``F`` is ``F^-1(U)`` with
    ``U ~ Beta(k, n - k + 1)``, so ``E[X_(k)] = int_0^1 F^-1(u) beta_pdf(u) du`` (numerical
    quadrature). For ``dof = 2`` this equals ``H_n - H_(n-k)`` (harmonic numbers).
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    if not np.isfinite(dof) or dof <= 0:
        raise ValueError(f"dof must be positive, got {dof!r}")
    shape = dof / 2.0

    def order_mean(k: int) -> float:
        beta = stats.beta(k, n - k + 1)
        lo, hi = beta.ppf(1e-13), beta.isf(1e-13)  # where the order statistic's mass lies
        val, _ = integrate.quad(
            lambda u: stats.gamma.ppf(u, shape, scale=1.0 / shape) * beta.pdf(u), lo, hi,
            limit=200,
        )
        return float(val)

    if n % 2:
        return order_mean((n + 1) // 2)
    return 0.5 * (order_mean(n // 2) + order_mean(n // 2 + 1))


def _window(k: int, n_bins: int, window_bins: int, gap_bins: int) -> NDArray[np.intp]:
    j = np.arange(n_bins)
    d = np.abs(j - k)
    return j[(d > gap_bins) & (d <= gap_bins + window_bins)]


def normalize_spectra(
    power: ArrayLike,
    *,
    window_bins: int = 8,
    gap_bins: int = 1,
    noise_dof: float = 2.0,
    pool_scans: int | None = None,
    bins: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Normalise beam spectra to unit noise mean with a split-window median across frequency.

    Parameters
    ----------
    power : array_like, shape (n_scans, n_beams, n_bins)
        Linear power of the beam spectra (scans in time order).
    window_bins : int
        Bins on each side of the window (>= 1).
    gap_bins : int
        Bins on each side of the bin being normalised left out of its window (>= 0), so that a
        line spread over neighbouring bins does not raise its own noise estimate.
    noise_dof : float
        Degrees of freedom of the noise in one cell (2 for a single periodogram, ``2 m`` for ``m``
        averaged looks); sets the median-to-mean factor.
    pool_scans : int, optional
        Scans pooled into each noise estimate: a centred run of this many scans (1: every update
        on its own); None (default): the whole history.
    bins : array_like of int, optional
        Normalise only these bins (default all); the output's last axis follows `bins`.

    Returns
    -------
    ndarray, shape (n_scans, n_beams, n_bins) or (n_scans, n_beams, len(bins))
        Normalised power: noise alone has mean 1 (to the accuracy of the noise estimate).

    Raises
    ------
    ValueError
        Wrong shape, non-finite or negative power, a window with fewer than 3 bins, a zero noise
        estimate, a bad option.

    Notes
    -----
    Program segment 22 of the method text asks for approximately unit-mean data in every bin
    without a narrowband signal, but does not name a normaliser. Here the noise level of bin ``k``
    of a beam is the median of the bins ``gap < |j - k| <= gap + window`` (one side only near
    the band edges) over the pooled scans, divided by :func:`expected_median_fraction` of the
    sample size, which makes the level unbiased for chi-square noise; the bin itself and its gap
    neighbours are left out, so a line never raises its own level (a line inside another bin's
    window moves that median by at most one rank). The normalised mean exceeds 1 by about the
    level estimate's relative variance, since ``E[1 / level] > 1 / E[level]``.

    Pooling scans matters for narrow cubes: with 16 bins one update offers about 14 window
    values, whose median scatters by about 40 % and would multiply every cell by that error;
    the whole 60-scan history brings it to about 5 %. ``pool_scans=1`` is the per-update
    normaliser of the text.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = 5.0 * rng.exponential(size=(60, 8, 32))
    >>> bool(abs(normalize_spectra(x).mean() - 1.0) < 0.02)
    True
    """
    p = np.asarray(power, dtype=float)
    if p.ndim != 3 or min(p.shape) < 1:
        raise ValueError(f"power must have shape (scans, beams, bins), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("power contains NaN or infinite values")
    if np.any(p < 0):
        raise ValueError("power has negative values")
    if int(window_bins) != window_bins or window_bins < 1:
        raise ValueError(f"window_bins must be a positive integer, got {window_bins!r}")
    if int(gap_bins) != gap_bins or gap_bins < 0:
        raise ValueError(f"gap_bins must be a non-negative integer, got {gap_bins!r}")
    n_scans, n_beams, n_bins = p.shape
    pool = n_scans if pool_scans is None else int(pool_scans)
    if pool_scans is not None and (int(pool_scans) != pool_scans or not 1 <= pool <= n_scans):
        raise ValueError(f"pool_scans must be an integer in [1, {n_scans}], got {pool_scans!r}")
    targets = np.arange(n_bins) if bins is None else np.asarray(bins, dtype=int).reshape(-1)
    if targets.size and (targets.min() < 0 or targets.max() >= n_bins):
        raise ValueError(f"bins must lie in [0, {n_bins - 1}]")
    out = np.empty((n_scans, n_beams, targets.size))
    for i, k in enumerate(targets):  # a few bins; each median is vectorised over scans x beams
        win = _window(int(k), n_bins, int(window_bins), int(gap_bins))
        if win.size < 3:
            raise ValueError(
                f"normalisation window of bin {k} has {win.size} bins (need >= 3): the cube has "
                f"{n_bins} bins; use fewer gap bins or a pre-normalised cube"
            )
        w = p[:, :, win]  # (scans, beams, window)
        if pool == n_scans:  # one estimate per beam from the whole history
            samples = np.moveaxis(w, 0, 1).reshape(n_beams, -1)[None]  # (1, beams, n)
        else:  # centred runs of `pool` scans (clipped at the ends of the history)
            start = np.clip(np.arange(n_scans) - pool // 2, 0, n_scans - pool)
            runs = np.lib.stride_tricks.sliding_window_view(w, pool, axis=0)[start]
            samples = np.moveaxis(runs, 3, 2).reshape(n_scans, n_beams, -1)
        # sample median by a sort along the short sample axis (faster than np.median here)
        srt = np.sort(samples, axis=-1)
        n, m = srt.shape[-1], srt.shape[-1] // 2
        med = srt[..., m] if n % 2 else 0.5 * (srt[..., m - 1] + srt[..., m])
        level = med / expected_median_fraction(n, noise_dof)
        if np.any(level <= 0):
            raise ValueError(f"noise level of bin {k} is zero in some spectra (all-zero window)")
        out[:, :, i] = p[:, :, k] / level
    return out


# --------------------------------------------------------------------------------------------
# program segments 26-28: initialisation band and its BTR
# --------------------------------------------------------------------------------------------
def ibw_bins(freqs: ArrayLike, freq_hz: float, ibw_hz: float | None = None) -> NDArray[np.intp]:
    """Indices of the bins of the initialisation band (IBW) centred on the clicked frequency.

    Parameters
    ----------
    freqs : array_like, shape (n_bins,)
        Bin centre frequencies, Hz, increasing.
    freq_hz : float
        Clicked frequency, Hz.
    ibw_hz : float, optional
        IBW width, Hz. Bins whose centre lies within ``ibw_hz / 2`` of `freq_hz` are in the band;
        the bin nearest `freq_hz` always is. None: that bin alone.

    Returns
    -------
    ndarray of int, shape (nbins_ibw,)
        Increasing bin indices.
    """
    f = np.asarray(freqs, dtype=float).reshape(-1)
    nearest = int(np.argmin(np.abs(f - freq_hz)))
    if ibw_hz is None:
        return np.array([nearest], dtype=np.intp)
    sel = np.abs(f - freq_hz) <= 0.5 * ibw_hz * (1.0 + 1e-9)
    sel[nearest] = True
    return np.flatnonzero(sel).astype(np.intp)


def ibw_btr(normalized_band: ArrayLike) -> NDArray[np.float64]:
    """IBW bearing-time record: the mean over the band's bins of each scan and beam.

    Parameters
    ----------
    normalized_band : array_like, shape (n_scans, n_beams, nbins_ibw)
        Normalised power of the IBW bins.

    Returns
    -------
    ndarray, shape (n_scans, n_beams)
        Estimates of normalised signal-plus-noise power in the IBW (program segment 28).
    """
    return np.asarray(normalized_band, dtype=float).mean(axis=-1)


# --------------------------------------------------------------------------------------------
# program segments 40-42: beamwidth and beam tolerance
# --------------------------------------------------------------------------------------------
def beamwidth_deg(beam: float, n_beams: int, *, wavelength: float, aperture: float) -> float:
    """Approximate beamwidth of a beam, deg (program segment 40).

    Parameters
    ----------
    beam : float
        Beam index (fractional allowed).
    n_beams : int
        Number of beams, equally spaced in cosine.
    wavelength : float
        Wavelength at the clicked frequency, m.
    aperture : float
        Array aperture, m.

    Returns
    -------
    float
        Width in bearing of the cosine interval ``cos(theta) +- 0.443 lambda / L`` around the beam's
        steering direction (clipped to ``[-1, 1]``, so it stays finite at endfire).
    """
    w = beamwidth_cos(wavelength, aperture)
    u = math.cos(float(bearing_from_beam(beam, n_beams)))
    lo, hi = max(-1.0, u - 0.5 * w), min(1.0, u + 0.5 * w)
    return math.degrees(math.acos(lo) - math.acos(hi))


# --------------------------------------------------------------------------------------------
# program segments 46-48: best line in each fan (rateest), vectorised
# --------------------------------------------------------------------------------------------
def slope_grid(min_slope: float, max_slope: float, step: float) -> NDArray[np.float64]:
    """Candidate slopes ``min_slope, min_slope + step, ... <= max_slope`` (beams per update)."""
    if not (np.isfinite(min_slope) and np.isfinite(max_slope) and np.isfinite(step)):
        raise ValueError("slope grid bounds and step must be finite")
    if step <= 0 or max_slope < min_slope:
        raise ValueError(
            f"need step > 0 and max_slope >= min_slope, got {min_slope}, {max_slope}, {step}"
        )
    n = int(math.floor((max_slope - min_slope) / step + 1e-9)) + 1
    return min_slope + step * np.arange(n)


@dataclass(frozen=True)
class _LineTensors:
    """Index tensors of every line of a fan, independent of the anchor beam.

    ``flat`` indexes a BTR padded with ``pad`` zero columns on each side and flattened, so a line
    anchored at beam ``b`` reads ``btr_pad.ravel()[b + flat]``. ``n_used[s, b]`` is the number of
    scans line ``s`` anchored at beam ``b`` spans before its first step off the BTR.
    """

    flat: NDArray[np.int64]  # (n_slopes, n_scans)
    n_used: NDArray[np.int64]  # (n_slopes, n_beams)
    pad: int


@lru_cache(maxsize=64)
def _line_tensors(n_scans: int, n_beams: int, slopes_bytes: bytes) -> _LineTensors:
    a = np.frombuffer(slopes_bytes, dtype=np.float64)
    k = np.arange(n_scans)
    off = np.floor(a[:, None] * k[None, :] + 0.5).astype(np.int64)  # round(a * iscan)
    # a line is cut at its first step off the BTR, so n_beams of padding suffice
    pad = int(min(np.abs(off).max(), n_beams)) + 1
    width = n_beams + 2 * pad
    flat = k[None, :] * width + pad + np.clip(off, -pad, n_beams - 1 + pad)
    lo = np.minimum.accumulate(off, axis=1)[:, :, None]  # running extremes along the line
    hi = np.maximum.accumulate(off, axis=1)[:, :, None]
    b = np.arange(n_beams)[None, None, :]
    n_used = ((b + lo >= 0) & (b + hi <= n_beams - 1)).sum(axis=1)  # (n_slopes, n_beams)
    for arr in (flat, n_used):
        arr.setflags(write=False)
    return _LineTensors(flat=flat, n_used=n_used, pad=pad)


@dataclass(frozen=True)
class FanSearch:
    """Best line of each fan.

    Attributes
    ----------
    anchors : ndarray of int, shape (n_fans,)
        Anchor beam of each fan (the beam the lines pass through at the latest update).
    slope : ndarray, shape (n_fans,)
        Slope of the best line, beams per update *going back in time* (the method's ``a``;
        0 when no line qualified).
    signal_plus_noise : ndarray, shape (n_fans,)
        Mean BTR value along the best line (0 when no line qualified).
    n_used : ndarray of int, shape (n_fans,)
        Scans the best line spans before leaving the BTR (0 when no line qualified).
    found : ndarray of bool, shape (n_fans,)
        Whether any line of the fan met the minimum-scan rule with a positive mean.
    """

    anchors: NDArray[np.int64]
    slope: NDArray[np.float64]
    signal_plus_noise: NDArray[np.float64]
    n_used: NDArray[np.int64]
    found: NDArray[np.bool_]


def _fan_inputs(
    btr_latest_first: ArrayLike, anchors: ArrayLike, min_scans: int
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Checked BTR (scans latest first, beams) and anchor beams of a fan search."""
    btr = np.asarray(btr_latest_first, dtype=float)
    if btr.ndim != 2:
        raise ValueError(f"btr must be 2-D (scans, beams), got shape {btr.shape}")
    n_scans, n_beams = btr.shape
    anc = np.asarray(anchors, dtype=np.int64).reshape(-1)
    if int(min_scans) != min_scans or not 1 <= min_scans <= n_scans:
        raise ValueError(f"min_scans must be an integer in [1, {n_scans}], got {min_scans!r}")
    if anc.size and (anc.min() < 0 or anc.max() >= n_beams):
        raise ValueError(f"anchor beams must lie in [0, {n_beams - 1}]")
    return btr, anc


def _best_in_fans(
    means: NDArray[np.float64],
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_]]:
    """Best candidate of each fan (rows): index, mean, and whether it beat the method's start 0.

    ``argmax`` takes the first maximum, the method's strict ">" in candidate order; the method's
    running maximum starts at 0, so a fan whose best mean is not positive found nothing.
    """
    best = np.argmax(means, axis=1)
    best_mean = means[np.arange(means.shape[0]), best]
    return best, best_mean, best_mean > 0.0


def best_lines_in_fans(
    btr_latest_first: ArrayLike,
    anchors: ArrayLike,
    slopes: ArrayLike,
    *,
    min_scans: int,
) -> FanSearch:
    """Search each anchor beam's fan of lines for the one with the largest mean BTR value.

    Parameters
    ----------
    btr_latest_first : array_like, shape (n_scans, n_beams)
        IBW BTR with row 0 the latest update (the method's ``btr[iscan][ibeam]``).
    anchors : array_like of int, shape (n_fans,)
        Anchor beams.
    slopes : array_like, shape (n_slopes,)
        Candidate slopes ``a``, beams per update, increasing (line ``fbeam = a * iscan + anchor``).
    min_scans : int
        Minimum number of scans a line must span before it leaves the BTR to be considered (the
        method's ``minscan``; ``n_scans`` means lines that leave the BTR are never used).

    Returns
    -------
    FanSearch

    Notes
    -----
    The ``rateest`` function of the method (segments 62-70): each line is followed from the
    latest update backwards, ``ibeam = round(a * iscan + anchor)``, until it leaves the BTR; its
    mean over the scans used is kept if it spans at least ``minscan`` scans, and the line with the
    strictly largest mean wins (the first such line on ties, slopes in increasing order). Rounding
    is ``floor(x + 0.5)``: the text's ``(int)(x + 0.5)`` truncates toward zero, which would take
    positions down to -1.5 as beam 0. All lines of all fans are evaluated at once: the rounded
    offsets of the lines and where they leave the BTR depend only on the slopes and the BTR's
    shape, and are cached.
    """
    sl = np.asarray(slopes, dtype=float).reshape(-1)
    if sl.size == 0:
        raise ValueError("no candidate slopes")
    btr, anc = _fan_inputs(btr_latest_first, anchors, min_scans)
    n_scans, n_beams = btr.shape
    lt = _line_tensors(n_scans, n_beams, np.ascontiguousarray(sl).tobytes())
    # scans each line spans before its first step off the BTR (the method's break)
    n_used = lt.n_used[:, anc].T  # (fans, slopes)
    padded = np.zeros((n_scans, n_beams + 2 * lt.pad))
    padded[:, lt.pad:lt.pad + n_beams] = btr
    # gather only the lines that meet the minimum-scan rule
    fan_i, slope_i = np.nonzero(n_used >= min_scans)
    vals = padded.ravel()[anc[fan_i, None] + lt.flat[slope_i]]  # (n_lines, n_scans)
    used = n_used[fan_i, slope_i]
    csum = np.cumsum(vals, axis=-1)
    means = np.full(n_used.shape, -np.inf)
    means[fan_i, slope_i] = csum[np.arange(used.size), used - 1] / used
    best, best_mean, found = _best_in_fans(means)
    rows = np.arange(anc.size)
    return FanSearch(
        anchors=anc,
        slope=np.where(found, sl[best], 0.0),
        signal_plus_noise=np.where(found, best_mean, 0.0),
        n_used=np.where(found, n_used[rows, best], 0).astype(np.int64),
        found=found,
    )


# --------------------------------------------------------------------------------------------
# program segments 46-48 generalised: fans of constant-bearing-rate traces in cosine-spaced beams
# --------------------------------------------------------------------------------------------
def constant_rate_traces(
    end_beams: ArrayLike,
    rates_rad_s: ArrayLike,
    *,
    n_scans: int,
    n_beams: int,
    scan_period: float,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Fractional beam positions of constant-bearing-rate traces, latest update first.

    Parameters
    ----------
    end_beams : array_like
        Beam of each trace at the latest update (fractional allowed, in ``[0, n_beams - 1]``).
    rates_rad_s : array_like
        Bearing rate of each trace, rad/s, forward in time (positive: toward aft endfire);
        broadcast against `end_beams`.
    n_scans, n_beams : int
        BTR shape.
    scan_period : float
        Time between scans, s.

    Returns
    -------
    positions : ndarray, shape (..., n_scans)
        Fractional beam of the trace ``iscan`` updates before the latest,
        ``beam_from_bearing(theta_end - rate * iscan * scan_period)`` (eq. 5).
    n_used : ndarray of int, shape (...)
        Scans the trace spans before its bearing first leaves ``[0, pi]`` (the trace's step off
        the BTR, the method's ``break``).

    Notes
    -----
    The method's lines ``fbeam = a * iscan + anchor`` are straight in beam number; a target with
    a constant bearing rate moves along ``b(t) = (N - 1) (1 - cos theta(t)) / 2`` in the cosine
    beam spacing the method assumes (eqs. 5-11), a curve whose slope ``db/dt`` is eq. 11. These
    traces are the method's lines with that spacing taken into account: a fan is the set of
    traces through its anchor beam at the latest update, one per candidate bearing rate.
    """
    if int(n_beams) != n_beams or n_beams < 2:
        raise ValueError(f"n_beams must be an integer >= 2, got {n_beams!r}")
    if int(n_scans) != n_scans or n_scans < 1:
        raise ValueError(f"n_scans must be a positive integer, got {n_scans!r}")
    if not np.isfinite(scan_period) or scan_period <= 0:
        raise ValueError(f"scan_period must be positive, got {scan_period!r}")
    end, rate = np.broadcast_arrays(np.asarray(end_beams, dtype=float),
                                    np.asarray(rates_rad_s, dtype=float))
    theta_end = np.arccos(np.clip(1.0 - 2.0 * end / (n_beams - 1), -1.0, 1.0))  # eq. 6
    tau = np.arange(n_scans) * float(scan_period)  # time back from the latest update
    theta = theta_end[..., None] - rate[..., None] * tau
    eps = 1e-12
    inside = (theta >= -eps) & (theta <= math.pi + eps)
    n_used = np.where(inside.all(axis=-1), n_scans, np.argmin(inside, axis=-1)).astype(np.int64)
    positions = (n_beams - 1) * (1.0 - np.cos(theta)) / 2.0  # eq. 5
    return positions, n_used


def _sample_indices(
    positions: NDArray[np.float64], n_used: NDArray[np.int64], n_beams: int, sampling: str
) -> tuple[NDArray[np.int32], NDArray[np.float64] | None]:
    """Flat indices (and linear weights) of trace samples in a BTR flattened with a zero appended.

    Scans at or beyond a trace's ``n_used`` point at the appended zero (weight 0), so a sum over
    all scans is the sum over the scans used.
    """
    n_scans = positions.shape[-1]
    sentinel = n_scans * n_beams
    row = np.arange(n_scans) * n_beams
    used = np.arange(n_scans) < n_used[..., None]
    if sampling == "nearest":
        ibeam = np.clip(np.floor(positions + 0.5), 0, n_beams - 1).astype(np.int64)
        return np.where(used, row + ibeam, sentinel).astype(np.int32), None
    lo = np.clip(np.floor(positions), 0, n_beams - 2).astype(np.int64)
    w = np.where(used, positions - lo, 0.0)
    return np.where(used, row + lo, sentinel).astype(np.int32), w


@dataclass(frozen=True)
class _TraceTensors:
    """Sample indices of one fan's traces (see :func:`_sample_indices`) and their scans used."""

    index: NDArray[np.int32]  # (n_rates, n_scans)
    weight: NDArray[np.float64] | None  # (n_rates, n_scans), linear sampling only
    n_used: NDArray[np.int64]  # (n_rates,)


@lru_cache(maxsize=128)
def _trace_tensors(
    n_scans: int, n_beams: int, anchor: int, rates_bytes: bytes, scan_period: float, sampling: str
) -> _TraceTensors:
    rates = np.frombuffer(rates_bytes, dtype=np.float64)
    pos, n_used = constant_rate_traces(float(anchor), rates, n_scans=n_scans, n_beams=n_beams,
                                       scan_period=scan_period)
    index, weight = _sample_indices(pos, n_used, n_beams, sampling)
    for arr in (index, weight, n_used):
        if arr is not None:
            arr.setflags(write=False)
    return _TraceTensors(index=index, weight=weight, n_used=n_used)


def _sum_along(flat_btr: NDArray[np.float64], index: NDArray[np.int32],
               weight: NDArray[np.float64] | None) -> NDArray[np.float64]:
    lo = flat_btr[index]
    if weight is None:
        return lo.sum(axis=-1)
    hi = flat_btr[np.minimum(index + 1, flat_btr.size - 1)]
    return (lo + weight * (hi - lo)).sum(axis=-1)


@dataclass(frozen=True)
class TraceFanSearch:
    """Best constant-bearing-rate trace of each fan.

    Attributes
    ----------
    anchors : ndarray of int, shape (n_fans,)
        Anchor beam of each fan (the beam its traces pass through at the latest update).
    rate_rad_s : ndarray, shape (n_fans,)
        Bearing rate of the best trace, rad/s forward in time (0 when no trace qualified).
    signal_plus_noise : ndarray, shape (n_fans,)
        Mean BTR value along the best trace (0 when no trace qualified).
    n_used : ndarray of int, shape (n_fans,)
        Scans the best trace spans before its bearing leaves ``[0, pi]`` (0 when none qualified).
    found : ndarray of bool, shape (n_fans,)
        Whether any trace of the fan met the minimum-scan rule with a positive mean.
    """

    anchors: NDArray[np.int64]
    rate_rad_s: NDArray[np.float64]
    signal_plus_noise: NDArray[np.float64]
    n_used: NDArray[np.int64]
    found: NDArray[np.bool_]


def best_traces_in_fans(
    btr_latest_first: ArrayLike,
    anchors: ArrayLike,
    rates_rad_s: ArrayLike,
    *,
    scan_period: float,
    min_scans: int,
    sampling: Literal["nearest", "linear"] = "nearest",
) -> TraceFanSearch:
    """Search each anchor beam's fan of constant-bearing-rate traces for the largest mean.

    Parameters
    ----------
    btr_latest_first : array_like, shape (n_scans, n_beams)
        IBW BTR with row 0 the latest update.
    anchors : array_like of int, shape (n_fans,)
        Anchor beams.
    rates_rad_s : array_like, shape (n_rates,)
        Candidate bearing rates, rad/s forward in time, increasing.
    scan_period : float
        Time between scans, s.
    min_scans : int
        The method's ``minscan``: fewest scans a trace must span before its bearing leaves
        ``[0, pi]``.
    sampling : {"nearest", "linear"}
        How a trace reads the BTR at its fractional beam: the nearest beam, ``floor(b + 0.5)``,
        the method's rounding (default); or linear interpolation between the two beams around it.

    Returns
    -------
    TraceFanSearch

    Notes
    -----
    ``rateest`` (segments 62-70) with the straight line ``fbeam = a * iscan + anchor`` replaced
    by the trace of :func:`constant_rate_traces`: the mean over the scans a trace spans, the
    minimum-scan rule, the strictly largest mean winning (the first trace in rate order on ties),
    the running maximum starting at 0. The sample indices of a fan depend only on the BTR's shape,
    the anchor, the rates and the scan period, and are cached; all traces of all fans are read
    with one gather.
    """
    if sampling not in ("nearest", "linear"):
        raise ValueError(f"sampling must be 'nearest' or 'linear', got {sampling!r}")
    rates = np.ascontiguousarray(np.asarray(rates_rad_s, dtype=float).reshape(-1))
    if rates.size == 0 or not np.all(np.isfinite(rates)):
        raise ValueError("candidate rates must be finite and not empty")
    btr, anc = _fan_inputs(btr_latest_first, anchors, min_scans)
    n_scans, n_beams = btr.shape
    key = rates.tobytes()
    fans = [_trace_tensors(n_scans, n_beams, int(a), key, float(scan_period), sampling)
            for a in anc]
    flat = np.append(btr.ravel(), 0.0)
    means = np.full((anc.size, rates.size), -np.inf)
    for i, t in enumerate(fans):  # a few fans; each is one gather over all its traces and scans
        ok = t.n_used >= min_scans
        sums = _sum_along(flat, t.index[ok], None if t.weight is None else t.weight[ok])
        means[i, ok] = sums / t.n_used[ok]
    best, best_mean, found = _best_in_fans(means)
    n_used = np.array([t.n_used[b] for t, b in zip(fans, best, strict=True)], dtype=np.int64)
    return TraceFanSearch(
        anchors=anc,
        rate_rad_s=np.where(found, rates[best], 0.0),
        signal_plus_noise=np.where(found, best_mean, 0.0),
        n_used=np.where(found, n_used, 0).astype(np.int64),
        found=found,
    )


# --------------------------------------------------------------------------------------------
# refinement of the overall best trace (between segments 52 and 54)
# --------------------------------------------------------------------------------------------
#: Sub-beam step of the tabulated matched score, beams (linear interpolation in between).
MATCHED_STEP_BEAMS = 1.0 / 16.0


@lru_cache(maxsize=32)
def _lobe_taps(
    n_beams: int, lobe_beams: float
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Main-lobe taps of the positions ``p * MATCHED_STEP_BEAMS``: beams, weights, ``sum w^2``.

    ``beams[t, p]`` and ``weights[t, p]`` list the beams within the main lobe of position ``p``
    (weight 0 beyond the lobe or the edges of the BTR).
    """
    n_pos = int(round((n_beams - 1) / MATCHED_STEP_BEAMS)) + 1
    x = np.arange(n_pos) * MATCHED_STEP_BEAMS
    half = int(math.ceil(lobe_beams))
    j = np.floor(x).astype(np.int64)[None, :] + np.arange(-half + 1, half + 1)[:, None]
    u = (j - x[None, :]) / lobe_beams
    w = np.where((np.abs(u) < 1.0) & (j >= 0) & (j < n_beams), np.sinc(u) ** 2, 0.0)
    beams = np.clip(j, 0, n_beams - 1)
    energy = (w * w).sum(axis=0)
    for arr in (beams, w, energy):
        arr.setflags(write=False)
    return beams, w, energy


def _matched_table(
    btr: NDArray[np.float64], lobe_beams: float, noise_level: float,
    centre: NDArray[np.float64] | None = None, half_width: float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Per-scan lobe correlation on the sub-beam grid (row 0 latest), template energy, offsets.

    With `centre` (a beam per scan) and `half_width` (beams) only the grid positions within
    `half_width` of the centre are tabulated; row ``k`` of the table then starts at grid position
    ``start[k]`` (0 for the full table).
    """
    n_scans, n_beams = btr.shape
    beams, w, energy = _lobe_taps(int(n_beams), float(lobe_beams))
    n_pos = energy.size
    if centre is None or half_width is None:
        start = np.zeros(n_scans, dtype=np.int64)
        cols = np.broadcast_to(np.arange(n_pos), (n_scans, n_pos))
    else:
        n_win = min(2 * int(math.ceil(half_width / MATCHED_STEP_BEAMS)) + 1, n_pos)
        start = np.clip(np.round(centre / MATCHED_STEP_BEAMS).astype(np.int64) - n_win // 2,
                        0, n_pos - n_win)
        cols = start[:, None] + np.arange(n_win)  # (scans, window)
    rows = np.arange(n_scans)[None, :, None]
    vals = (btr - float(noise_level))[rows, beams[:, cols]]  # (taps, scans, window)
    return (vals * w[:, cols]).sum(axis=0), energy, start


def _score_from_table(
    table: NDArray[np.float64], energy: NDArray[np.float64], start: NDArray[np.int64],
    positions: NDArray[np.float64], n_used: NDArray[np.int64],
) -> NDArray[np.float64]:
    n_scans, n_win = table.shape
    g = np.clip(positions / MATCHED_STEP_BEAMS - start, 0.0, n_win - 1.0)
    lo = np.minimum(g.astype(np.int64), n_win - 2)
    f = g - lo
    used = np.arange(n_scans) < n_used[..., None]
    flat = table.ravel()
    cell = lo + np.arange(n_scans) * n_win
    corr = flat[cell] + f * (flat[cell + 1] - flat[cell])
    e = lo + start
    en = energy[e] + f * (energy[e + 1] - energy[e])
    num = np.where(used, corr, 0.0).sum(axis=-1)
    den = np.where(used, en, 0.0).sum(axis=-1)
    return num / np.sqrt(np.maximum(den, 1e-300))


def matched_trace_score(
    btr_latest_first: ArrayLike,
    positions: ArrayLike,
    n_used: ArrayLike,
    *,
    lobe_beams: float,
    noise_level: float,
) -> NDArray[np.float64]:
    """Main-lobe matched score of traces at fractional beam positions.

    Parameters
    ----------
    btr_latest_first : array_like, shape (n_scans, n_beams)
        IBW BTR, row 0 the latest update.
    positions : array_like, shape (..., n_scans)
        Fractional beam of each trace at each scan, latest first, in ``[0, n_beams - 1]``.
    n_used : array_like of int, shape (...)
        Scans each trace spans (later rows are ignored).
    lobe_beams : float
        Half-width of the main lobe to its first nulls, in beams:
        ``(n_beams - 1) / 2 * lambda / L``.
    noise_level : float
        Mean BTR value of noise alone (the band noise level), subtracted from every cell.

    Returns
    -------
    ndarray, shape (...)
        ``sum w (btr - noise) / sqrt(sum w^2)`` over the cells of the main lobe around the trace
        in every scan it spans, with ``w = sinc^2((beam - position) / lobe_beams)`` the main lobe of
        a line array in cosine space.

    Notes
    -----
    The correlation of the BTR with the main lobe the array would draw along the trace,
    normalised by the energy of that template (the matched filter for a line of unknown level in
    unit-mean noise). For a noise-free trace the Cauchy-Schwarz inequality makes the true trace
    the maximum, also where the lobe is cut by the edge of the BTR at endfire; a trace read from
    one cell per scan (nearest or linear) is instead maximal on whole beams, so it cannot resolve
    a trace that crosses less than a beam or two over the history. Beams beyond the edges count as
    absent. The per-scan correlation and the template energy are tabulated every
    ``MATCHED_STEP_BEAMS`` (1/16 beam, one gather of the lobe's taps per BTR) and interpolated
    linearly, so scoring a trace is a gather of two table cells per scan.
    """
    btr = np.asarray(btr_latest_first, dtype=float)
    pos = np.asarray(positions, dtype=float)
    nu = np.asarray(n_used, dtype=np.int64)
    if btr.ndim != 2:
        raise ValueError(f"btr must be 2-D (scans, beams), got shape {btr.shape}")
    if pos.shape[-1] != btr.shape[0]:
        raise ValueError(f"positions must have {btr.shape[0]} scans on the last axis, got {pos.shape}")
    if not np.isfinite(lobe_beams) or lobe_beams <= 0:
        raise ValueError(f"lobe_beams must be positive, got {lobe_beams!r}")
    table, energy, start = _matched_table(btr, lobe_beams, noise_level)
    return _score_from_table(table, energy, start, pos, nu)


@dataclass(frozen=True)
class RefinedTrace:
    """Result of :func:`refine_trace`.

    Attributes
    ----------
    end_beam : float
        Fractional beam at the latest update.
    rate_rad_s : float
        Bearing rate, rad/s forward in time.
    score : float
        Matched score (:func:`matched_trace_score`) of the refined trace.
    start_score : float
        Matched score of the starting trace (never above `score`).
    n_used : int
        Scans the refined trace spans.
    """

    end_beam: float
    rate_rad_s: float
    score: float
    start_score: float
    n_used: int


def refine_trace(
    btr_latest_first: ArrayLike,
    end_beam: float,
    rate_rad_s: float,
    *,
    scan_period: float,
    min_scans: int,
    lobe_beams: float,
    noise_level: float,
    span_beams: float = 2.0,
    n_grid: int = 21,
    n_fine: int = 11,
) -> RefinedTrace:
    """Sub-beam refinement of a trace's end beam and bearing rate by a local matched search.

    Parameters
    ----------
    btr_latest_first : array_like, shape (n_scans, n_beams)
        IBW BTR, row 0 the latest update.
    end_beam, rate_rad_s : float
        Starting trace (the overall best trace of the fan search).
    scan_period : float
        Time between scans, s.
    min_scans : int
        Fewest scans a candidate trace must span (the method's ``minscan``).
    lobe_beams, noise_level : float
        See :func:`matched_trace_score`.
    span_beams : float
        Half-size of the search box: the end beam moves up to this many beams, the rate up to the
        change that moves the trace's oldest scan by this many beams (at the trace's mid bearing,
        its sine floored at 0.1).
    n_grid, n_fine : int
        Odd grid sizes per axis of the first search and of the second one, a fifth of the size,
        around the first one's best.

    Returns
    -------
    RefinedTrace

    Notes
    -----
    Both grids contain their centre, so the refined score is never below the starting trace's.
    The matched score is tabulated once, within ``2 span_beams + 2`` beams of the starting
    trace at every scan (candidates are scored with two table cells per scan).
    """
    btr = np.asarray(btr_latest_first, dtype=float)
    n_scans, n_beams = btr.shape
    for name, n in (("n_grid", n_grid), ("n_fine", n_fine)):
        if int(n) != n or n < 3 or n % 2 == 0:
            raise ValueError(f"{name} must be an odd integer >= 3, got {n!r}")
    if not np.isfinite(span_beams) or span_beams <= 0:
        raise ValueError(f"span_beams must be positive, got {span_beams!r}")
    if not np.isfinite(lobe_beams) or lobe_beams <= 0:
        raise ValueError(f"lobe_beams must be positive, got {lobe_beams!r}")
    kw = {"n_scans": n_scans, "n_beams": n_beams, "scan_period": scan_period}
    # the matched score tabulated once, near the starting trace (the search box and a margin)
    centre, _ = constant_rate_traces(float(end_beam), float(rate_rad_s), **kw)
    table, energy, offset = _matched_table(btr, lobe_beams, noise_level, centre,
                                           2.0 * span_beams + 2.0)

    def score(ends: NDArray[np.float64], rates: NDArray[np.float64]) -> NDArray[np.float64]:
        pos, nu = constant_rate_traces(ends, rates, **kw)
        s = _score_from_table(table, energy, offset, pos, nu)
        return np.where(nu >= min_scans, s, -np.inf)

    end, rate = float(end_beam), float(rate_rad_s)
    start = float(score(np.array(end), np.array(rate)))
    best = start
    half_span = float(span_beams)
    for n in (n_grid, n_fine):
        pos, nu = constant_rate_traces(end, rate, **kw)
        mid = pos[max(int(nu) - 1, 0) // 2] if int(nu) > 0 else end
        sin_mid = max(math.sin(float(bearing_from_beam(mid, n_beams))), 0.1)
        history = max(int(nu) - 1, 1) * scan_period
        rate_span = half_span / ((n_beams - 1) / 2.0 * sin_mid * history)  # eq. 11 inverted
        grid = np.linspace(-1.0, 1.0, n)
        ends = np.clip(end + half_span * grid[:, None], 0.0, n_beams - 1.0) + 0.0 * grid[None, :]
        rates = rate + rate_span * grid[None, :] + 0.0 * grid[:, None]
        s = score(ends, rates)
        i, j = np.unravel_index(int(np.argmax(s)), s.shape)
        if s[i, j] > best:
            end, rate, best = float(ends[i, j]), float(rates[i, j]), float(s[i, j])
        half_span /= 5.0
    _, nu = constant_rate_traces(end, rate, **kw)
    return RefinedTrace(end_beam=end, rate_rad_s=rate, score=best, start_score=start,
                        n_used=int(nu))


# --------------------------------------------------------------------------------------------
# program segment 52: band noise level
# --------------------------------------------------------------------------------------------
def band_noise_level(
    btr_latest_first: ArrayLike,
    anchor: float,
    slope: float = 0.0,
    *,
    exclude_beams: float,
    track: ArrayLike | None = None,
) -> float:
    """Mean BTR value off the target's trace (program segment 52).

    Parameters
    ----------
    btr_latest_first : array_like, shape (n_scans, n_beams)
        IBW BTR, row 0 the latest update.
    anchor : float
        Anchor beam of the best line (ignored when `track` is given).
    slope : float
        Slope of the best line, beams per update going back in time (ignored when `track` is
        given).
    exclude_beams : float
        Cells within this many beams of the line (extended over every scan) are left out.
    track : array_like, shape (n_scans,), optional
        Fractional beam of the trace at every scan, latest first (a curved trace); default the
        straight line ``anchor + slope * iscan``.

    Returns
    -------
    float
        Band noise level (linear).

    Raises
    ------
    ValueError
        When no cell is left, or `track` has the wrong length.
    """
    btr = np.asarray(btr_latest_first, dtype=float)
    n_scans, n_beams = btr.shape
    if track is None:
        line = anchor + slope * np.arange(n_scans)
    else:
        line = np.asarray(track, dtype=float).reshape(-1)
        if line.size != n_scans:
            raise ValueError(f"track must have {n_scans} positions, got {line.size}")
    off = np.abs(np.arange(n_beams)[None, :] - line[:, None]) > exclude_beams
    if not off.any():
        raise ValueError(
            f"no BTR cell lies off the target's trace ({n_beams} beams, {exclude_beams:.1f} "
            "beams excluded each side): cannot estimate the band noise level"
        )
    return float(btr[off].mean())


# --------------------------------------------------------------------------------------------
# results and the component
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BestLine:
    """The overall best line on the IBW BTR (program segment 50), for plotting and checks.

    Attributes
    ----------
    anchor_beam : int
        Beam the best line's fan is anchored at, at the latest scan (the method's ``bestbeam``).
    beam_rate_per_scan : float
        Mean slope forward in time, beams per scan: for a straight line minus the method's
        ``brgratebpu`` (which runs backwards from the latest update); for a constant-bearing-rate
        trace ``(end_beam - start_beam) / (n_scans_used - 1)``.
    start_scan, end_scan : int
        Oldest and latest scans the line spans (chronological scan indices, ``end_scan`` the latest).
    start_beam, end_beam : float
        Beam positions of the line at `start_scan` and `end_scan` (unrounded; after refinement for
        a refined trace).
    n_scans_used : int
        Scans the line spans.
    signal_plus_noise : float
        Mean IBW BTR value along the fan search's best line (the method's ``signalplusnoise``).
    trace : {"beam", "bearing"}
        Straight line in beam number (the literal method) or constant-bearing-rate trace.
    bearing_rate_deg_per_min : float
        Bearing rate of a constant-bearing-rate trace, deg/min (NaN for a straight line).
    coarse_end_beam : float
        End beam found by the fan search, before refinement (the anchor beam).
    coarse_bearing_rate_deg_per_min : float
        Bearing rate of the fan search's best trace, before refinement (NaN for a straight line).
    refined : bool
        Whether the sub-beam refinement was applied.
    beams : ndarray, shape (n_scans_used,)
        Fractional beam of the line at scans ``start_scan .. end_scan`` (chronological).
    """

    anchor_beam: int
    beam_rate_per_scan: float
    start_scan: int
    end_scan: int
    start_beam: float
    end_beam: float
    n_scans_used: int
    signal_plus_noise: float
    trace: Literal["beam", "bearing"] = "beam"
    bearing_rate_deg_per_min: float = float("nan")
    coarse_end_beam: float = float("nan")
    coarse_bearing_rate_deg_per_min: float = float("nan")
    refined: bool = False
    beams: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))


@dataclass(frozen=True)
class AcquisitionResult:
    """Initial bearing, bearing rate and SNR of a clicked narrowband target.

    Attributes
    ----------
    bearing_deg : float
        Bearing from the forward axis at the latest scan, lag-corrected, deg in ``[0, 180]``.
    bearing_rate_deg_per_min : float
        Bearing rate, deg/min (positive: bearing increasing, toward aft endfire).
    snr_db : float
        SNR in a 1 Hz band, dB (eq. 4 of the method text; the default's value when
        `default_used`).
    default_used : bool
        True when the IBW SNR was too low (``snr_ibw <= min_snr_ibw``) and the defaults were output:
        rate 0, the clicked beam's bearing, the default SNR.
    snr_ibw : float
        Linear SNR in the IBW, ``(S+N - N) / N`` (measured, also when defaults are output; NaN when
        no line qualified).
    bearing_uncorrected_deg : float
        Bearing of the best line's latest end before the lag correction (the method's
        ``bestbrguncorrected``): the anchor beam of a straight line, the refined end beam of a
        constant-bearing-rate trace, deg.
    best_line : BestLine or None
        The overall best line (None when no line of any fan qualified).
    btr : ndarray, shape (n_scans, n_beams)
        IBW BTR, chronological rows (row ``n_scans - 1`` the latest scan).
    band_noise_level : float
        Mean BTR value off the trace.
    beamwidth_deg : float
        Approximate beamwidth of the clicked beam, deg.
    beam_tolerance : int
        Beams on each side of the clicked beam used as anchors.
    anchor_beams : tuple of int
        The anchor beams searched.
    ibw_bins : tuple of int
        Bin indices of the IBW.
    """

    bearing_deg: float
    bearing_rate_deg_per_min: float
    snr_db: float
    default_used: bool
    snr_ibw: float
    bearing_uncorrected_deg: float
    best_line: BestLine | None
    btr: NDArray[np.float64]
    band_noise_level: float
    beamwidth_deg: float
    beam_tolerance: int
    anchor_beams: tuple[int, ...]
    ibw_bins: tuple[int, ...]

    def to_json(self) -> dict[str, float | bool]:
        """The ``fusion acquire`` output: bearing, bearing rate, SNR, whether defaults were used."""
        return {
            "bearing_deg": float(self.bearing_deg),
            "bearing_rate_deg_per_min": float(self.bearing_rate_deg_per_min),
            "snr_db": float(self.snr_db),
            "default_used": bool(self.default_used),
        }


class Acquisition:
    """Estimate a clicked target's bearing, bearing rate and SNR from the best line on its IBW BTR.

    Parameters
    ----------
    ibw_hz : float, optional
        Width of the initialisation band, Hz; None (default) uses the clicked bin alone.
    lag_s : float
        Delay between what the spectra show and the present, s (spectral integration, about half
        an integration period, plus any display delay); the bearing is corrected by
        ``rate * lag_s``. Default 0.
    normalize : bool
        Normalise the IBW bins (program segment 22) with :func:`normalize_spectra`; set False for
        cubes already normalised to unit noise mean.
    window_bins, gap_bins : int
        Split window of the normaliser (bins each side, bins left out each side).
    pool_scans : int, optional
        Scans pooled into each noise estimate of the normaliser (None: the whole history).
    noise_dof : float
        Degrees of freedom of the noise in one cell, for the normaliser.
    trace : {"bearing", "beam"}
        Lines of the fans: constant-bearing-rate traces in the cosine beam spacing (default, see
        :func:`constant_rate_traces`) or the method's literal straight lines in beam number.
    sampling : {"nearest", "linear"}
        How a constant-bearing-rate trace reads the BTR: the nearest beam (the method's rounding,
        default) or linear interpolation across beams.
    refine : bool, optional
        Refine the overall best trace to sub-beam end position and rate (:func:`refine_trace`).
        None (default): True for ``trace="bearing"``; the literal straight lines are never refined.
    refine_span_beams : float
        Half-size of the refinement's search box, beams (see :func:`refine_trace`).
    min_scans : int, optional
        The method's ``minscan``: fewest scans a line may span before it leaves the BTR. None
        (default) uses all scans, as the method text does.
    max_rate_deg_per_min : float, optional
        ``trace="bearing"``: largest bearing-rate magnitude searched, deg/min; None: 180 deg over
        ``min_scans - 1`` scans (the analogue of a line crossing all beams).
    rate_step_deg_per_min : float, optional
        ``trace="bearing"``: bearing-rate increment, deg/min; None: the increment that moves a
        broadside trace's oldest scan by a quarter of a beam, ``0.25 / ((N - 1) / 2 * history)``
        rad/s (the straight lines' quarter beam over the history).
    max_slope : float, optional
        ``trace="beam"``: largest slope magnitude searched, beams per update; None: the slope that
        crosses all beams in ``min_scans`` scans, ``(n_beams - 1) / (min_scans - 1)``.
    slope_step : float, optional
        ``trace="beam"``: slope increment, beams per update; None: a quarter of a beam over the
        history, ``0.25 / (n_scans - 1)``.
    rate_at : {"midpoint", "latest"}
        ``trace="beam"``: beam at which the beam rate is turned into a bearing rate (eq. 10): the
        middle of the best line (default) or its latest end.
    min_snr_ibw : float
        Defaults are output when the linear IBW SNR is at most this (the method: 1, i.e. 0 dB).
    default_snr_ibw : float
        Linear IBW SNR put through eq. 4 to give the default SNR (the method: the threshold).
    exclude_beams : float, optional
        Beams each side of the best line left out of the band noise level; None: the main lobe to
        its first nulls, ``ceil(lambda / L / (2 / (N - 1)))``, at least the beam tolerance.

    Notes
    -----
    Choices where the method text is silent or its equations were lost:

    - normaliser: split-window median (see :func:`normalize_spectra`);
    - fans: the method's lines are straight in beam number, but the method also assumes beams
      equally spaced in cosine (eqs. 5-11), where a target at a constant bearing rate draws a
      curve; by default each fan holds the constant-bearing-rate traces through its anchor beam,
      rates ``-max_rate .. max_rate`` in steps of ``rate_step``, each read at the nearest beam as
      ``rateest`` reads its lines (segments 62-70: mean over the scans used, minimum-scan rule,
      strictly largest mean). ``trace="beam"`` keeps the straight lines, slopes
      ``-max_slope .. max_slope`` in steps of ``slope_step``;
    - the overall best trace and its SPN give the band noise level, the IBW SNR and the defaults
      exactly as in the method (segments 50-52); only when the defaults are not used is the trace
      refined to a sub-beam end position and rate by a local search of its main-lobe matched score
      (:func:`refine_trace`), since one cell per scan cannot place a trace between beams;
    - segment 54 for a trace: the bearing of its (refined) end beam (eq. 6) and its bearing rate,
      which is already in rad/s (the trace is the integral of eq. 11); for a straight line eq. 10
      is evaluated at the middle of the line by default (at constant bearing rate the chord has
      beam rate ``(N - 1) / 2 sin(theta) theta_dot`` at the *mean* bearing to within
      ``sinc(delta_theta / 2)``);
    - SNR (eq. 4, reconstructed): SNR per bin ``~ snr_ibw * nbins_ibw``, SNR in 1 Hz
      ``= SNR_bin * dfbin * 1.3`` (Hamming equivalent noise bandwidth), in dB;
    - the lag-corrected bearing is clipped to ``[0, 180]`` deg.

    Examples
    --------
    >>> from fusion.simulate.cube import simulate_cube
    >>> sc = simulate_cube(seed=3, bearing0_deg=60.0, bearing_rate_deg_per_min=30.0, snr_db=6.0)
    >>> res = Acquisition().acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    >>> bool(abs(res.bearing_rate_deg_per_min - 30.0) < 7.5)
    True
    """

    def __init__(
        self,
        *,
        ibw_hz: float | None = None,
        lag_s: float = 0.0,
        normalize: bool = True,
        window_bins: int = 8,
        gap_bins: int = 1,
        noise_dof: float = 2.0,
        pool_scans: int | None = None,
        trace: Literal["bearing", "beam"] = "bearing",
        sampling: Literal["nearest", "linear"] = "nearest",
        refine: bool | None = None,
        refine_span_beams: float = 2.0,
        min_scans: int | None = None,
        max_rate_deg_per_min: float | None = None,
        rate_step_deg_per_min: float | None = None,
        max_slope: float | None = None,
        slope_step: float | None = None,
        rate_at: Literal["midpoint", "latest"] = "midpoint",
        min_snr_ibw: float = 1.0,
        default_snr_ibw: float = 1.0,
        exclude_beams: float | None = None,
    ) -> None:
        if ibw_hz is not None and (not np.isfinite(ibw_hz) or ibw_hz <= 0):
            raise ValueError(f"ibw_hz must be positive, got {ibw_hz!r}")
        if not np.isfinite(lag_s):
            raise ValueError(f"lag_s must be finite, got {lag_s!r}")
        if min_scans is not None and (int(min_scans) != min_scans or min_scans < 2):
            raise ValueError(f"min_scans must be an integer >= 2, got {min_scans!r}")
        for name, v in (("max_slope", max_slope), ("slope_step", slope_step),
                        ("max_rate_deg_per_min", max_rate_deg_per_min),
                        ("rate_step_deg_per_min", rate_step_deg_per_min),
                        ("exclude_beams", exclude_beams), ("refine_span_beams", refine_span_beams)):
            if v is not None and (not np.isfinite(v) or v <= 0):
                raise ValueError(f"{name} must be positive, got {v!r}")
        if trace not in ("bearing", "beam"):
            raise ValueError(f"trace must be 'bearing' or 'beam', got {trace!r}")
        if sampling not in ("nearest", "linear"):
            raise ValueError(f"sampling must be 'nearest' or 'linear', got {sampling!r}")
        if trace == "beam":
            if refine:
                raise ValueError("refine applies to trace='bearing' (the straight lines are literal)")
            for name, v in (("max_rate_deg_per_min", max_rate_deg_per_min),
                            ("rate_step_deg_per_min", rate_step_deg_per_min)):
                if v is not None:
                    raise ValueError(f"{name} applies to trace='bearing'; use max_slope/slope_step")
        else:
            for name, v in (("max_slope", max_slope), ("slope_step", slope_step)):
                if v is not None:
                    raise ValueError(
                        f"{name} applies to trace='beam'; use max_rate_deg_per_min/"
                        "rate_step_deg_per_min"
                    )
        if rate_at not in ("midpoint", "latest"):
            raise ValueError(f"rate_at must be 'midpoint' or 'latest', got {rate_at!r}")
        for name, v in (("min_snr_ibw", min_snr_ibw), ("default_snr_ibw", default_snr_ibw)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive, got {v!r}")
        if not np.isfinite(noise_dof) or noise_dof <= 0:
            raise ValueError(f"noise_dof must be positive, got {noise_dof!r}")
        if pool_scans is not None and (int(pool_scans) != pool_scans or pool_scans < 1):
            raise ValueError(f"pool_scans must be a positive integer, got {pool_scans!r}")
        self.ibw_hz = ibw_hz
        self.lag_s = float(lag_s)
        self.normalize = bool(normalize)
        self.window_bins = int(window_bins)
        self.gap_bins = int(gap_bins)
        self.noise_dof = float(noise_dof)
        self.pool_scans = pool_scans
        self.trace = trace
        self.sampling = sampling
        self.refine = (trace == "bearing") if refine is None else bool(refine)
        self.refine_span_beams = float(refine_span_beams)
        self.min_scans = min_scans
        self.max_rate_deg_per_min = max_rate_deg_per_min
        self.rate_step_deg_per_min = rate_step_deg_per_min
        self.max_slope = max_slope
        self.slope_step = slope_step
        self.rate_at = rate_at
        self.min_snr_ibw = float(min_snr_ibw)
        self.default_snr_ibw = float(default_snr_ibw)
        self.exclude_beams = exclude_beams

    # ----------------------------------------------------------------------------------------
    def _check(self, cube: Cube, beam: int, freq_hz: float) -> float:
        if not isinstance(cube, Cube):
            raise ValueError(f"cube must be a fusion.io.Cube, got {type(cube).__name__}")
        power = np.asarray(cube.power)
        if power.ndim != 3:
            raise ValueError(f"cube power must have shape (scans, beams, bins), got {power.shape}")
        if cube.n_bins < 2:
            raise ValueError("the cube needs at least 2 frequency bins (bin spacing unknown)")
        if isinstance(beam, bool) or not float(beam).is_integer():
            raise ValueError(f"beam must be an integer beam index, got {beam!r}")
        if not 0 <= int(beam) < cube.n_beams:
            raise ValueError(f"beam {beam} is outside the cube's beams 0..{cube.n_beams - 1}")
        df = float(np.median(np.diff(cube.freqs)))
        lo, hi = cube.freqs[0] - 0.5 * df, cube.freqs[-1] + 0.5 * df
        if not np.isfinite(freq_hz) or not lo <= freq_hz <= hi:
            raise ValueError(
                f"frequency {freq_hz!r} Hz is outside the cube's band {lo:.3f}..{hi:.3f} Hz"
            )
        return df

    def _best_straight_line(
        self, btr_rev: NDArray[np.float64], anchors: NDArray[np.int64], min_scans: int
    ) -> BestLine | None:
        """Segments 46-50 with the method's straight lines."""
        n_scans, n_beams = btr_rev.shape
        max_slope = ((n_beams - 1) / (min_scans - 1) if self.max_slope is None
                     else float(self.max_slope))
        step = 0.25 / (n_scans - 1) if self.slope_step is None else float(self.slope_step)
        fans = best_lines_in_fans(btr_rev, anchors, slope_grid(-max_slope, max_slope, step),
                                  min_scans=min_scans)
        if not fans.found.any():
            return None
        i = int(np.argmax(np.where(fans.found, fans.signal_plus_noise, -np.inf)))
        bestbeam, a, n_used = int(fans.anchors[i]), float(fans.slope[i]), int(fans.n_used[i])
        return BestLine(
            anchor_beam=bestbeam,
            beam_rate_per_scan=-a,
            start_scan=n_scans - n_used,
            end_scan=n_scans - 1,
            start_beam=bestbeam + a * (n_used - 1),
            end_beam=float(bestbeam),
            n_scans_used=n_used,
            signal_plus_noise=float(fans.signal_plus_noise[i]),
            trace="beam",
            coarse_end_beam=float(bestbeam),
            beams=bestbeam + a * np.arange(n_used)[::-1].astype(float),
        )

    def _trace_line(
        self, n_scans: int, n_beams: int, scan_period: float, *, anchor: int, end: float,
        rate: float, coarse_rate: float, spn: float, refined: bool,
    ) -> BestLine:
        pos, n_used = constant_rate_traces(end, rate, n_scans=n_scans, n_beams=n_beams,
                                           scan_period=scan_period)
        n_used = int(n_used)
        beams = pos[:n_used][::-1].copy()  # chronological
        return BestLine(
            anchor_beam=anchor,
            beam_rate_per_scan=float((beams[-1] - beams[0]) / max(n_used - 1, 1)),
            start_scan=n_scans - n_used,
            end_scan=n_scans - 1,
            start_beam=float(beams[0]),
            end_beam=float(end),
            n_scans_used=n_used,
            signal_plus_noise=spn,
            trace="bearing",
            bearing_rate_deg_per_min=math.degrees(rate) * 60.0,
            coarse_end_beam=float(anchor),
            coarse_bearing_rate_deg_per_min=math.degrees(coarse_rate) * 60.0,
            refined=refined,
            beams=beams,
        )

    def _best_trace(
        self, btr_rev: NDArray[np.float64], anchors: NDArray[np.int64], min_scans: int,
        scan_period: float,
    ) -> BestLine | None:
        """Segments 46-50 with constant-bearing-rate traces (not yet refined)."""
        n_scans, n_beams = btr_rev.shape
        max_rate = (math.pi / ((min_scans - 1) * scan_period) if self.max_rate_deg_per_min is None
                    else math.radians(self.max_rate_deg_per_min) / 60.0)
        step = (0.25 / ((n_beams - 1) / 2.0 * (n_scans - 1) * scan_period)
                if self.rate_step_deg_per_min is None
                else math.radians(self.rate_step_deg_per_min) / 60.0)
        k = int(math.floor(max_rate / step + 1e-9))
        rates = step * np.arange(-k, k + 1)  # symmetric, 0 included
        fans = best_traces_in_fans(btr_rev, anchors, rates, scan_period=scan_period,
                                   min_scans=min_scans, sampling=self.sampling)
        if not fans.found.any():
            return None
        i = int(np.argmax(np.where(fans.found, fans.signal_plus_noise, -np.inf)))
        rate = float(fans.rate_rad_s[i])
        return self._trace_line(n_scans, n_beams, scan_period, anchor=int(fans.anchors[i]),
                                end=float(fans.anchors[i]), rate=rate, coarse_rate=rate,
                                spn=float(fans.signal_plus_noise[i]), refined=False)

    def acquire(self, cube: Cube, *, beam: int, freq_hz: float) -> AcquisitionResult:
        """Acquire the target clicked at (`beam`, `freq_hz`) on the latest scan of `cube`.

        Parameters
        ----------
        cube : fusion.io.Cube
            Beam spectra, power shape (n_scans, n_beams, n_bins), scans in time order (the last is
            the latest update), beams equally spaced in cosine from forward endfire.
        beam : int
            Clicked beam (the method's ``ibeamclick``).
        freq_hz : float
            Clicked frequency, Hz (the method's ``freqclick``).

        Returns
        -------
        AcquisitionResult

        Raises
        ------
        ValueError
            Not a cube, a beam or frequency outside the cube, NaN power, too few bins for the
            normaliser or beams for the noise level.
        """
        df = self._check(cube, beam, freq_hz)
        beam = int(beam)
        n_scans, n_beams, _ = cube.power.shape
        scan_period = float(cube.scan_period)

        # segments 26-28: IBW, normalisation of its bins, BTR
        band = ibw_bins(cube.freqs, freq_hz, self.ibw_hz)
        if self.normalize:
            spectra = normalize_spectra(cube.power, window_bins=self.window_bins,
                                        gap_bins=self.gap_bins, noise_dof=self.noise_dof,
                                        pool_scans=(None if self.pool_scans is None
                                                    else min(self.pool_scans, n_scans)),
                                        bins=band)
        else:
            spectra = cube.power[:, :, band]
            if not np.all(np.isfinite(spectra)):
                raise ValueError("cube power contains NaN or infinite values")
        btr = ibw_btr(spectra)  # (scans, beams), chronological
        btr_rev = btr[::-1]  # row 0 = latest update, as in the method's btr[iscan][ibeam]

        # segments 40-44: beamwidth, beam tolerance, anchors
        wavelength = cube.sound_speed / float(cube.freqs[int(np.argmin(np.abs(cube.freqs - freq_hz)))])
        bw_deg = beamwidth_deg(beam, n_beams, wavelength=wavelength, aperture=cube.aperture)
        tol = beam_tolerance(wavelength, cube.aperture, n_beams)
        anchors = np.arange(max(0, beam - tol), min(n_beams - 1, beam + tol) + 1)

        # segments 46-50: best line in every fan, overall best line
        min_scans = n_scans if self.min_scans is None else min(int(self.min_scans), n_scans)
        if self.trace == "beam":
            best_line = self._best_straight_line(btr_rev, anchors, min_scans)
        else:
            best_line = self._best_trace(btr_rev, anchors, min_scans, scan_period)
        brg_click = float(bearing_from_beam(beam, n_beams))

        # segment 52: band noise level off the trace, linear SNR in the IBW
        snr_ibw = float("nan")
        noise = float("nan")
        lobe_beams = wavelength / cube.aperture * (n_beams - 1) / 2.0  # first null, beams
        if best_line is not None:
            excl = (float(max(tol, int(math.ceil(lobe_beams)))) if self.exclude_beams is None
                    else self.exclude_beams)
            # the trace over every scan, also beyond where it leaves the BTR
            if best_line.trace == "beam":
                track = best_line.end_beam - best_line.beam_rate_per_scan * np.arange(n_scans)
            else:
                track = constant_rate_traces(
                    best_line.end_beam, math.radians(best_line.bearing_rate_deg_per_min) / 60.0,
                    n_scans=n_scans, n_beams=n_beams, scan_period=scan_period)[0]
            noise = band_noise_level(btr_rev, best_line.anchor_beam, exclude_beams=excl,
                                     track=track)
            if noise <= 0:
                raise ValueError("band noise level is zero: the IBW holds no noise power")
            snr_ibw = (best_line.signal_plus_noise - noise) / noise

        common = {"snr_ibw": snr_ibw, "btr": btr, "band_noise_level": noise,
                  "beamwidth_deg": bw_deg, "beam_tolerance": tol,
                  "anchor_beams": tuple(int(b) for b in anchors),
                  "ibw_bins": tuple(int(b) for b in band)}
        nbins_ibw = int(band.size)
        if best_line is None or not snr_ibw > self.min_snr_ibw:
            # defaults (segment 52): rate 0, clicked beam's bearing, default SNR through eq. 4
            logger.info("IBW SNR %.3g <= %.3g: default estimates", snr_ibw, self.min_snr_ibw)
            snr_1hz = self.default_snr_ibw * nbins_ibw * df * HAMMING_ENBW
            return AcquisitionResult(
                bearing_deg=math.degrees(brg_click), bearing_rate_deg_per_min=0.0,
                snr_db=10.0 * math.log10(snr_1hz), default_used=True,
                bearing_uncorrected_deg=math.degrees(brg_click), best_line=best_line, **common)

        # sub-beam refinement of the overall best trace (the SPN and SNR stay the fan search's)
        if best_line.trace == "bearing" and self.refine:
            coarse_rate = math.radians(best_line.bearing_rate_deg_per_min) / 60.0
            ref = refine_trace(btr_rev, best_line.end_beam, coarse_rate, scan_period=scan_period,
                               min_scans=min_scans, lobe_beams=lobe_beams, noise_level=noise,
                               span_beams=self.refine_span_beams)
            best_line = self._trace_line(
                n_scans, n_beams, scan_period, anchor=best_line.anchor_beam, end=ref.end_beam,
                rate=ref.rate_rad_s, coarse_rate=coarse_rate,
                spn=best_line.signal_plus_noise, refined=True)

        # segment 54: beam -> bearing (eq. 6), beam rate -> bearing rate (eq. 10), lag correction
        if best_line.trace == "bearing":
            rate_rad_s = math.radians(best_line.bearing_rate_deg_per_min) / 60.0
        else:
            beam_rate = best_line.beam_rate_per_scan / scan_period  # beams/s, forward in time
            ref_beam = (0.5 * (best_line.start_beam + best_line.end_beam)
                        if self.rate_at == "midpoint" else best_line.end_beam)
            rate_rad_s = float(bearing_rate_from_beam_rate(ref_beam, beam_rate, n_beams))
        brg_uncorrected = float(bearing_from_beam(best_line.end_beam, n_beams))
        brg = min(max(brg_uncorrected + rate_rad_s * self.lag_s, 0.0), math.pi)
        snr_1hz = snr_ibw * nbins_ibw * df * HAMMING_ENBW  # eq. 4 (reconstructed)
        return AcquisitionResult(
            bearing_deg=math.degrees(brg),
            bearing_rate_deg_per_min=math.degrees(rate_rad_s) * 60.0,
            snr_db=10.0 * math.log10(snr_1hz),
            default_used=False,
            bearing_uncorrected_deg=math.degrees(brg_uncorrected),
            best_line=best_line,
            **common,
        )


def acquire(cube: Cube, *, beam: int, freq_hz: float, **options: object) -> AcquisitionResult:
    """Function form of :class:`Acquisition`: ``Acquisition(**options).acquire(cube, ...)``.

    Parameters
    ----------
    cube : fusion.io.Cube
        Beam spectra, shape (n_scans, n_beams, n_bins), the last scan the latest.
    beam : int
        Clicked beam.
    freq_hz : float
        Clicked frequency, Hz.
    **options
        Keyword options of :class:`Acquisition`.

    Returns
    -------
    AcquisitionResult
    """
    return Acquisition(**options).acquire(cube, beam=beam, freq_hz=freq_hz)  # type: ignore[arg-type]
