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

from fusion.passive.crossing.types import AlertKind, CrossingAlert

__all__ = ["_Events", "_Hits", "raise_alerts"]


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
    #: the interval that confirms (the fits' own where an allowance only widens `low`, `high`)
    conf_low: NDArray[np.float64]
    conf_high: NDArray[np.float64]

    _FIELDS = ("a", "b", "t_cross", "low", "high", "predicted", "window_s", "direction",
               "conf_low", "conf_high")


def raise_alerts(ev: _Events, key: NDArray[np.int64], h: _Hits, t: float, *,
                 merge_window_s: float, split_repeats: bool, revise: bool) -> list:
    """The de-duplication rule of :class:`~fusion.passive.crossing.detector.CrossingDetector`:
    the hits `h` (pair keys `key`) join or open events of `ev` (updated in place); the alerts
    to raise at time `t`, in the order of `h`."""
    pos = np.searchsorted(ev.key, key)
    found = pos < ev.key.size
    found[found] = ev.key[pos[found]] == key[found]
    pf = pos[found]
    same = np.zeros(key.size, bool)
    near = np.abs(h.t_cross[found] - ev.t_cross[pf]) <= merge_window_s
    overlap = (h.low[found] <= ev.high[pf]) & (h.high[found] >= ev.low[pf])  # NaN: False
    same[found] = near | overlap
    if split_repeats:  # a crossing the other way is the pair's next crossing
        same[found] &= h.direction[found] == ev.direction[pf]
    old_pred = np.zeros(key.size, bool)
    old_det = np.zeros(key.size, bool)
    old_pred[found] = ev.predicted[pf]
    old_det[found] = ev.detected[pf]
    old_pred &= same  # a new event starts with no alerts
    old_det &= same
    emit_pred = h.predicted & ~old_pred & ~old_det
    if revise:  # a prediction whose interval left the one said is said again
        said_lo = np.full(key.size, np.nan)
        said_hi = np.full(key.size, np.nan)
        said_lo[found], said_hi[found] = ev.said_low[pf], ev.said_high[pf]
        emit_pred |= h.predicted & old_pred & ~old_det & ((h.low > said_hi) | (h.high < said_lo))
    emit_det = ~h.predicted & ~old_det
    # Existing rows: the event (same or replaced) takes the latest t_c, interval and flags.
    ev.t_cross[pf] = h.t_cross[found]
    ev.low[pf] = h.low[found]
    ev.high[pf] = h.high[found]
    ev.direction[pf] = h.direction[found]
    ev.predicted[pf] = (old_pred | emit_pred)[found]
    ev.detected[pf] = (old_det | emit_det)[found]
    ep = emit_pred[found]
    ev.said_low[pf] = np.where(ep, h.low[found], ev.said_low[pf])
    ev.said_high[pf] = np.where(ep, h.high[found], ev.said_high[pf])
    new = ~found
    if np.any(new):
        ev.append(key=key[new], t_cross=h.t_cross[new], low=h.low[new], high=h.high[new],
                  direction=h.direction[new], predicted=emit_pred[new],
                  detected=emit_det[new], said_low=h.low[new], said_high=h.high[new])
    emit = np.flatnonzero(emit_pred | emit_det)
    kind_of = (AlertKind.PREDICTED, AlertKind.DETECTED)
    out = [
        CrossingAlert(t, ta, tb, tc, kind_of[k], lo, hi, w)
        for ta, tb, tc, k, lo, hi, w in zip(
            h.a[emit].tolist(), h.b[emit].tolist(), h.t_cross[emit].tolist(),
            np.where(emit_pred[emit], 0, 1).tolist(), h.low[emit].tolist(),
            h.high[emit].tolist(), h.window_s[emit].tolist(), strict=True)
    ]
    return out
