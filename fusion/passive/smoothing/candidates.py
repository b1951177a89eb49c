"""Detections a linked track may have made where no segment holds them: in its gaps, and
before its first or after its last segment.

:class:`~fusion.passive.smoothing.multitrack.MultiTrackSmoother` cuts tracks where two of them
are ambiguous and links the segments into tracks; the detections it released there are
candidates of every track whose prediction gates them, and enter those tracks through
association-weighted factors.

- :func:`gap_candidates` -- unassigned detections between two linked segments, gated against
  the track's interpolation across the gap (forward and backward predictions fused);
- :func:`end_candidates` -- unassigned detections before a track's first segment or after its
  last one (a track that starts or ends beside another), gated against the end state
  predicted scan by scan until ``max_misses`` scans in a row hold none.

An end is the tuple of :meth:`MultiTrackSmoother._segment_ends`: ``(first scan, first state,
its covariance, last scan, last state, its covariance)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import wrap_angle

__all__ = ["end_candidates", "gap_candidates"]

FloatArray = NDArray[np.float64]


def gap_candidates(end: tuple, start: tuple, scan_times: FloatArray, z: FloatArray,
                   scan_of: NDArray[np.int64], labels: NDArray[np.int64], *, q: float,
                   sigma_bearing: float, gate: float) -> list[int]:
    """Unassigned detections (`labels` -1) in the gap between segment ends `end` and `start`,
    within `gate` standard deviations of the track's interpolation across the gap."""
    s1, x_e, p_e = end[3], end[4], end[5]
    s0, x_s, p_s = start[0], start[1], start[2]
    sel = np.flatnonzero((scan_of > s1) & (scan_of < s0) & (labels < 0))
    # forward prediction from the end, backward prediction from the start (the 2x2
    # products F P F^T + Q written out, all detections of the gap at once)
    dt_f = scan_times[scan_of[sel]] - scan_times[s1]
    dt_b = scan_times[s0] - scan_times[scan_of[sel]]
    m_f = x_e[0] + dt_f * x_e[1]
    v_f = p_e[0, 0] + 2 * dt_f * p_e[0, 1] + dt_f**2 * p_e[1, 1] + q * dt_f**3 / 3
    m_b = x_s[0] - dt_b * x_s[1]
    v_b = ((p_s[0, 0] + q * dt_b**3 / 3) - 2 * dt_b * (p_s[0, 1] + q * dt_b**2 / 2)
           + dt_b**2 * (p_s[1, 1] + q * dt_b))
    theta = m_f + wrap_angle(m_b - m_f) * v_f / (v_f + v_b)
    var = v_f * v_b / (v_f + v_b) + sigma_bearing**2
    ok = np.abs(wrap_angle(z[sel] - theta)) < gate * np.sqrt(var)
    return [int(j) for j in sel[ok]]


def end_candidates(end: tuple, forward: bool, scan_times: FloatArray, z: FloatArray,
                   scan_of: NDArray[np.int64], labels: NDArray[np.int64], *, q: float,
                   sigma_bearing: float, gate: float, max_misses: int, max_scans: int,
                   eligible: NDArray[np.bool_] | None = None) -> list[int]:
    """Unassigned detections (`labels` -1) after the last scan of `end` (`forward`) or before
    its first scan, within `gate` standard deviations of the end state predicted to their
    scan (constant rate, white-noise acceleration `q`), scan by scan until more than
    `max_misses` scans in a row hold none or `max_scans` scans are passed; only detections
    marked in `eligible` (default all). `scan_of` must be non-decreasing."""
    s_end, x, p = (end[3], end[4], end[5]) if forward else (end[0], end[1], end[2])
    sgn = 1.0 if forward else -1.0
    free = (labels < 0) if eligible is None else (labels < 0) & eligible
    out: list[int] = []
    misses = 0
    for step in range(1, max_scans + 1):
        s = s_end + step if forward else s_end - step
        if s < 0 or s >= scan_times.size:
            break
        dt = abs(scan_times[s] - scan_times[s_end])
        theta = x[0] + sgn * dt * x[1]
        var = (p[0, 0] + 2 * sgn * dt * p[0, 1] + dt**2 * p[1, 1] + q * dt**3 / 3
               + sigma_bearing**2)
        sel = np.arange(np.searchsorted(scan_of, s), np.searchsorted(scan_of, s, "right"))
        sel = sel[free[sel]]
        ok = sel[np.abs(wrap_angle(z[sel] - theta)) < gate * np.sqrt(var)]
        if ok.size:
            out.extend(int(j) for j in ok)
            misses = 0
        else:
            misses += 1
            if misses > max_misses:
                break
    return out


def track_candidates(kept: list[list[int]], ends: list[tuple], scan_times: FloatArray,
                     z: FloatArray, scan_of: NDArray[np.int64], labels: NDArray[np.int64],
                     first: NDArray[np.int64], last: NDArray[np.int64], *, q: float,
                     sigma_bearing: float, gate: float, starts: bool, finishes: bool,
                     max_misses: int, max_scans: int, eligible) -> list[list[int]]:
    """Candidate tracks of every detection: the gaps of each chain of `kept` (segment indices
    into `ends`), and with `starts` / `finishes` also before its first / after its last
    segment (:func:`end_candidates` over the detections ``eligible(p)`` allows for segment
    ``p``); `first` and `last` (scan per track) are widened in place to the extensions."""
    cand: list[list[int]] = [[] for _ in range(z.size)]
    gating = {"q": q, "sigma_bearing": sigma_bearing, "gate": gate}
    for m, ch in enumerate(kept):
        for p, p_next in zip(ch[:-1], ch[1:], strict=True):
            for j in gap_candidates(ends[p], ends[p_next], scan_times, z, scan_of, labels,
                                    **gating):
                cand[j].append(m)
        for fwd, p, on in ((False, ch[0], starts), (True, ch[-1], finishes)):
            if not on:
                continue
            js = end_candidates(ends[p], fwd, scan_times, z, scan_of, labels, **gating,
                                max_misses=max_misses, max_scans=max_scans,
                                eligible=eligible(p))
            for j in js:
                cand[j].append(m)
            if js:
                if fwd:
                    last[m] = max(last[m], int(scan_of[js].max()))
                else:
                    first[m] = min(first[m], int(scan_of[js].min()))
    return cand
