"""Data of the track quality indicator: its four states, the per-update memory and the history.

Importable from :mod:`fusion.passive.quality` too, whose component
(:class:`~fusion.passive.quality.TrackQualityIndicator`) produces them.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

__all__ = ["LABELS", "START", "TQIHistory", "TQIMemory", "TrackQuality"]

#: Code of the "previous state" before a tracker's first update (no TQI yet).
START: int = -1


class TrackQuality(IntEnum):
    """The four TQI states, ordered from worst to best; :attr:`label` is the file name."""

    LOST = 0
    UNCERTAIN = 1
    LOW_SNR = 2
    STRONG = 3

    @property
    def label(self) -> str:
        """Name used in files: ``lost``, ``uncertain``, ``low_snr`` or ``strong``."""
        return self.name.lower()

    @classmethod
    def from_label(cls, label: str) -> TrackQuality:
        """The state named `label` in files (``ValueError`` if unknown)."""
        try:
            return cls[label.strip().upper()]
        except KeyError:
            names = ", ".join(s.label for s in cls)
            raise ValueError(f"unknown TQI state {label!r} (expected one of {names})") from None


#: File names indexed by state code.
LABELS: NDArray[np.str_] = np.array([s.label for s in TrackQuality])


@dataclass(frozen=True)
class TQIMemory:
    """What the TQI carries from one update to the next, per tracker.

    Attributes
    ----------
    state : ndarray of int8, shape (n,)
        ``TQI(k)`` codes (:data:`START` before the first update).
    sllr0, sllr1 : ndarray, shape (n,)
        ``SLLR_0(k)``, ``SLLR_1(k)``.
    residual_deg : ndarray, shape (n,)
        Smoothed error residual ``ES(k)``, deg.
    residual_var : ndarray, shape (n,)
        Smoothed squared deviation of the raw residual from ``ES``, deg^2.
    snr : ndarray, shape (n,)
        Smoothed amplitude estimate (linear SNR estimate in the cell).
    err_max_deg : ndarray, shape (n,)
        Residual threshold ``n KE / (2 Omega) + T_err SRESVAR`` of the last update, deg.
    """

    state: NDArray[np.int8]
    sllr0: NDArray[np.float64]
    sllr1: NDArray[np.float64]
    residual_deg: NDArray[np.float64]
    residual_var: NDArray[np.float64]
    snr: NDArray[np.float64]
    err_max_deg: NDArray[np.float64]

    @property
    def n_tracks(self) -> int:
        """Number of trackers."""
        return int(self.state.shape[0])


@dataclass(frozen=True)
class TQIHistory:
    """TQI of many trackers over many updates (rows: updates, columns: trackers).

    Attributes
    ----------
    state : ndarray of int8, shape (n_updates, n_tracks)
        :class:`TrackQuality` codes (:data:`START` where a tracker has not yet been updated).
    sllr0, sllr1 : ndarray, shape (n_updates, n_tracks)
        Summed log likelihood ratios after each update.
    residual_deg : ndarray, shape (n_updates, n_tracks)
        Smoothed error residual ``ES``, deg.
    err_max_deg : ndarray, shape (n_updates, n_tracks)
        Residual threshold in degrees (``|ES|`` above it means uncertain).
    """

    state: NDArray[np.int8]
    sllr0: NDArray[np.float64]
    sllr1: NDArray[np.float64]
    residual_deg: NDArray[np.float64]
    err_max_deg: NDArray[np.float64]

    def labels(self) -> NDArray[np.str_]:
        """State names (``lost`` ...); ``""`` where no state exists yet."""
        out = np.full(self.state.shape, "", dtype=LABELS.dtype)
        ok = self.state >= 0
        out[ok] = LABELS[self.state[ok]]
        return out

    def n_changes(self) -> NDArray[np.int64]:
        """Number of state changes per tracker, shape (n_tracks,)."""
        s = self.state
        return np.sum((s[1:] != s[:-1]) & (s[:-1] >= 0), axis=0)

