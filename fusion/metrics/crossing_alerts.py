"""Crossing alerts scored against true crossings (tests, examples and benchmarks).

:func:`score_alerts` is the method-level score (an alert belongs to the pair's true crossing
nearest its ``t_cross`` within ``J K``); :func:`score_intervals` scores alerts that carry a
confidence interval of the crossing time: an alert is true when a crossing of its pair lies in
its interval widened by one sample period, and the intervals' coverage is counted.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.passive.crossing.types import AlertKind, CrossingAlert

__all__ = ["CrossingScore", "IntervalScore", "score_alerts", "score_intervals"]


@dataclass(frozen=True)
class CrossingScore:
    """Alerts scored against true crossings.

    Attributes
    ----------
    n_crossings : int
        True crossings scored (those with enough data before and after, see
        :func:`score_alerts`).
    n_predicted_ahead : int
        Of those, crossings with a matching ``predicted`` alert raised at least one sample
        period K before the true crossing time.
    n_detected : int
        Crossings with a matching ``detected`` alert raised no later than ``J K`` after it.
    detection_delay_s : ndarray, shape (n_detected,)
        Alert time minus true crossing time of each detected crossing, s.
    n_non_crossing_pairs : int
        Pairs that never cross.
    n_false_pairs : int
        Of those, pairs with at least one alert.
    n_spurious_alerts : int
        Alerts on crossing pairs that match none of the pair's true crossings.
    """

    n_crossings: int
    n_predicted_ahead: int
    n_detected: int
    detection_delay_s: NDArray[np.float64]
    n_non_crossing_pairs: int
    n_false_pairs: int
    n_spurious_alerts: int

    @property
    def predicted_fraction(self) -> float:
        """Fraction of scored crossings predicted at least K ahead (NaN if none scored)."""
        return self.n_predicted_ahead / self.n_crossings if self.n_crossings else float("nan")

    @property
    def detected_fraction(self) -> float:
        """Fraction of scored crossings detected within J K (NaN if none scored)."""
        return self.n_detected / self.n_crossings if self.n_crossings else float("nan")

    @property
    def false_pair_fraction(self) -> float:
        """Fraction of never-crossing pairs with an alert (NaN if there are none)."""
        if not self.n_non_crossing_pairs:
            return float("nan")
        return self.n_false_pairs / self.n_non_crossing_pairs


def score_alerts(
    alerts: list[CrossingAlert],
    crossings: list[tuple[int, int, float]],
    non_crossing_pairs: list[tuple[int, int]],
    *,
    J: int,
    K: float,
    t_start: float,
    t_end: float,
    match_tol_s: float | None = None,
) -> CrossingScore:
    """Score alerts against true crossings.

    Parameters
    ----------
    alerts : list of CrossingAlert
        Output of the detector.
    crossings : list of (int, int, float)
        True crossings ``(track_a, track_b, t_cross)``, ``track_a < track_b``.
    non_crossing_pairs : list of (int, int)
        Pairs that never cross.
    J : int
        Samples per window.
    K : float
        Sample period, s.
    t_start, t_end : float
        First and last sample time, s.
    match_tol_s : float, optional
        An alert belongs to the pair's true crossing nearest its ``t_cross`` if within this
        (default ``J K``).

    Returns
    -------
    CrossingScore

    Notes
    -----
    A crossing is scored when ``t_start + (J + 1) K <= t_c <= t_end - J K``: a full window
    exists one sample before it and a full window of samples follows it.
    """
    tol = J * K if match_tol_s is None else float(match_tol_s)
    by_pair: dict[tuple[int, int], list[float]] = {}
    for a, b, tc in crossings:
        by_pair.setdefault((min(a, b), max(a, b)), []).append(float(tc))
    pred_time: dict[tuple[int, int, int], float] = {}
    det_time: dict[tuple[int, int, int], float] = {}
    spurious = 0
    alerted_pairs = set()
    for al in alerts:
        key = (al.track_a, al.track_b)
        alerted_pairs.add(key)
        tcs = by_pair.get(key)
        if not tcs:
            continue
        j = int(np.argmin([abs(al.t_cross - tc) for tc in tcs]))
        if abs(al.t_cross - tcs[j]) > tol:
            spurious += 1
            continue
        slot = pred_time if al.kind == AlertKind.PREDICTED else det_time
        k3 = (key[0], key[1], j)
        slot[k3] = min(slot.get(k3, np.inf), al.time)
    n = n_pred = n_det = 0
    delays = []
    for key, tcs in by_pair.items():
        for j, tc in enumerate(tcs):
            if not (t_start + (J + 1) * K <= tc <= t_end - J * K):
                continue
            n += 1
            if pred_time.get((*key, j), np.inf) <= tc - K:
                n_pred += 1
            dt = det_time.get((*key, j), np.inf)
            if dt <= tc + J * K:
                n_det += 1
                delays.append(dt - tc)
    ncp = {(min(a, b), max(a, b)) for a, b in non_crossing_pairs}
    return CrossingScore(
        n_crossings=n,
        n_predicted_ahead=n_pred,
        n_detected=n_det,
        detection_delay_s=np.array(delays, dtype=float),
        n_non_crossing_pairs=len(ncp),
        n_false_pairs=len(ncp & alerted_pairs),
        n_spurious_alerts=spurious,
    )


@dataclass(frozen=True)
class IntervalScore:
    """Alerts with crossing-time intervals scored against true crossings.

    Attributes
    ----------
    n_crossings : int
        True crossings scored (those marked eligible).
    n_predicted : int
        Of those, crossings with a true ``predicted`` alert raised at least `lead_min_s` before.
    n_detected : int
        Crossings with a true ``detected`` alert.
    n_alerts : int
        All alerts.
    n_false : int
        Alerts that are true for no crossing of their pair (any crossing, scored or not).
    n_on_crossing_pairs : int
        Alerts of pairs that cross at least once.
    n_covered : int
        Of those, alerts whose interval contains a crossing of their pair.
    lead_s : ndarray, shape (n_predicted,)
        True crossing time minus the time of its first true prediction, s.
    error_s : ndarray, shape (n_predicted,)
        ``t_cross`` of that prediction minus the true crossing time, s.
    """

    n_crossings: int
    n_predicted: int
    n_detected: int
    n_alerts: int
    n_false: int
    n_on_crossing_pairs: int
    n_covered: int
    lead_s: NDArray[np.float64]
    error_s: NDArray[np.float64]

    @property
    def predicted_fraction(self) -> float:
        """Fraction of scored crossings predicted ahead (NaN if none scored)."""
        return self.n_predicted / self.n_crossings if self.n_crossings else float("nan")

    @property
    def false_per_crossing(self) -> float:
        """False alerts per scored crossing (NaN if none scored)."""
        return self.n_false / self.n_crossings if self.n_crossings else float("nan")

    @property
    def coverage(self) -> float:
        """Fraction of alerts on crossing pairs whose interval holds a crossing (NaN if none)."""
        if not self.n_on_crossing_pairs:
            return float("nan")
        return self.n_covered / self.n_on_crossing_pairs


def score_intervals(
    alerts: Sequence[CrossingAlert],
    crossings: Sequence[tuple[int, int, float]],
    *,
    eligible: Sequence[bool] | None = None,
    tol_s: float = 0.0,
    lead_min_s: float = 0.0,
) -> IntervalScore:
    """Score alerts carrying crossing-time intervals against true crossings.

    Parameters
    ----------
    alerts : sequence of CrossingAlert
        Alerts; one without an interval (NaN bounds) stands for the point ``t_cross``.
    crossings : sequence of (int, int, float)
        Every true crossing ``(track_a, track_b, t_cross)``, ``track_a < track_b``.
    eligible : sequence of bool, optional
        Which crossings are scored (default all); the others still make their alerts true.
    tol_s : float, optional
        An alert is true for a crossing of its pair inside
        ``[t_cross_low - tol_s, t_cross_high + tol_s]`` (one sample period is fair: the
        alerts are raised on the sample grid).
    lead_min_s : float, optional
        A crossing counts as predicted when a true ``predicted`` alert is raised at least this
        long before it (strictly before when 0).

    Returns
    -------
    IntervalScore
    """
    by_pair: dict[tuple[int, int], list[int]] = {}
    for j, c in enumerate(crossings):
        by_pair.setdefault((min(c[0], c[1]), max(c[0], c[1])), []).append(j)
    ok = [True] * len(crossings) if eligible is None else [bool(e) for e in eligible]
    if len(ok) != len(crossings):
        raise ValueError("eligible must have one entry per crossing")
    first_pred: dict[int, CrossingAlert] = {}
    detected: set[int] = set()
    n_false = n_on = n_cov = 0
    for al in alerts:
        lo, hi = al.t_cross_low, al.t_cross_high
        if not (np.isfinite(lo) and np.isfinite(hi)):
            lo = hi = al.t_cross
        idx = by_pair.get((al.track_a, al.track_b), [])
        if idx:
            n_on += 1
        tcs = np.array([crossings[j][2] for j in idx])
        n_cov += int(np.any((tcs >= lo) & (tcs <= hi)))
        inside = (tcs >= lo - tol_s) & (tcs <= hi + tol_s)
        if not np.any(inside):
            n_false += 1
            continue
        # the crossing nearest the alert's t_cross among those its interval holds
        j = idx[int(np.flatnonzero(inside)[np.argmin(np.abs(tcs[inside] - al.t_cross))])]
        if al.kind == AlertKind.PREDICTED:
            if j not in first_pred or al.time < first_pred[j].time:
                first_pred[j] = al
        else:
            detected.add(j)
    n = n_pred = n_det = 0
    lead, err = [], []
    for j, c in enumerate(crossings):
        if not ok[j]:
            continue
        n += 1
        n_det += int(j in detected)
        al = first_pred.get(j)
        if al is not None and (c[2] - al.time >= lead_min_s if lead_min_s > 0 else al.time < c[2]):
            n_pred += 1
            lead.append(c[2] - al.time)
            err.append(al.t_cross - c[2])
    return IntervalScore(
        n_crossings=n, n_predicted=n_pred, n_detected=n_det, n_alerts=len(alerts),
        n_false=n_false, n_on_crossing_pairs=n_on, n_covered=n_cov,
        lead_s=np.array(lead, dtype=float), error_s=np.array(err, dtype=float),
    )
