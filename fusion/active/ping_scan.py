"""One ping's work state while its receivers are scanned, new tracks, and the ping's result.

The tracker (:mod:`fusion.active.tracker`) scans each receiver's detections of a ping in turn
(Section 2.5, "Tracker", of "Target tracking using fuzzy logic association"); this module holds
what those scans share (:class:`PingScan`), the initial state of a track born from a detection
(:func:`birth_states`) and the assembly of the ping's :class:`~fusion.active.types.PingResult`
once track management is done (:func:`ping_result`), where a track that took several receivers'
detections gets one information-weighted equivalent measurement.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import chain

import numpy as np
from numpy.typing import NDArray

from fusion.active.kalman import fuse_positions
from fusion.active.types import Ping, PingResult

__all__ = ["PingScan", "birth_states", "ping_result", "score_gate"]


@dataclass
class PingScan:
    """Work state of one ping while its receivers are scanned.

    Attributes
    ----------
    ping : Ping
        The ping's detections (after the classifier-score gate).
    Rz : ndarray, shape (n, 2, 2)
        Position covariance of each detection, m^2.
    hot_d : ndarray, shape (n,)
        Distance of each detection to the nearest hotspot region, m (inf without a map).
    confirmed : ndarray of bool, shape (k0,)
        Which tracks alive before the ping were confirmed.
    dets : list of list of int
        Per track, the detections it took on this ping (one per receiver at most).
    rank : list of float
        Per track, the rank of the first detection it took (NaN when none).
    rows : list of list of float
        Per detection, its motion-test row ``time, x, y, R_xx, R_xy, R_yy``.
    """

    ping: Ping
    Rz: NDArray[np.float64]
    hot_d: NDArray[np.float64]
    confirmed: NDArray[np.bool_]
    dets: list[list[int]]
    rank: list[float]
    rows: list[list[float]] = field(default_factory=list)


def score_gate(ping: Ping, threshold: float | None) -> tuple[NDArray[np.int64], Ping]:
    """The detections that pass the classifier-score gate, and their indices in `ping`.

    Parameters
    ----------
    ping : Ping
    threshold : float or None
        Lowest classifier score kept (Section 2.2 of the method text: only detections whose
        score passes a threshold enter the tracker); None, or a ping without a ``score`` clue,
        keeps every detection.

    Returns
    -------
    index : ndarray of int, shape (m,)
        Indices of the kept detections in `ping`.
    ping : Ping
        The ping with only those detections (`ping` itself when all are kept).
    """
    if threshold is None or "score" not in ping.clues or ping.n == 0:
        return np.arange(ping.n), ping
    keep = np.flatnonzero(ping.clues["score"] >= threshold)
    return keep, (ping if keep.size == ping.n else ping.subset(keep))


def birth_states(
    xy: NDArray[np.float64], R: NDArray[np.float64], *, speed_sigma_mps: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Initial states of tracks born from detections.

    Parameters
    ----------
    xy : ndarray, shape (n, 2)
        Birth detections, m.
    R : ndarray, shape (n, 2, 2)
        Their position covariances, m^2.
    speed_sigma_mps : float
        Standard deviation of each velocity component, m/s (zero mean velocity).

    Returns
    -------
    x : ndarray, shape (n, 4)
        ``x, y, vx, vy``.
    P : ndarray, shape (n, 4, 4)
        Block-diagonal covariance: ``R`` and ``speed_sigma_mps**2 I``.
    """
    n = xy.shape[0]
    x = np.zeros((n, 4))
    x[:, :2] = xy
    P = np.zeros((n, 4, 4))
    P[:, :2, :2] = R
    P[:, 2:, 2:] = np.eye(2) * speed_sigma_mps**2
    return x, P


def ping_result(
    scan: PingScan,
    *,
    full_index: NDArray[np.int64],
    track_id: NDArray[np.int64],
    state: NDArray[np.float64],
    covariance: NDArray[np.float64],
    status: NDArray[np.str_],
    hotspots: NDArray[np.float64],
) -> PingResult:
    """The ping's result: tracks, their states and the detections they took.

    Parameters
    ----------
    scan : PingScan
        The ping's work state after all receivers were scanned.
    full_index : ndarray of int, shape (n,)
        Index of each detection of ``scan.ping`` in the ping as given (before the score gate).
    track_id : ndarray of int, shape (k,)
    state : ndarray, shape (k, 4)
        ``x, y, vx, vy`` after the ping, m and m/s.
    covariance : ndarray, shape (k, 4, 4)
    status : ndarray of str, shape (k,)
    hotspots : ndarray, shape (h, 2)
        Hotspot positions after the ping, m.

    Returns
    -------
    PingResult

    Notes
    -----
    A track that took several detections (one per receiver) reports one equivalent measurement,
    their information-weighted fusion ``C = (sum R_i^-1)^-1``, ``z = C sum R_i^-1 z_i``
    (:func:`fusion.active.kalman.fuse_positions`).
    """
    ping, Rz = scan.ping, scan.Rz
    nt = track_id.size
    z = np.full((nt, 2), np.nan)
    Rz_all = np.full((nt, 2, 2), np.nan)
    count = np.fromiter(map(len, scan.dets), np.int64, nt)
    head = np.fromiter((d[0] if d else -1 for d in scan.dets), np.int64, nt)
    one = count == 1
    z[one], Rz_all[one] = ping.xy[head[one]], Rz[head[one]]
    for i in np.flatnonzero(count > 1).tolist():
        d = scan.dets[i]
        z[i], Rz_all[i] = fuse_positions(ping.xy[d], Rz[d])
    flat = full_index[np.fromiter(chain.from_iterable(scan.dets), np.int64, int(count.sum()))]
    ends = np.cumsum(count).tolist()
    first = np.where(head >= 0, full_index[np.maximum(head, 0)] if full_index.size else -1,
                     -1).astype(np.int64)
    return PingResult(
        event=ping.event,
        time=ping.time,
        track_id=track_id.copy(),
        state=state.copy(),
        status=status,
        detection=first,
        rank=np.asarray(scan.rank, dtype=float),
        hotspots=hotspots,
        covariance=covariance.copy(),
        measurement=z,
        measurement_cov=Rz_all,
        detections=tuple(flat[a:b] for a, b in zip([0, *ends][:-1], ends, strict=True)),
    )
