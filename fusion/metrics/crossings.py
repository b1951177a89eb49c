"""Scores of track identities through crossings against simulated truth.

:func:`crossing_outcomes` says, per true crossing, whether the estimated tracks kept, swapped or
lost the two targets' identities (:data:`CROSSING_OUTCOMES`); :func:`identity_swaps` is its swap
column. The crossing detector's alert and interval scores (:func:`score_alerts`,
:func:`score_intervals`, defined in :mod:`fusion.metrics.crossing_alerts`) are listed here too,
so every crossing metric is found in one place.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.metrics.crossing_alerts import (
    CrossingScore,
    IntervalScore,
    score_alerts,
    score_intervals,
)

__all__ = [
    "CROSSING_OUTCOMES",
    "CrossingScore",
    "IntervalScore",
    "FAILURE_CAUSES",
    "crossing_bearing_errors",
    "crossing_failure_causes",
    "crossing_outcomes",
    "crossing_window_identity",
    "identity_swaps",
    "score_alerts",
    "score_intervals",
]

#: What became of two tracks' identities at a true crossing (see :func:`crossing_outcomes`).
CROSSING_OUTCOMES = ("kept", "swap", "lost", "unscored")


def crossing_outcomes(
    true_labels: ArrayLike,
    est_labels: ArrayLike,
    times: ArrayLike,
    crossings: Sequence[tuple[int, int, float]],
    *,
    guard_s: float,
    window_s: float,
    min_fraction: float = 0.5,
) -> NDArray[np.str_]:
    """What became of the two tracks' identities at each true crossing.

    Parameters
    ----------
    true_labels, est_labels : array_like of int, shape (n,)
        True track of each detection (-1 clutter) and the estimated owner (-1 none).
    times : array_like, shape (n,)
        Detection times, s.
    crossings : sequence of (int, int, float)
        True crossings ``(track_a, track_b, t_cross)``.
    guard_s : float
        Half-width of the ambiguous interval around ``t_cross`` that is not scored, s.
    window_s : float
        Length of the scored windows ``[t_c - guard - window, t_c - guard)`` (before) and
        ``(t_c + guard, t_c + guard + window]`` (after), s.
    min_fraction : float, optional
        Share of a true track's detections in a window that one estimated track must own to
        follow it there (default 0.5).

    Returns
    -------
    ndarray of str, shape (n_crossings,)
        Per crossing, with ``f(x, W)`` the estimated track that follows true track ``x`` in
        window ``W`` (the most frequent estimated label of x's detections there, if it owns at
        least `min_fraction` of them):

        - ``"unscored"``: a or b has no detection in one of the windows;
        - ``"lost"``: a or b is followed by no track before or after, or by the same track as
          the other one, or after the crossing by a track that followed neither before
          (fragmented or restarted);
        - ``"swap"``: after the crossing a is followed by b's track from before, or b by a's;
        - ``"kept"``: both followed by their own tracks before and after.

    Examples
    --------
    >>> t = np.repeat(np.arange(10.0), 2)
    >>> true = np.tile([0, 1], 10)
    >>> crossing_outcomes(true, true, t, [(0, 1, 5.0)], guard_s=0.5, window_s=4).tolist()
    ['kept']
    """
    tl, el, t = _labelled(true_labels, est_labels, times)

    def follower(trk: int, sel_t: NDArray[np.bool_]) -> int | None:
        return _follower(tl, el, trk, sel_t, min_fraction)

    out = []
    for a, b, tc in crossings:
        before = _before(t, tc, guard_s, window_s)
        after = (t > tc + guard_s) & (t <= tc + guard_s + window_s)
        fb = [follower(x, before) for x in (a, b)]
        fa = [follower(x, after) for x in (a, b)]
        if None in fb or None in fa:
            out.append("unscored")
        elif -1 in fb or -1 in fa or fb[0] == fb[1] or fa[0] == fa[1]:
            out.append("lost")
        elif fa[0] == fb[1] or fa[1] == fb[0]:
            out.append("swap")
        elif fa != fb:
            out.append("lost")
        else:
            out.append("kept")
    return np.array(out, dtype="<U8")


def _labelled(true_labels: ArrayLike, est_labels: ArrayLike, times: ArrayLike
              ) -> tuple[NDArray, NDArray, NDArray[np.float64]]:
    """The true and estimated labels and times of the detections, checked 1-D of equal length."""
    tl = np.asarray(true_labels)
    el = np.asarray(est_labels)
    t = np.asarray(times, float)
    if not (tl.shape == el.shape == t.shape and tl.ndim == 1):
        raise ValueError("true_labels, est_labels and times must be 1-D of equal length")
    return tl, el, t


def _before(t: NDArray[np.float64], tc: float, guard_s: float, window_s: float
            ) -> NDArray[np.bool_]:
    """The scored window before a crossing at `tc`: ``[t_c - guard - window, t_c - guard)``."""
    return (t >= tc - guard_s - window_s) & (t < tc - guard_s)


def _follower(tl: NDArray, el: NDArray, trk: int, sel_t: NDArray[np.bool_],
              min_fraction: float) -> int | None:
    """The estimated track owning at least `min_fraction` of true track `trk`'s detections
    in `sel_t` (-1 none; None: no detection there)."""
    sel = (tl == trk) & sel_t
    n = int(sel.sum())
    if n == 0:
        return None
    lab = el[sel]
    lab = lab[lab >= 0]
    if lab.size == 0:
        return -1
    u, c = np.unique(lab, return_counts=True)
    i = int(np.argmax(c))
    return int(u[i]) if c[i] >= min_fraction * n else -1


def crossing_window_identity(
    true_labels: ArrayLike,
    est_labels: ArrayLike,
    times: ArrayLike,
    crossings: Sequence[tuple[int, int, float]],
    *,
    guard_s: float,
    window_s: float,
    min_fraction: float = 0.5,
) -> NDArray[np.int64]:
    """Identity per detection inside the crossing window, where :func:`crossing_outcomes`
    does not look.

    For each true crossing ``(a, b, t_c)`` and each detection of a or b with
    ``|t - t_c| <= guard_s``: is its estimated label the track that followed its true track in
    the window before the guard (``[t_c - guard - window, t_c - guard)``, majority owner as in
    :func:`crossing_outcomes`)?

    Returns
    -------
    ndarray of int, shape (n_crossings, 2)
        Per crossing: detections of a and b inside ``+-guard_s``, and of those the ones labelled
        with their true track's follower (a true track followed by no track before counts all
        its detections as wrong).

    Examples
    --------
    >>> t = np.repeat(np.arange(10.0), 2)
    >>> true = np.tile([0, 1], 10)
    >>> est = true.copy(); est[10] = 1  # at t = 5 track 0's detection went to track 1
    >>> crossing_window_identity(true, est, t, [(0, 1, 5.0)], guard_s=1, window_s=4).tolist()
    [[6, 5]]
    """
    tl, el, t = _labelled(true_labels, est_labels, times)
    out = np.zeros((len(crossings), 2), np.int64)
    for i, (a, b, tc) in enumerate(crossings):
        before = _before(t, tc, guard_s, window_s)
        inside = np.abs(t - tc) <= guard_s
        for x in (a, b):
            f = _follower(tl, el, x, before, min_fraction)
            sel = inside & (tl == x)
            out[i, 0] += int(sel.sum())
            if f is not None and f >= 0:
                out[i, 1] += int(np.sum(el[sel] == f))
    return out


def crossing_bearing_errors(
    true_labels: ArrayLike,
    est_labels: ArrayLike,
    times: ArrayLike,
    crossings: Sequence[tuple[int, int, float]],
    tracks: Mapping[int, tuple[ArrayLike, ArrayLike]],
    truth_time: ArrayLike,
    truth_bearing: Mapping[int, ArrayLike],
    *,
    within_s: float,
    guard_s: float,
    window_s: float,
    min_fraction: float = 0.5,
) -> NDArray[np.float64]:
    """Bearing errors of the tracks that follow two crossing targets, near the crossing.

    For each true crossing ``(a, b, t_c)`` and each of a, b: the estimated track that followed
    it before the crossing (majority owner in ``[t_c - guard - window, t_c - guard)``) is
    interpolated (on the circle) at the truth times within ``+-within_s`` of ``t_c`` that it
    spans, and compared with the true bearing there. A target followed by no track, and truth
    times outside its track's span, give NaN (not covered).

    Parameters
    ----------
    tracks : mapping of int to (times, bearings)
        Estimated track id to its smoothed states, s and rad.
    truth_time : array_like, shape (n_t,)
        Times of the true bearings, s.
    truth_bearing : mapping of int to array_like, shape (n_t,)
        True track id to its bearings at `truth_time`, rad.
    within_s : float
        Half-width of the scored interval around each crossing, s.

    Returns
    -------
    ndarray, shape (n_samples,)
        Wrapped errors, rad (NaN where not covered), all crossings and both targets in turn.
    """
    tl, el, t = _labelled(true_labels, est_labels, times)
    tt = np.asarray(truth_time, float)
    errs: list[NDArray[np.float64]] = []
    for a, b, tc in crossings:
        before = _before(t, tc, guard_s, window_s)
        near = np.abs(tt - tc) <= within_s
        for x in (a, b):
            truth = np.asarray(truth_bearing[x], float)[near]
            f = _follower(tl, el, x, before, min_fraction)
            e = np.full(truth.size, np.nan)
            if f is not None and f >= 0 and f in tracks:
                ts, bs = (np.asarray(v, float) for v in tracks[f])
                tq = tt[near]
                ok = (tq >= ts[0]) & (tq <= ts[-1])
                est = np.angle(np.interp(tq[ok], ts, np.cos(bs))
                               + 1j * np.interp(tq[ok], ts, np.sin(bs)))
                e[ok] = np.angle(np.exp(1j * (est - truth[ok])))
            errs.append(e)
    return np.concatenate(errs) if errs else np.zeros(0)


def identity_swaps(
    true_labels: ArrayLike,
    est_labels: ArrayLike,
    times: ArrayLike,
    crossings: Sequence[tuple[int, int, float]],
    *,
    guard_s: float,
    window_s: float,
) -> NDArray[np.bool_]:
    """Which true crossings exchanged the two tracks' identities.

    ``crossing_outcomes(...) == "swap"``; lost or fragmented tracks are not swaps (see
    :func:`crossing_outcomes`).

    Returns
    -------
    ndarray of bool, shape (n_crossings,)
    """
    return crossing_outcomes(true_labels, est_labels, times, crossings, guard_s=guard_s,
                             window_s=window_s) == "swap"


#: Causes of a crossing not kept (see :func:`crossing_failure_causes`).
FAILURE_CAUSES = ("slow swap", "swap", "late start", "merge", "third-target swap",
                  "fragmentation", "clutter capture", "dropped")


def crossing_failure_causes(
    true_labels: ArrayLike,
    est_labels: ArrayLike,
    times: ArrayLike,
    crossings: Sequence[tuple[int, int, float]],
    rate_diff_deg_per_min: Sequence[float],
    *,
    guard_s: float,
    window_s: float,
    slow_deg_per_min: float = 6.0,
    min_fraction: float = 0.5,
) -> list[str]:
    """Why each true crossing was not kept ("" for kept and unscored ones).

    With ``f(x, W)`` as in :func:`crossing_outcomes` (before / after windows):

    - ``"slow swap"`` / ``"swap"``: swapped, the targets' bearing rates differing by less /
      more than `slow_deg_per_min` at the crossing (`rate_diff_deg_per_min`, one per crossing);
    - ``"late start"``: a target followed by no track before the crossing;
    - ``"merge"``: one track follows both targets before or after;
    - ``"third-target swap"``: after the crossing a target is followed by the track that
      followed a third target before (identity exchanged with a target not in this crossing);
    - ``"fragmentation"``: after the crossing a target is followed by a track that followed
      no target before (a track ended and a new one began);
    - ``"clutter capture"``: a target followed by no track after, its former track still
      alive there but owning mostly clutter or the other target's detections;
    - ``"dropped"``: a target followed by no track after and its former track gone.
    """
    tl, el, t = _labelled(true_labels, est_labels, times)
    outcomes = crossing_outcomes(tl, el, t, crossings, guard_s=guard_s, window_s=window_s,
                                 min_fraction=min_fraction)
    out = []
    for (a, b, tc), o, rd in zip(crossings, outcomes, rate_diff_deg_per_min, strict=True):
        if o in ("kept", "unscored"):
            out.append("")
            continue
        if o == "swap":
            out.append("slow swap" if abs(rd) < slow_deg_per_min else "swap")
            continue
        before = _before(t, tc, guard_s, window_s)
        after = (t > tc + guard_s) & (t <= tc + guard_s + window_s)
        fb = [_follower(tl, el, x, before, min_fraction) for x in (a, b)]
        fa = [_follower(tl, el, x, after, min_fraction) for x in (a, b)]
        if -1 in fb:
            out.append("late start")
        elif fb[0] == fb[1] or fa[0] == fa[1]:
            out.append("merge")
        elif any(f >= 0 and f not in fb for f in fa):
            others = {_follower(tl, el, int(c), before, min_fraction)
                      for c in np.unique(tl[before & (tl >= 0)]) if c not in (a, b)}
            new = [f for f in fa if f >= 0 and f not in fb]
            out.append("third-target swap" if all(f in others for f in new)
                       else "fragmentation")
        else:
            x = fa.index(-1)
            owned = after & (el == fb[x])
            others = owned & (tl != (a, b)[x])
            out.append("clutter capture" if owned.any() and others.sum() * 2 >= owned.sum()
                       else "dropped")
    return out
