"""Segments of the multi-track smoother chained into tracks, shared detections grouped.

- :func:`link_segments` -- one assignment of segment ends to later segment starts (step 3 of
  :class:`~fusion.passive.smoothing.multitrack.MultiTrackSmoother`).
- :func:`crossing_clusters` -- shared detections grouped by candidate track and time (one EM
  per group).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from fusion.geometry import wrap_angle

__all__ = ["crossing_clusters", "link_segments", "segment_accelerations"]

FloatArray = NDArray[np.float64]


def link_segments(ends: list[tuple], scan_times: FloatArray, *, q: float, link_gate: float,
                  max_gap_scans: int, relink_gate: float | None = None,
                  relink_allowed: NDArray[np.bool_] | None = None,
                  crossing_gap_scans: int | None = None,
                  curvature: bool = False,
                  implausible: Callable[[NDArray[np.int64], NDArray[np.int64]],
                                        NDArray[np.bool_]] | None = None) -> list[list[int]]:
    """Chain segments by one assignment of segment ends to later segment starts.

    With `relink_gate` (> `link_gate`), the ends and starts the first assignment left unlinked
    are offered a second assignment among themselves with that wider gate: a fragment whose
    rate changed too much for the first gate (bearing curvature through a dense crossing zone)
    is linked to the one end left free for it instead of starting a new track; links made
    by the first assignment are not changed; `relink_allowed` (n x n, end x start; default
    all) limits the second assignment's pairs. With `crossing_gap_scans` (> `max_gap_scans`)
    the pairs of `relink_allowed` -- gaps across a crossing -- may bridge up to that many scans
    in both assignments: a slow crossing keeps two tracks ambiguous for longer than misses
    would. With `curvature`, the end state is propagated across the gap with the mean of the
    two segments' bearing accelerations (:func:`segment_accelerations`) and that mean's
    variance is added to the link covariance. `implausible(ei, si)` (optional) says which
    gated links (ends ``ei``, starts ``si``) are refused whatever their distance
    (:func:`~fusion.passive.smoothing.linkpath.implausible_links`)."""
    n = len(ends)
    if n == 0:
        return []
    period = float(np.median(np.diff(scan_times))) if scan_times.size > 1 else 1.0
    # the cost's log-determinant only where a link can be made (the widest gate)
    widest = link_gate if relink_gate is None else max(link_gate, relink_gate)
    longest = max_gap_scans if crossing_gap_scans is None else max(max_gap_scans,
                                                                     crossing_gap_scans)
    acc, acc_var = (segment_accelerations(ends, scan_times, q=q) if curvature
                    else (np.zeros(n), np.zeros(n)))
    s0 = np.array([int(x[0]) for x in ends])
    s1 = np.array([int(x[3]) for x in ends])
    ok = s0[None, :] > s1[:, None]  # end e (row) before start s (column)
    dtm = np.where(ok, scan_times[s0][None, :] - scan_times[s1][:, None], -1.0)
    ok &= (dtm > 0) & (dtm <= longest * period)
    np.fill_diagonal(ok, False)
    far = dtm > max_gap_scans * period
    ok &= ~far if relink_allowed is None else (~far | relink_allowed)
    ei, si = np.nonzero(ok)
    d2 = np.full((n, n), np.inf)
    lndet = np.zeros((n, n))
    if ei.size:
        d2_k, lndet_k = _link_distances(ends, ei, si, dtm[ei, si], q, acc, acc_var)
        d2[ei, si] = d2_k
        inside = d2_k <= widest
        if implausible is not None and inside.any():
            idx = np.flatnonzero(inside)
            bad = implausible(ei[idx], si[idx])
            d2[ei[idx[bad]], si[idx[bad]]] = np.inf
            inside[idx[bad]] = False
        lndet[ei[inside], si[inside]] = lndet_k[inside]
    nxt = _assign(np.where(d2 <= link_gate, d2 + lndet, np.inf))
    if relink_gate is not None and relink_gate > link_gate:
        free_e = np.array([e not in nxt for e in range(n)])
        free_s = np.ones(n, bool)
        free_s[list(nxt.values())] = False
        ok = (d2 <= relink_gate) & free_e[:, None] & free_s[None, :]
        if relink_allowed is not None:
            ok &= relink_allowed
        nxt.update(_assign(np.where(ok, d2 + lndet, np.inf)))
    has_prev = set(nxt.values())
    chains = []
    for p in range(n):
        if p in has_prev:
            continue
        ch = [p]
        while ch[-1] in nxt:
            ch.append(nxt[ch[-1]])
        chains.append(ch)
    return chains


#: Fewest scans a segment spans for its bearing acceleration to enter a link (`curvature`);
#: a shorter segment's is taken as 0 (tuning seeds, RESULTS.md "Issue 18: links across slow
#: crossings": 0, 5, 10, 15, 20, 30 tried).
CURVATURE_MIN_SCANS = 10
#: ... and only where its rate changed over its span by more than the white-noise acceleration
#: `q` and the two rates' variances explain: ``dr^2 > CURVATURE_SIGNIFICANCE (q span + P0_rr +
#: P1_rr)`` (tried 1 and 4 on the tuning seeds; 4 removed the gain).
CURVATURE_SIGNIFICANCE = 1.0


def _link_distances(ends: list[tuple], ei: NDArray[np.int64], si: NDArray[np.int64],
                    dt: FloatArray, q: float, acc: FloatArray, acc_var: FloatArray
                    ) -> tuple[FloatArray, FloatArray]:
    """Squared Mahalanobis distance and ``ln det S`` of the links (end ``ei``, start ``si``)
    over gaps `dt`, all at once: ``nu = x_s - F x_e`` (less the mean acceleration's part),
    ``S = F P_e F' + Q(dt) + P_s`` (plus its variance's), in closed form for 2 x 2."""
    xe = np.array([x[4] for x in ends], float)[ei]
    pe = np.array([x[5] for x in ends], float)[ei]
    xs = np.array([x[1] for x in ends], float)[si]
    ps = np.array([x[2] for x in ends], float)[si]
    fp01 = pe[:, 0, 1] + dt * pe[:, 1, 1]
    c00 = pe[:, 0, 0] + dt * pe[:, 1, 0] + fp01 * dt + q * dt**3 / 3.0 + ps[:, 0, 0]
    c01 = fp01 + q * dt**2 / 2.0 + ps[:, 0, 1]
    c10 = pe[:, 1, 0] + pe[:, 1, 1] * dt + q * dt**2 / 2.0 + ps[:, 1, 0]
    c11 = pe[:, 1, 1] + q * dt + ps[:, 1, 1]
    nu0 = xs[:, 0] - (xe[:, 0] + dt * xe[:, 1])
    nu1 = xs[:, 1] - xe[:, 1]
    a_bar = 0.5 * (acc[ei] + acc[si])
    v_bar = 0.25 * (acc_var[ei] + acc_var[si])
    j0, j1 = 0.5 * dt * dt, dt
    nu0, nu1 = wrap_angle(nu0 - a_bar * j0), nu1 - a_bar * j1
    c00, c01, c10, c11 = (c00 + v_bar * j0 * j0, c01 + v_bar * j0 * j1, c10 + v_bar * j1 * j0,
                          c11 + v_bar * j1 * j1)
    det = c00 * c11 - c01 * c10
    d2 = (nu0 * (c11 * nu0 - c01 * nu1) + nu1 * (c00 * nu1 - c10 * nu0)) / det
    return d2, np.log(det)


def segment_accelerations(ends: list[tuple], scan_times: FloatArray, *, q: float = 0.0
                          ) -> tuple[FloatArray, FloatArray]:
    """Each segment's mean bearing acceleration, rad/s^2: the change of its rate from its first
    to its last state over its span, with that estimate's variance (the two rates' variances
    over the span squared); 0 with variance 0 for a segment spanning fewer than
    :data:`CURVATURE_MIN_SCANS` scans or whose rate change the white-noise acceleration `q`
    (rad^2/s^3) and the rates' variances explain (:data:`CURVATURE_SIGNIFICANCE`)."""
    acc, var = np.zeros(len(ends)), np.zeros(len(ends))
    for i, (s0, x0, p0, s1, x1, p1) in enumerate(ends):
        span = float(scan_times[s1] - scan_times[s0])
        dr = x1[1] - x0[1]
        if span > 0 and s1 - s0 >= CURVATURE_MIN_SCANS and (
                dr * dr > CURVATURE_SIGNIFICANCE * (q * span + p0[1, 1] + p1[1, 1])):
            acc[i] = dr / span
            var[i] = (p0[1, 1] + p1[1, 1]) / span**2
    return acc, var


