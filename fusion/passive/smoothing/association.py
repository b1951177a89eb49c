"""Association weights of shared bearings: posterior probabilities, or a hard baseline.

Around a crossing a detection may come from any of the tracks near it, or from clutter. The
multi-track smoother (:mod:`~fusion.passive.smoothing.multitrack`) puts such a detection into
every candidate track's graph through an association-weighted factor
(:func:`factors.weighted.weighted_factor`); this module computes the weights.

- :func:`joint_weights` -- the posterior probability ``beta_jm`` that detection ``j`` of a scan
  came from track ``m`` (joint probabilistic data association): every joint event of the scan
  (each detection from at most one track or from clutter, each track giving at most one
  detection) has the probability

  .. math::

      P(\\theta) \\propto \\prod_{(j, m) \\in \\theta} P_D\\, g_{jm}
      \\prod_{j \\text{ clutter}} \\lambda \\prod_{m \\text{ missed}} (1 - P_D),

  ``g_jm`` the measurement density of ``z_j`` at the track's current bearing, ``lambda`` the
  clutter density (per scan per radian) and ``P_D`` the detection probability; ``beta_jm`` is
  the sum over the events holding ``(j, m)``. Scans with more than `max_joint` shared
  detections get per-detection responsibilities ``P_D g_jm / (lambda + sum_m' P_D g_jm')``
  (no one-detection-per-track constraint) and are counted.
- :func:`nearest_weights` -- the baseline: per scan a gated nearest assignment (weights 0/1).
- :func:`clutter_and_detection` -- ``lambda`` and ``P_D`` counted from labelled detections.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

__all__ = ["clutter_and_detection", "joint_weights", "nearest_weights"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Detection probabilities are kept inside [P_MIN, P_MAX] in the joint events (a track certain
#: to be detected would make two tracks with one detection between them impossible).
P_MIN, P_MAX = 0.05, 0.995


def _events(dets: list[int], tracks: list[int], pairs: dict[tuple[int, int], float],
            p_d: float, clutter: float) -> tuple[dict[tuple[int, int], float], float]:
    """Sum of event probabilities holding each pair, and of all events (one scan)."""
    acc = dict.fromkeys(pairs, 0.0)
    total = 0.0
    n_tracks = len(tracks)
    chosen: list[tuple[int, int]] = []

    def rec(i: int, used: frozenset, prob: float) -> None:
        nonlocal total
        if i == len(dets):
            p = prob * (1.0 - p_d) ** (n_tracks - len(used))
            total += p
            for pr in chosen:
                acc[pr] += p
            return
        j = dets[i]
        rec(i + 1, used, prob * clutter)  # j from clutter
        for m in tracks:
            g = pairs.get((j, m))
            if g is not None and m not in used:
                chosen.append((j, m))
                rec(i + 1, used | {m}, prob * p_d * g)
                chosen.pop()

    rec(0, frozenset(), 1.0)
    return acc, total


def _scan_rows(scan: IntArray) -> list[IntArray]:
    """Indices of the pairs of each scan (ascending), scans in ascending order."""
    if scan.size == 0:
        return []
    order = np.argsort(scan, kind="stable")
    return np.split(order, np.flatnonzero(np.diff(scan[order])) + 1)


def joint_weights(scan: IntArray, det: IntArray, track: IntArray, density: FloatArray, *,
                  p_detect: float, clutter_density: float, max_joint: int = 7
                  ) -> tuple[FloatArray, int]:
    """Posterior association probabilities of (detection, track) pairs, scan by scan.

    Parameters
    ----------
    scan, det, track : ndarray of int, shape (n_pairs,)
        Per candidate pair: its scan, detection and track.
    density : ndarray, shape (n_pairs,)
        Measurement density of the detection at the track's current bearing, 1/rad.
    p_detect : float, keyword-only
        Detection probability of a track in a scan (clipped to [0.05, 0.995]).
    clutter_density : float, keyword-only
        False detections per scan per radian.
    max_joint : int, keyword-only
        Most shared detections of one scan whose joint events are enumerated.

    Returns
    -------
    weights : ndarray, shape (n_pairs,)
        ``beta_jm``; per detection they sum to at most 1 (the rest is clutter).
    n_approximate : int
        Scans that had more than `max_joint` shared detections (per-detection
        responsibilities instead of joint events).

    Examples
    --------
    One detection halfway between two tracks, no clutter to speak of: half each.

    >>> w, _ = joint_weights(np.array([0, 0]), np.array([5, 5]), np.array([0, 1]),
    ...                      np.array([2.0, 2.0]), p_detect=0.9, clutter_density=1e-9)
    >>> np.round(w, 6).tolist()
    [0.5, 0.5]
    """
    p_d = float(np.clip(p_detect, P_MIN, P_MAX))
    lam = float(clutter_density)
    out = np.zeros(det.size)
    n_approx = 0
    for rows in _scan_rows(scan):
        dets = sorted({int(j) for j in det[rows]})
        if len(dets) > max_joint:
            n_approx += 1
            lik = p_d * density[rows]
            denom = np.full(int(det[rows].max()) + 1, lam)
            np.add.at(denom, det[rows], lik)
            out[rows] = lik / denom[det[rows]]
            continue
        if len(dets) == 1 and np.unique(track[rows]).size == rows.size:
            # one detection: its events are clutter or one of its tracks; the products and
            # sums of _events in the same order, without the recursion
            by_track = rows[np.argsort(track[rows], kind="stable")]
            n_t = rows.size
            p_m = [p_d * float(density[r]) * (1.0 - p_d) ** (n_t - 1) for r in by_track]
            total = lam * (1.0 - p_d) ** n_t
            for p in p_m:
                total += p
            for r, p in zip(by_track, p_m, strict=True):
                out[r] = p / total
            continue
        tracks = sorted({int(m) for m in track[rows]})
        pairs = {(int(det[r]), int(track[r])): float(density[r]) for r in rows}
        acc, total = _events(dets, tracks, pairs, p_d, lam)
        for r in rows:
            out[r] = acc[(int(det[r]), int(track[r]))] / total
    return out, n_approx


def nearest_weights(scan: IntArray, det: IntArray, track: IntArray, d2: FloatArray, *,
                    gate: float) -> FloatArray:
    """Hard weights (0 or 1): per scan, the assignment of detections to tracks with the least
    sum of squared normalised innovations `d2`, pairs beyond ``gate**2`` not allowed.

    Examples
    --------
    >>> nearest_weights(np.array([0, 0, 0, 0]), np.array([1, 1, 2, 2]), np.array([0, 1, 0, 1]),
    ...                 np.array([0.1, 2.0, 1.0, 0.5]), gate=3.0).tolist()
    [1.0, 0.0, 0.0, 1.0]
    """
    out = np.zeros(det.size)
    big = 1e12
    for rows in _scan_rows(scan):
        dets = np.unique(det[rows])
        tracks = np.unique(track[rows])
        cost = np.full((dets.size, tracks.size), big)
        ri = np.searchsorted(dets, det[rows])
        ci = np.searchsorted(tracks, track[rows])
        cost[ri, ci] = np.where(d2[rows] <= gate**2, d2[rows], big)
        rr, cc = linear_sum_assignment(cost)
        ok = {(int(r), int(c)) for r, c in zip(rr, cc, strict=True) if cost[r, c] < big}
        out[rows] = [1.0 if (int(a), int(b)) in ok else 0.0 for a, b in zip(ri, ci, strict=True)]
    return out


def clutter_and_detection(labels: IntArray, scan_of: IntArray, first: IntArray, last: IntArray,
                          released: NDArray[np.bool_], bearings: FloatArray
                          ) -> tuple[float, float]:
    """Clutter density and detection probability counted from the labelled detections.

    Parameters
    ----------
    labels : ndarray of int, shape (n,)
        Track of each detection, -1 none.
    scan_of : ndarray of int, shape (n,)
        Scan index of each detection.
    first, last : ndarray of int, shape (n_tracks,)
        First and last scan of each track.
    released : ndarray of bool, shape (n,)
        Detections in a track's gap (candidates of shared association): neither clutter nor
        a track's in this count.
    bearings : ndarray, shape (n,)
        Bearings, rad (the arc they cover is the clutter's support).

    Returns
    -------
    clutter_density : float
        Unlabelled, unreleased detections per scan per radian of the arc the bearings cover
        (at least 1e-3).
    p_detect : float
        A track's detections per scan of its life, gap scans left out (in [0.05, 0.995]).
    """
    n_scans = int(scan_of.max()) + 1 if scan_of.size else 1
    srt = np.sort(np.mod(bearings, 2 * np.pi))
    gaps = np.diff(np.r_[srt, srt[:1] + 2 * np.pi]) if srt.size else np.array([0.0])
    arc = max(2 * np.pi - float(gaps.max()), np.radians(1.0))
    n_clutter = int(np.sum((labels < 0) & ~released))
    lam = max(n_clutter / (n_scans * arc), 1e-3)
    own, span = 0, 0
    for m in range(first.size):
        sel = labels == m
        gap_scans = np.unique(scan_of[released & (scan_of >= first[m]) & (scan_of <= last[m])])
        own += int(np.unique(scan_of[sel]).size)
        span += int(last[m] - first[m] + 1) - gap_scans.size
    p_d = own / span if span > 0 else 0.9
    return float(lam), float(np.clip(p_d, P_MIN, P_MAX))
