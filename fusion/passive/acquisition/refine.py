"""Sub-beam refinement of the best constant-bearing-rate trace (added between segments 52 and 54).

One BTR cell per scan cannot place a trace between beams; the overall best trace of the fan
search is refined to a sub-beam end position and bearing rate by a local search of its main-lobe
matched score (:func:`matched_trace_score`, :func:`refine_trace`). Only the bearing estimate
changes: the SPN, the band noise level and the IBW SNR stay the fan search's, as in the method.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import bearing_from_beam
from fusion.passive.acquisition.traces import constant_rate_traces

__all__ = ["MATCHED_STEP_BEAMS", "RefinedTrace", "matched_trace_score", "refine_trace"]

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