def _assign(cost: FloatArray) -> dict[int, int]:
    """One assignment of ends (rows) to starts (columns) over the finite costs, the most
    links first, then the cheapest."""
    finite = np.isfinite(cost)
    if not finite.any():
        return {}
    # admissible links cost less than any pair of non-links
    c = np.where(finite, cost - cost[finite].min(), 1e9)
    rr, cc = linear_sum_assignment(c)
    return {int(r): int(s) for r, s in zip(rr, cc, strict=True) if finite[r, s]}


def crossing_clusters(shared_idx: NDArray[np.int64], cands: tuple[tuple[int, ...], ...],
                      scan_of: NDArray[np.int64], margin_scans: int) -> list[NDArray[np.int64]]:
    """Group shared detections: same candidate track and < margin scans apart."""
    if shared_idx.size == 0:
        return []
    parent = np.arange(shared_idx.size)

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    last_seen: dict[int, int] = {}
    for pos, j in enumerate(shared_idx):
        for m in cands[j]:
            if m in last_seen and scan_of[j] - scan_of[shared_idx[last_seen[m]]] <= (
                margin_scans
            ):
                parent[find(pos)] = find(last_seen[m])
            last_seen[m] = pos
    roots = np.array([find(p) for p in range(shared_idx.size)])
    return [shared_idx[roots == r] for r in np.unique(roots)]
