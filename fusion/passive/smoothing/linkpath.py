"""Links refused when the path they imply crosses scans with no detection (issue 18).

A segment of three or four clutter detections has an end state whose rate is barely known;
propagated across a gap of 30-55 scans its covariance covers most of the sky, so its link to
a target's later segment has a small Mahalanobis distance, and the assignment, which makes
the most links first, prefers two such links (the target's end to a clutter start, a clutter
end to the target's start) to the target's own one ("fragmentation" in
:func:`fusion.metrics.crossings.crossing_failure_causes`; tuning seed 9235, spent seeds 9244,
9823, 9859, 9874). A target bridged across a gap is detected with probability ``P_D`` on
each scan of it (inside a crossing its detections are released, not absent); the path of a
clutter link passes through scans with nothing near it. :func:`path_misses` counts, along
the cubic (Hermite) path between a link's end and start states, the scans of the gap with no
detection within ``k`` sigma of the path, the sigma including the end states' covariances
carried along the path and the bridge variance of the white-noise acceleration model;
:func:`implausible_links` refuses a link whose miss count has binomial tail probability
below ``alpha`` under "a target detected with ``P_D``" (misses taken as independent).
:func:`short_segment_path_test` applies it only to links from or to a segment with fewer than
``min_length`` detections (the clutter segments' signature, a barely known end state): on
the Autoferry camera bearings, where boats are occluded for tens of seconds (misses that are
not independent), testing every link lost true links (mean cover 0.527 -> 0.35).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.special import betainc

from fusion.geometry import wrap_angle

__all__ = ["implausible_links", "miss_tail_probability", "path_misses",
           "short_segment_path_test", "tracker_p_detect"]

FloatArray = NDArray[np.float64]

#: Half-width of the window around the path, in standard deviations.
PATH_K_SIGMA = 3.0


def miss_tail_probability(misses: NDArray, scans: NDArray, p_detect: float) -> FloatArray:
    """``P(X >= misses)`` for ``X ~ Binomial(scans, 1 - p_detect)`` (1 where misses is 0)."""
    m = np.asarray(misses, float)
    n = np.asarray(scans, float)
    out = np.ones(np.broadcast(m, n).shape)
    pos = m > 0
    out[pos] = betainc(m[pos], n[pos] - m[pos] + 1.0, 1.0 - p_detect)
    return out


def path_misses(end: tuple, start: tuple, scan_times: FloatArray, scan_ptr: NDArray[np.int64],
                z_sorted: FloatArray, *, q: float, sigma: float) -> tuple[int, int]:
    """Scans strictly inside the gap from `end` (its last scan) to `start` (its first scan)
    with no detection within :data:`PATH_K_SIGMA` sigma of the Hermite path, and the number
    of scans inside the gap. `z_sorted` holds every detection's bearing ordered by scan,
    those of scan k at ``scan_ptr[k]: scan_ptr[k + 1]``."""
    s1, xe, pe = int(end[3]), end[4], end[5]
    s0, xs, ps = int(start[0]), start[1], start[2]
    inner = np.arange(s1 + 1, s0)
    if inner.size == 0:
        return 0, 0
    t_e, t_s = scan_times[s1], scan_times[s0]
    big_t = t_s - t_e
    th_e, r_e, r_s = float(xe[0]), float(xe[1]), float(xs[1])
    th_s = th_e + float(wrap_angle(xs[0] - th_e))  # the start on the end's branch
    u = (scan_times[inner] - t_e) / big_t
    h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
    h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
    path = h00 * th_e + h10 * big_t * r_e + h01 * th_s + h11 * big_t * r_s
    tau = u * big_t
    ge, gs = np.stack([h00, h10 * big_t]), np.stack([h01, h11 * big_t])  # path gradients
    var = (sigma**2 + q * tau**3 * (big_t - tau) ** 3 / (3.0 * big_t**3)
           + np.einsum("in,ij,jn->n", ge, pe, ge) + np.einsum("in,ij,jn->n", gs, ps, gs))
    half = PATH_K_SIGMA * np.sqrt(var)
    # Every detection of the gap's scans at once: a scan is missed when none lies within
    # `half` of the path there (an empty scan included).
    lo, cnt = scan_ptr[inner], scan_ptr[inner + 1] - scan_ptr[inner]
    row = np.repeat(np.arange(inner.size), cnt)
    det = np.repeat(lo - np.cumsum(cnt) + cnt, cnt) + np.arange(row.size)
    near = np.abs(wrap_angle(z_sorted[det] - path[row])) <= half[row]
    misses = inner.size - np.count_nonzero(np.bincount(row[near], minlength=inner.size))
    return int(misses), int(inner.size)


def implausible_links(ends: list[tuple], ei: NDArray[np.int64], si: NDArray[np.int64],
                      scan_times: FloatArray, scan_of_det: NDArray[np.int64], z: FloatArray,
                      *, q: float, sigma: float, p_detect: float, alpha: float
                      ) -> NDArray[np.bool_]:
    """Which links (end ``ei[k]``, start ``si[k]``) have a path whose scans without a nearby
    detection are less probable than `alpha` for a target detected with `p_detect`."""
    order = np.argsort(scan_of_det, kind="stable")
    z_sorted = z[order]
    scan_ptr = np.searchsorted(scan_of_det[order], np.arange(scan_times.size + 1))
    bad = np.zeros(ei.size, bool)
    for k, (e, s) in enumerate(zip(ei, si, strict=True)):
        m, n = path_misses(ends[int(e)], ends[int(s)], scan_times, scan_ptr, z_sorted, q=q,
                           sigma=sigma)
        if m > 0:
            bad[k] = miss_tail_probability(np.array([m]), np.array([n]), p_detect)[0] < alpha
    return bad


def short_segment_path_test(ends: list[tuple], sizes: NDArray[np.int64], min_length: int,
                            scan_times: FloatArray, scan_of_det: NDArray[np.int64],
                            z: FloatArray, *, q: float, sigma: float, p_detect: float,
                            alpha: float
                            ) -> Callable[[NDArray[np.int64], NDArray[np.int64]],
                                          NDArray[np.bool_]]:
    """``implausible(ei, si)`` for :func:`~fusion.passive.smoothing.linking.link_segments`:
    :func:`implausible_links` on the links whose end or start segment has fewer than
    `min_length` detections (`sizes`), False for the others."""
    def implausible(ei: NDArray[np.int64], si: NDArray[np.int64]) -> NDArray[np.bool_]:
        out = np.zeros(ei.size, bool)
        few = (sizes[ei] < min_length) | (sizes[si] < min_length)
        if few.any():
            out[few] = implausible_links(ends, ei[few], si[few], scan_times, scan_of_det, z,
                                         q=q, sigma=sigma, p_detect=p_detect, alpha=alpha)
        return out
    return implausible


def tracker_p_detect(tr) -> float:
    """Detections per scan of the initial tracker's tracks' lives (0.8 without tracks,
    at most 0.99): ``P_D`` of the test when the smoother is given none."""
    lives = int(np.sum(tr.last_scan - tr.first_scan + 1)) if tr.n_tracks else 0
    return min(0.99, int(np.sum(tr.labels >= 0)) / lives) if lives else 0.8
