"""Multistatic tracker output scored against the simulated target: coverage, false tracks,
identity switches (the scenarios of :mod:`fusion.simulate.multistatic`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fusion.types import Table

__all__ = ["TrackScore", "identity_switches", "score_tracks"]


@dataclass(frozen=True)
class TrackScore:
    """How well confirmed tracks follow a known target.

    Attributes
    ----------
    coverage : float
        Fraction of the pings after the third (index >= 3) on which a confirmed track lies
        within ``match_m`` of the target.
    false_tracks : int
        Confirmed tracks that are within ``match_m`` of the target on fewer than half of their
        confirmed pings.
    confirmed_tracks : int
        All tracks confirmed at some ping.
    identity_switches : int
        Times the confirmed track following the target changed identity
        (:func:`identity_switches`).
    """

    coverage: float
    false_tracks: int
    confirmed_tracks: int
    identity_switches: int = 0


def identity_switches(track_ids: list[np.ndarray], distances: list[np.ndarray]) -> int:
    """Identity switches on one target over a run.

    Parameters
    ----------
    track_ids : list of ndarray of int
        Per ping, the confirmed tracks within the match distance of the target.
    distances : list of ndarray
        Per ping, their distances to the target, m.

    Returns
    -------
    int
        The track following the target keeps its identity while it stays within the match
        distance; when it does not, the nearest matching track takes over, and a switch is
        counted when that track differs from the last one that followed the target (pings with
        no matching track do not reset it, as in the CLEAR-MOT identity-switch count).

    Examples
    --------
    >>> identity_switches([np.array([1]), np.array([]), np.array([2, 1]), np.array([2])],
    ...                   [np.array([10.0]), np.array([]), np.array([5.0, 20.0]), np.array([1.0])])
    1
    """
    current = None
    switches = 0
    for ids, d in zip(track_ids, distances, strict=True):
        ids = np.asarray(ids)
        if ids.size == 0 or (current is not None and current in ids):
            continue
        new = int(ids[int(np.argmin(d))])
        if current is not None and new != current:
            switches += 1
        current = new
    return switches


def score_tracks(columns: dict, truth: Table, *, match_m: float = 500.0) -> TrackScore:
    """Score tracker output (``TrackingResult.columns()``) against the target truth.

    Parameters
    ----------
    columns : dict of str to ndarray
        ``track_id, event, x, y, status`` rows.
    truth : Table
        ``event, x, y`` of the target at every ping (events consecutive).
    match_m : float, optional
        Distance within which a track is on the target, m (default 500: about the 99 % gate
        radius of a track with 100-m position errors after a ping of prediction).

    Returns
    -------
    TrackScore
    """
    ev0 = int(truth["event"][0])
    conf = columns["status"] == "confirmed"
    k = np.asarray(columns["event"]) - ev0
    inside = (k >= 0) & (k < len(truth))
    kk = np.clip(k, 0, len(truth) - 1)
    d = np.where(inside, np.hypot(columns["x"] - truth["x"][kk], columns["y"] - truth["y"][kk]),
                 np.inf)
    on = conf & (d <= match_m)
    covered = np.zeros(len(truth), dtype=bool)
    covered[k[on]] = True
    ids = np.unique(columns["track_id"][conf])
    false = sum(np.mean(d[conf & (columns["track_id"] == t)] <= match_m) < 0.5 for t in ids)
    tid = np.asarray(columns["track_id"])
    per_ping = [np.flatnonzero(on & (k == i)) for i in range(len(truth))]
    switches = identity_switches([tid[r] for r in per_ping], [d[r] for r in per_ping])
    return TrackScore(float(covered[3:].mean()) if len(truth) > 3 else float("nan"),
                      int(false), int(ids.size), int(switches))
