"""Where tentative tracks start, and successors of lost confirmed tracks (issue 20).

A detection that no track takes starts a tentative track when it lies in no track's gate
(:class:`fusion.active.tracker.Tracker`, after Section 2.5 of "Target tracking using fuzzy logic
association"): a detection inside a gate that its track did not take is taken to be that
track's clutter, and a second track on it would be a duplicate. At low ``P_D`` this blocks the
re-acquisition of a target: a confirmed track that has lost its target coasts with a gate that
grows every ping, and the target's own detections that fall in that gate but rank too low for
the coasting track start nothing (the issue-20 breakdown on tuning seeds 1000-1023 at ``P_D``
0.5 and 10 clutter echoes: 8 of 39 uncovered pings after a loss, see RESULTS).

Two options, both off by default:

- ``coast_gate_births`` (:func:`birth_blockers`): only the gates of tentative tracks and of
  confirmed tracks that took a detection of this receiver on the ping block a birth; a coasting
  confirmed track's gate does not.
- ``successor_llr`` (:func:`successor_flags`): a track born inside a coasting confirmed track's
  gate is a *successor*: it starts with this track score instead of 0 and is confirmed with one
  hit fewer. The lost track is prior evidence that a target is there; in the sequential
  likelihood-ratio test the starting score is the log prior odds of a target against clutter,
  which is higher where a target was being tracked than anywhere else in the field.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.active.lifecycle import Lifecycle
from fusion.active.ping_scan import PingScan, birth_states

__all__ = ["birth_blockers", "start_tracks", "successor_flags"]


def birth_blockers(hit: NDArray[np.bool_], confirmed: NDArray[np.bool_], *,
                   coast_gate_births: bool) -> NDArray[np.bool_]:
    """Tracks whose gates keep a free detection from starting a track.

    Parameters
    ----------
    hit : ndarray of bool, shape (t,)
        Tracks that took a detection of this receiver on the ping.
    confirmed : ndarray of bool, shape (t,)
        Tracks confirmed before the ping.
    coast_gate_births : bool
        False: every track; True: all but the confirmed tracks that took nothing (coasting).

    Examples
    --------
    >>> birth_blockers(np.array([True, False, False]), np.array([True, True, False]),
    ...                coast_gate_births=True).tolist()
    [True, False, True]
    """
    if not coast_gate_births:
        return np.ones(hit.shape, dtype=bool)
    return hit | ~confirmed


def successor_flags(gated: NDArray[np.bool_], hit: NDArray[np.bool_],
                    confirmed: NDArray[np.bool_], new: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Which new detections lie in the gate of a coasting confirmed track.

    Parameters
    ----------
    gated : ndarray of bool, shape (t, n)
        Gate of each track over the receiver's detections.
    hit, confirmed : ndarray of bool, shape (t,)
        As in :func:`birth_blockers`.
    new : ndarray of int, shape (k,)
        Detections starting a track.
    """
    coasting = confirmed & ~hit
    if not coasting.any():
        return np.zeros(new.size, dtype=bool)
    return gated[coasting][:, new].any(axis=0)


def start_tracks(tr: Any, scan: PingScan, key: object, idx: NDArray[np.int64],
                 new: NDArray[np.int64], xy: NDArray[np.float64], R: NDArray[np.float64],
                 successor: NDArray[np.bool_]) -> None:
    """Append a tentative track for each detection ``new`` of a receiver's scan (``idx``: the
    scan's detections in the ping; ``xy``, ``R``: their positions and covariances) to the arrays
    of the tracker `tr` (a :class:`fusion.active.tracker.Tracker`, not imported here: the tracker
    imports this module); `successor` marks successors (``tr.successor_llr``). With
    ``tr.birth_evidence`` a track starts at its detection's feature likelihood ratio
    (:meth:`fusion.active.track_score.TrackScorer.birth_delta`)."""
    nt = tr._ids.size
    x_new, P_new = birth_states(xy[new], R[new], speed_sigma_mps=tr.speed_sigma_mps)
    tr._ids = np.concatenate([tr._ids, np.arange(tr._next_id, tr._next_id + new.size)])
    tr._next_id += new.size
    tr._x = np.concatenate([tr._x, x_new])
    tr._P = np.concatenate([tr._P, P_new])
    succ = successor & (tr.successor_llr is not None)
    tr._succ = np.concatenate([tr._succ, succ])
    llr0 = np.where(succ, tr.successor_llr or 0.0, 0.0)
    if tr.scorer is not None and tr.birth_evidence:     # the features' likelihood ratio
        clues = scan.ping.clues
        llr0 = llr0 + tr.scorer.birth_delta(
            new.size, clues["score"][idx[new]] if "score" in clues else None,
            clues["snr_db"][idx[new]] if "snr_db" in clues else None)
    tr._llr = np.concatenate([tr._llr, llr0])
    tr._life += [Lifecycle()] * new.size
    tr._seen += [[scan.rows[j]] for j in idx[new].tolist()]
    if tr.scorer is not None:
        tr.scorer.remember(np.arange(nt, nt + new.size), new, key, xy, new=new.size)
    scan.dets += [[int(j)] for j in idx[new].tolist()]
    scan.rank += [np.nan] * new.size
