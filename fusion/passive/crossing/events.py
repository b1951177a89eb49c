"""Crossing events and per-sample hits of the streaming detector (internal records).

:class:`_Events` holds each pair's open crossing event (latest crossing time, interval,
direction, which alerts it raised and the interval of its latest prediction); :class:`_Hits`
the pairs that satisfied an inequality at one sample. Used by
:class:`~fusion.passive.crossing.detector.CrossingDetector` only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["_Events", "_Hits"]


@dataclass
class _Events:
    """Open crossing events, one row per pair, sorted by pair key (internal, mutable).

    ``key = slot_a * 2**32 + slot_b`` with the tracks' storage slots; ``t_cross``, ``low``,
    ``high`` are the latest crossing time and interval seen for the event; ``direction`` is the
    sign of the bearing difference's rate at the crossing (successive crossings of a pair
    alternate it); ``predicted`` and ``detected`` say which alerts the event has raised;
    ``said_low``, ``said_high`` are the interval of its latest ``predicted`` alert.
    """

    key: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    t_cross: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    low: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    high: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    direction: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    predicted: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))
    detected: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))
    said_low: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    said_high: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    _COLUMNS = ("key", "t_cross", "low", "high", "direction", "predicted", "detected",
                "said_low", "said_high")

    def keep(self, index: NDArray) -> None:
        for name in self._COLUMNS:
            setattr(self, name, getattr(self, name)[index])

    def append(self, **cols: NDArray) -> None:
        for name in self._COLUMNS:
            setattr(self, name, np.concatenate([getattr(self, name), cols[name]]))
        self.keep(np.argsort(self.key, kind="stable"))


@dataclass(frozen=True)
class _Hits:
    """Pairs that satisfied an inequality at one sample, with their intervals (internal)."""

    a: NDArray[np.int64]
    b: NDArray[np.int64]
    t_cross: NDArray[np.float64]
    low: NDArray[np.float64]
    high: NDArray[np.float64]
    predicted: NDArray[np.bool_]
    window_s: NDArray[np.float64]
    direction: NDArray[np.float64]

    _FIELDS = ("a", "b", "t_cross", "low", "high", "predicted", "window_s", "direction")
