"""Segments of the initial tracks and which of them may be linked across a crossing.

- :func:`cut_segments` -- the tracker's tracks cut where two of them are ambiguous (step 2 of
  :class:`~fusion.passive.smoothing.multitrack.MultiTrackSmoother`);
- :func:`across_crossings` -- the (end, start) pairs of the second link assignment;
- :func:`segment_end_states` -- each segment's end states for the links.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import wrap_angle
from fusion.passive.crossing.timing import crossing_time
from fusion.passive.smoothing.graph import _initial_states, _Measurements, _solve_cov
from fusion.passive.smoothing.types import TrackerResult, TrackPrior

__all__ = ["across_crossings", "cut_segments", "segment_end_states"]


def cut_segments(tr: TrackerResult, scan_of: NDArray[np.int64], *, separation: float,
                 min_length: int, window_s: float, n_confirm: int
                 ) -> tuple[list[NDArray[np.int64]], NDArray[np.bool_]]:
    """Cut the tracker's tracks where two of them are ambiguous; detections per segment and
    the ambiguous scans of each tracker track (n_tracks x n_scans)."""
    n_scans = tr.scan_times.size
    ambiguous = np.zeros((tr.n_tracks, n_scans), bool)
    # a track too short to be kept does not cut others
    counts = np.bincount(tr.labels[tr.labels >= 0], minlength=tr.n_tracks)
    for a in range(tr.n_tracks):
        if counts[a] < min_length:
            continue
        for b in range(a + 1, tr.n_tracks):
            if counts[b] < min_length:
                continue
            lo = max(tr.first_scan[a], tr.first_scan[b])
            hi = min(tr.last_scan[a], tr.last_scan[b])
            if hi < lo:
                continue
            xa = tr.states[a][lo - tr.first_scan[a]: hi - tr.first_scan[a] + 1]
            xb = tr.states[b][lo - tr.first_scan[b]: hi - tr.first_scan[b] + 1]
            sep = np.abs(wrap_angle(xa[:, 0] - xb[:, 0]))
            tc = np.asarray(crossing_time(xa[:, 0], xa[:, 1], xb[:, 0], xb[:, 1]))
            # eq. (3) predicted or eq. (4) detected crossing, and close in bearing
            amb = (sep < separation) & (np.abs(tc) <= window_s)
            if amb.any():
                k = np.flatnonzero(amb) + lo
                for d in (-1, 0, 1):  # one scan of margin
                    kk = np.clip(k + d, 0, n_scans - 1)
                    ambiguous[a, kk] = True
                    ambiguous[b, kk] = True
    segments: list[NDArray[np.int64]] = []
    for m in range(tr.n_tracks):
        own = np.flatnonzero(tr.labels == m)
        own = own[np.argsort(scan_of[own], kind="stable")]
        keep = own[~ambiguous[m, scan_of[own]]]
        if keep.size == 0:
            continue
        amb_scans = np.flatnonzero(ambiguous[m])
        # a new segment starts after every ambiguous scan between two kept detections
        cut = np.searchsorted(amb_scans, scan_of[keep])
        for c in np.unique(cut):
            seg = keep[cut == c]
            if seg.size >= n_confirm:
                segments.append(seg)
    return segments, ambiguous


def across_crossings(ambiguous: NDArray[np.bool_], tr: TrackerResult,
                     segments: list[NDArray[np.int64]], ends: list[tuple]) -> NDArray[np.bool_]:
    """Pairs (end, start) of the second link assignment: the gap between them (one scan of
    margin) holds an ambiguous scan of the end's or the start's tracker track -- a fragment
    across a crossing, not a track that ended and another that began."""
    n = len(segments)
    if n == 0:
        return np.zeros((0, 0), bool)
    k = np.array([int(tr.labels[seg[0]]) for seg in segments])
    lo = np.array([int(x[3]) for x in ends])  # scans [lo, hi) of the gap from end e to start s
    hi = np.minimum(np.array([int(x[0]) for x in ends]) + 2, ambiguous.shape[1])
    # ambiguous scans of each tracker track before each scan (a prefix count)
    before = np.zeros((ambiguous.shape[0], ambiguous.shape[1] + 1), np.int64)
    np.cumsum(ambiguous, axis=1, out=before[:, 1:])
    in_end = before[k[:, None], hi[None, :]] - before[k, lo][:, None]
    in_start = before[k[None, :], hi[None, :]] - before[k[None, :], lo[:, None]]
    return (hi[None, :] > lo[:, None] + 1) & ((in_end > 0) | (in_start > 0))


def segment_end_states(seg: NDArray[np.int64], z: NDArray[np.float64],
                       scan_of: NDArray[np.int64], scan_times: NDArray[np.float64], *,
                       fit_scans: int, model, init_sigma_rate: float,
                       failed: list) -> tuple:
    """First and last scan of a segment with their states and marginal covariances (each end
    fitted on its first / last `fit_scans` scans); a fit GTSAM refuses keeps its initial line
    with weak covariances and is appended to `failed` as ``(a, b, message)``."""
    s0, s1 = int(scan_of[seg[0]]), int(scan_of[seg[-1]])
    out = []
    w = fit_scans
    spans = [(s0, s1)] if s1 - s0 < 2 * w else [(s0, s0 + w - 1), (s1 - w + 1, s1)]
    for a, b in spans:
        sel = seg[(scan_of[seg] >= a) & (scan_of[seg] <= b)]
        times_ab = scan_times[a: b + 1]
        meas = _Measurements(state=(scan_of[sel] - a).astype(np.int64), bearing=z[sel])
        x0 = _initial_states(times_ab, meas, None)
        prior = TrackPrior(bearing=float(wrap_angle(x0[0, 0])), rate=float(x0[0, 1]),
                           sigma_bearing=10.0 * model.sigma_bearing, sigma_rate=init_sigma_rate)
        try:
            states, covs = _solve_cov(times_ab, meas, prior, model, x0, (0, b - a))
        except RuntimeError as err:  # gtsam: too few bearings for the scans spanned
            # The segment's end keeps its initial line with weak covariances; counted and
            # said once per run (a WARNING of MultiTrackSmoother.run), not hidden.
            failed.append((a, b, str(err)))
            weak = np.diag([model.sigma_bearing**2, init_sigma_rate**2])
            states, covs = x0, [weak, weak]
        out.append((states, covs))
    (st_a, cov_a), (st_b, cov_b) = out[0], out[-1]
    return (s0, st_a[0], cov_a[0], s1, st_b[-1], cov_b[-1])
