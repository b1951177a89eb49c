"""Track quality of narrowband bearing trackers: the TQI with hysteresis (quality stage).

This package turns a tracker's per-update outputs -- the cell amplitude at the tracked beam and
the bearing error residual -- into one of four track states (``strong``, ``low_snr``,
``uncertain``, ``lost``) with hysteresis, for many tracks at once. It uses only numpy and the
cell power statistics of :mod:`fusion.passive.tracker` (no I/O, no pipeline). A user calls
:class:`TrackQualityIndicator` (``step`` for streaming, ``run`` for a batch) and reads
:class:`TrackQuality` states and :class:`TQIHistory`; :func:`design_statistics` and
:func:`omega_for_beamwidth` give its design values, :func:`tqi_transition` one flow step.

Modules: :mod:`~fusion.passive.quality.indicator` (the component and the method notes),
:mod:`~fusion.passive.quality.flow` (flow steps and design statistics),
:mod:`~fusion.passive.quality.types` (states, memory, history).
"""

from fusion.passive.quality.flow import design_statistics, omega_for_beamwidth, tqi_transition
from fusion.passive.quality.indicator import SLLR0_CEILING_MARGIN, TrackQualityIndicator
from fusion.passive.quality.types import LABELS, START, TQIHistory, TQIMemory, TrackQuality

__all__ = [
    "LABELS",
    "SLLR0_CEILING_MARGIN",
    "START",
    "TQIHistory",
    "TQIMemory",
    "TrackQuality",
    "TrackQualityIndicator",
    "design_statistics",
    "omega_for_beamwidth",
    "tqi_transition",
]
