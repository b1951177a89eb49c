"""Data of the bearing-rate smoothers: a track prior, smoothed tracks, tracker and multi-track results.

Frozen dataclasses with documented fields; the smoothers of this package take and return them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import check_radians

__all__ = ["MultiTrackResult", "SmoothedTrack", "TrackPrior", "TrackerResult"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TrackPrior:
    """Gaussian prior on a track's first state (e.g. from acquisition).

    Attributes
    ----------
    bearing : float
        Bearing, rad (``|bearing| > 2 pi``, degrees, is refused).
    rate : float
        Bearing rate, rad/s.
    sigma_bearing : float
        Standard deviation of `bearing`, rad (> 0).
    sigma_rate : float
        Standard deviation of `rate`, rad/s (> 0).
    """

    bearing: float
    rate: float
    sigma_bearing: float
    sigma_rate: float

    def __post_init__(self) -> None:
        for name in ("bearing", "rate"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"prior {name} must be finite")
        check_radians(self.bearing, "prior bearing")
        for name in ("sigma_bearing", "sigma_rate"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"prior {name} must be finite and > 0, got {v!r}")

    @property
    def mean(self) -> FloatArray:
        """``[bearing, rate]``, shape (2,)."""
        return np.array([self.bearing, self.rate])

    @property
    def covariance(self) -> FloatArray:
        """Diagonal covariance, shape (2, 2)."""
        return np.diag([self.sigma_bearing**2, self.sigma_rate**2])


@dataclass(frozen=True)
class SmoothedTrack:
    """A smoothed bearing track.

    Attributes
    ----------
    track_id : int
        Track identifier.
    times : ndarray, shape (n,)
        State times, s, increasing.
    bearing : ndarray, shape (n,)
        Smoothed bearing, rad, wrapped to [-pi, pi).
    rate : ndarray, shape (n,)
        Smoothed bearing rate, rad/s.
    sigma_bearing : ndarray, shape (n,)
        Marginal standard deviation of the bearing, rad.
    sigma_rate : ndarray, shape (n,)
        Marginal standard deviation of the rate, rad/s.
    """

    track_id: int
    times: FloatArray
    bearing: FloatArray
    rate: FloatArray
    sigma_bearing: FloatArray
    sigma_rate: FloatArray

    def __len__(self) -> int:
        return int(self.times.shape[0])


@dataclass(frozen=True)
class TrackerResult:
    """Output of :class:`NearestNeighbourTracker`.

    Attributes
    ----------
    labels : ndarray of int, shape (n_detections,)
        Track index of each detection (in input order), ``-1`` for none (clutter, tentative or
        shared).
    candidates : tuple of tuple of int, length n_detections
        For a detection inside a crossing region, the tracks that may own it (two or more);
        empty otherwise.
    first_scan, last_scan : ndarray of int, shape (n_tracks,)
        Scan indices (into `scan_times`) of each confirmed track's first and last state.
    states : tuple of ndarray
        Per track, the filtered states ``(n_scans_of_track, 2)`` [rad (unwrapped), rad/s].
    scan_times : ndarray, shape (n_scans,)
        The distinct detection times, s.
    """

    labels: NDArray[np.int64]
    candidates: tuple[tuple[int, ...], ...]
    first_scan: NDArray[np.int64]
    last_scan: NDArray[np.int64]
    states: tuple[FloatArray, ...]
    scan_times: FloatArray

    @property
    def n_tracks(self) -> int:
        """Number of confirmed tracks."""
        return len(self.states)


@dataclass(frozen=True)
class MultiTrackResult:
    """Output of :class:`MultiTrackSmoother`.

    Attributes
    ----------
    tracks : tuple of SmoothedTrack
        One per track, ``track_id`` 0, 1, ...
    labels : ndarray of int, shape (n_detections,)
        Most probable owner (``track_id``) of each detection in input order, ``-1`` for clutter.
    shared : ndarray of bool, shape (n_detections,)
        Detections that entered more than one track through association-weighted factors.
    em_iterations : int
        Largest number of expectation-maximisation iterations over the crossing clusters.
    pairs : tuple of three ndarrays, shape (n_pairs,) each
        The shared (detection, track) pairs and their settled association weights: detection
        index (input order), track id, weight (posterior probability, or 0/1 with
        ``association == "nearest"``).
    association : str
        ``"weighted"`` (posterior association probabilities) or ``"nearest"`` (hard baseline).
    clutter_density : float
        Clutter density used in the association, per scan per radian (given or counted).
    p_detect : float
        Detection probability used in the association (given or counted).
    approximate_scans : int
        Scans with too many shared detections for joint events (per-detection
        responsibilities instead).
    """

    tracks: tuple[SmoothedTrack, ...]
    labels: NDArray[np.int64]
    shared: NDArray[np.bool_]
    em_iterations: int
    pairs: tuple[NDArray[np.int64], NDArray[np.int64], FloatArray] = (
        np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    association: str = "weighted"
    clutter_density: float = float("nan")
    p_detect: float = float("nan")
    approximate_scans: int = 0
