"""Data types of crossing prediction/detection: alert kinds, alerts and per-sample pair checks.

Shared by the detector (:mod:`fusion.passive.crossing`), the pair evaluation
(:mod:`fusion.passive.crossing.pairs`) and the scoring (:mod:`fusion.metrics.crossing_alerts`).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

__all__ = ["AlertKind", "CrossingAlert", "PairCheck"]


class AlertKind(StrEnum):
    """Kind of crossing alert: ``predicted`` (inequality 3) or ``detected`` (inequality 4)."""

    PREDICTED = "predicted"
    DETECTED = "detected"


@dataclass(frozen=True, slots=True)
class CrossingAlert:
    """An alert that two bearing tracks will cross or have crossed.

    Attributes
    ----------
    time : float
        Time of the sample at which the inequality held, s.
    track_a, track_b : int
        The two tracks, ``track_a < track_b``.
    t_cross : float
        Crossing time from equation (2), s (same clock as `time`).
    kind : AlertKind
        ``predicted`` (crossing ahead, inequality 3) or ``detected`` (crossing behind,
        inequality 4).
    t_cross_low, t_cross_high : float
        Confidence interval of the crossing time from the covariance of the two window fits
        (Fieller's interval, see :func:`fusion.passive.crossing.pairs.crossing_time_interval`),
        s; NaN when the detector computes no interval.
    window_s : float
        Span of the least-squares windows the alert comes from, s (NaN if not recorded).
    """

    time: float
    track_a: int
    track_b: int
    t_cross: float
    kind: AlertKind
    t_cross_low: float = float("nan")
    t_cross_high: float = float("nan")
    window_s: float = float("nan")


@dataclass(frozen=True)
class PairCheck:
    """Pairs that satisfy inequality (3) or (4) at one sample.

    Attributes
    ----------
    index_a, index_b : ndarray of int64, shape (p,)
        Positions of the two tracks in the arrays given to
        :func:`~fusion.passive.crossing.pairs.evaluate_pairs`, ``index_a < index_b``.
    t_cross : ndarray, shape (p,)
        Crossing times from equation (2), s.
    predicted : ndarray of bool, shape (p,)
        True where inequality (3) holds, False where inequality (4) holds.
    t_cross_low, t_cross_high : ndarray, shape (p,) or None
        Confidence interval of each crossing time, s (``-inf``/``inf`` where the rate
        difference is not resolved); None when no covariance was given.
    """

    index_a: NDArray[np.int64]
    index_b: NDArray[np.int64]
    t_cross: NDArray[np.float64]
    predicted: NDArray[np.bool_]
    t_cross_low: NDArray[np.float64] | None = None
    t_cross_high: NDArray[np.float64] | None = None
