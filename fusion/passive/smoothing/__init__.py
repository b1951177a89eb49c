"""Bearing-rate smoothing on factor graphs: one track, incremental, and many tracks through crossings.

Every track is a chain of states ``x_k = (theta_k, theta_dot_k)`` (bearing, rad; bearing rate,
rad/s) at the scan times, tied by constant-rate motion factors with white-noise-acceleration
noise and by bearing factors, with a prior on the first state (for instance from acquisition):
the bearing-rate graph of the project's design notes ("Factor graphs"), built and solved in
:mod:`~fusion.passive.smoothing.graph` from GTSAM's built-in linear factors with the bearings
re-centred on the wrap.

Unlabeled detections -- the input of :class:`MultiTrackSmoother`,
:func:`~fusion.passive.smoothing.settings.pair_scatter` and
:func:`~fusion.passive.smoothing.merge.merge_scan_detections` -- are two arrays of equal length:
``times`` (s; equal times form a scan) and ``bearings`` (rad).

Modules, one role each:

- :mod:`~fusion.passive.smoothing.types` -- :class:`TrackPrior`, :class:`SmoothedTrack`,
  :class:`TrackerResult`, :class:`MultiTrackResult`.
- :mod:`~fusion.passive.smoothing.batch` -- :class:`BearingSmoother`, batch smoothing of one
  track (one sparse linear solve, or Levenberg-Marquardt with a Huber/Cauchy loss for outlier
  bearings), equal to a Rauch-Tung-Striebel smoother (:func:`rts_reference`) on linear-Gaussian
  data.
- :mod:`~fusion.passive.smoothing.fixed_lag` -- :class:`FixedLagBearingTrack`, the one
  incremental bearing tracker: one track's graph grown state by state on a GTSAM fixed-lag
  smoother (the passive pipeline's tracks).
- :mod:`~fusion.passive.smoothing.online` -- :class:`OnlineBearingSmoother`, the same graph as
  the batch smoother grown one scan at a time (a fixed-lag track that keeps every state).
- :mod:`~fusion.passive.smoothing.nearest_neighbour` -- :class:`NearestNeighbourTracker`, a
  Kalman bearing tracker (filterpy's arithmetic) with global nearest-neighbour assignment, optionally
  crossing-aware.
- :mod:`~fusion.passive.smoothing.multitrack` -- :class:`MultiTrackSmoother`, tracks from
  unlabeled detections with expectation-maximisation around every crossing through
  association-weighted factors.
- :mod:`~fusion.passive.smoothing.association` -- the weights of shared detections: posterior
  association probabilities over each scan's joint events, clutter and missed detections
  included, or the gated nearest assignment they are measured against.
- :mod:`~fusion.passive.smoothing.candidates` -- released detections gated into the gaps and
  beyond the ends of linked tracks.
- :mod:`~fusion.passive.smoothing.em` -- the M-step of the crossing-cluster EM in closed form.
- :mod:`~fusion.passive.smoothing.huber` -- Huber-loss track graphs minimised by Newton steps.
- :mod:`~fusion.passive.smoothing.linking` -- segments chained into tracks by one assignment;
  shared detections grouped into crossing clusters.
- :mod:`~fusion.passive.smoothing.grid` -- :func:`~fusion.passive.smoothing.grid.on_grid`, a
  smoothed track on a regular time grid through short gaps, with its sigmas.
- :mod:`~fusion.passive.smoothing.merge` -- :func:`~fusion.passive.smoothing.merge.
  merge_scan_detections`, same-scan bearings closer than the sensor resolves made one.
- :mod:`~fusion.passive.smoothing.twins` -- :func:`~fusion.passive.smoothing.twins.twin_groups`,
  tracks that follow one source side by side.
- :mod:`~fusion.passive.smoothing.settings` -- :func:`~fusion.passive.smoothing.settings.
  fit_smooth_settings`, the scales of ``fusion smooth`` estimated from its input.
- :mod:`~fusion.passive.smoothing.diffusion` -- the bearing acceleration PSD of tracks from
  their block-wise rate changes and from their second differences across lags.
- :mod:`~fusion.passive.smoothing.table` -- :func:`smooth_bearings`, the rows of a bearing table
  (labelled tracks alone, unknown-origin rows jointly).

Crossings are predicted with equation (2) of "Target Track Crossing Prediction/Detection"
(:func:`fusion.passive.crossing.timing.crossing_time`, the one copy of that equation, re-exported
here as :func:`crossing_time`). The identity scores :func:`crossing_outcomes` and
:func:`identity_swaps` live in :mod:`fusion.metrics.crossings`; their old import path here warns
and forwards for one release.
"""

from fusion._deprecated import moved_names
from fusion.passive.crossing.timing import crossing_time
from fusion.passive.smoothing.batch import BearingSmoother, rts_reference
from fusion.passive.smoothing.fixed_lag import FixedLagBearingTrack, TrackStates
from fusion.passive.smoothing.graph import ROBUST_LOSSES
from fusion.passive.smoothing.multitrack import MultiTrackSmoother
from fusion.passive.smoothing.nearest_neighbour import NearestNeighbourTracker
from fusion.passive.smoothing.online import OnlineBearingSmoother
from fusion.passive.smoothing.table import smooth_bearings
from fusion.passive.smoothing.types import (
    MultiTrackResult,
    SmoothedTrack,
    TrackerResult,
    TrackPrior,
)

__all__ = [
    "ROBUST_LOSSES",
    "BearingSmoother",
    "FixedLagBearingTrack",
    "MultiTrackResult",
    "MultiTrackSmoother",
    "NearestNeighbourTracker",
    "OnlineBearingSmoother",
    "SmoothedTrack",
    "TrackPrior",
    "TrackStates",
    "TrackerResult",
    "crossing_time",
    "rts_reference",
    "smooth_bearings",
]

#: Identity scores, moved to :mod:`fusion.metrics.crossings`; served here with a DeprecationWarning
#: for one release.
__getattr__ = moved_names(
    __name__, "fusion.metrics.crossings", ["CROSSING_OUTCOMES", "crossing_outcomes", "identity_swaps"],
    shown="fusion.metrics.crossings",
)
