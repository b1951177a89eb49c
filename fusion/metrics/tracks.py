"""Scores of passive bearing tracks against a simulated scenario's truth.

Tracks are given as plain arrays (:class:`ScoredTrack`), so the passive pipeline's tracks and any
other tracker's are scored the same way. A track *follows* a target at a scan when, among the live
tracks of the target's bin, it is the nearest to the target's true bearing and within a gate;
identities through crossings are then judged by :func:`fusion.metrics.crossings.crossing_outcomes`
on those per-scan labels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.metrics.crossings import crossing_outcomes
from fusion.simulate.passive import PassiveScenario

__all__ = ["PassiveScore", "ScoredTrack", "score_tracks"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ScoredTrack:
    """One track to score.

    Attributes
    ----------
    target : int
        Target the track was started on (its click).
    time : ndarray, shape (n,)
        State times, s.
    bearing_deg : ndarray, shape (n,)
        Bearings, deg.
    end_s : float
        Time the track was ended (``inf``: never).
    """

    target: int
    time: FloatArray
    bearing_deg: FloatArray
    end_s: float = float("inf")


@dataclass(frozen=True)
class PassiveScore:
    """Tracks scored against truth.

    Attributes
    ----------
    outcomes : ndarray of str, shape (n_crossings,)
        ``kept``, ``swap``, ``lost`` or ``unscored`` per true crossing.
    rmse_deg : float
        RMS bearing error of every track against its own target over the scans where that target
        is present and above 0 dB per bin, deg.
    lost_delay_s : ndarray, shape (n_fading,)
        Per fading target, its track's end minus the time the target fell below 0 dB per bin, s
        (``inf`` if the track never ended).
    n_early_ends : int
        Tracks ended while their target was still above 0 dB per bin.
    """

    outcomes: NDArray[np.str_]
    rmse_deg: float
    lost_delay_s: FloatArray
    n_early_ends: int

    @property
    def n_swaps(self) -> int:
        """Crossings that exchanged identities."""
        return int(np.sum(self.outcomes == "swap"))

    @property
    def n_scored(self) -> int:
        """Crossings scored (kept, swap or lost)."""
        return int(np.sum(self.outcomes != "unscored"))


def score_tracks(
    tracks: Sequence[ScoredTrack],
    scenario: PassiveScenario,
    *,
    gate_deg: float = 3.0,
    guard_s: float = 25.0,
    window_s: float = 40.0,
) -> PassiveScore:
    """Score tracks against the scenario's truth.

    Parameters
    ----------
    tracks : sequence of ScoredTrack
        The tracks.
    scenario : PassiveScenario
        The simulated scenario.
    gate_deg : float
        Largest bearing error at which a track follows a target, deg.
    guard_s, window_s : float
        Crossing scoring: the ambiguous half-width around each true crossing left out, and the
        windows before and after it that are scored (:func:`fusion.metrics.crossings.
        crossing_outcomes`), s.

    Returns
    -------
    PassiveScore
    """
    t_all = scenario.time
    n_scans, n_targets = scenario.bearing_deg.shape
    audible = scenario.snr_db > 0.0  # (n_scans, n_targets)
    # per scan and target: the nearest track of the target's bin within the gate
    follow = np.full((n_scans, n_targets), -1, np.int64)
    best = np.full((n_scans, n_targets), np.inf)
    errs: list[FloatArray] = []
    for j, tr in enumerate(tracks):
        k = np.searchsorted(t_all, tr.time)
        ok = (k < n_scans) & np.isclose(t_all[np.minimum(k, n_scans - 1)], tr.time)
        k = k[ok]
        b = np.asarray(tr.bearing_deg, float)[ok]
        own = audible[k, tr.target]
        errs.append(b[own] - scenario.bearing_deg[k[own], tr.target])
        same = np.flatnonzero(scenario.bins == scenario.bins[tr.target])
        for i in same:
            d = np.abs(b - scenario.bearing_deg[k, i])
            hit = audible[k, i] & (d <= gate_deg) & (d < best[k, i])
            follow[k[hit], i] = j
            best[k[hit], i] = d[hit]
    # one pseudo-detection per audible target and scan, labelled by target and follower
    kk, ii = np.nonzero(audible)
    outcomes = crossing_outcomes(ii, follow[kk, ii], t_all[kk], list(scenario.crossings),
                                 guard_s=guard_s, window_s=window_s)
    e = np.concatenate(errs) if errs else np.zeros(0)
    delays = []
    early = 0
    for tr in tracks:
        gone = float(scenario.gone_s[tr.target])
        if np.isfinite(gone):
            delays.append(tr.end_s - gone)
        if np.isfinite(tr.end_s) and tr.end_s < gone:
            early += 1
    return PassiveScore(
        outcomes=outcomes,
        rmse_deg=float(np.sqrt(np.mean(e**2))) if e.size else float("nan"),
        lost_delay_s=np.array(delays, dtype=float),
        n_early_ends=early,
    )
