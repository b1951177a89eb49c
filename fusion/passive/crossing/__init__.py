"""Prediction and detection of bearing-track crossings (the crossing stage of the passive chain).

This package takes bearing tracks -- a bearing table, or the live tracks' bearings scan by scan --
and raises alerts for pairs of tracks that are about to cross or have crossed. It uses only
:mod:`fusion.geometry`, :mod:`fusion.passive.line_fit` and :mod:`fusion.passive.bearing_grid`
(no I/O, no pipeline). A user calls :func:`detect_crossings` (batch), :class:`CrossingDetector`
(streaming, ``step``) and :func:`crossing_settings` (windows in seconds from the data); streaming
over chunked files lives in :mod:`fusion.passive.crossing.stream`. Alerts are scored against true
crossings in :mod:`fusion.metrics.crossings` (``score_alerts``, ``score_intervals``; their old
import path here warns and forwards for one release).

Implements *Target Track Crossing Prediction/Detection* (the method text of that title): every
K seconds each track's bearing rate ``B'`` and bearing intercept ``B0`` come from a least-squares
line over its most recent J samples (regression routine 104A); for every pair of tracks the
crossing time ``t_c`` follows from equation (2); pairs whose ``t_c`` falls outside an accepted
range are dropped (in-range check 104C); inequality (3) predicts a crossing and inequality (4)
detects one (104D, 104E), and either raises an alert (output 106).

Beyond the method text, each alert carries a confidence interval of ``t_c`` from the covariance
of the two window fits (Fieller's interval), an alert is raised only when that interval is
bounded and no wider than the horizon, and a pair whose bearing-rate difference the J-sample
window cannot resolve is tried again on windows of 2 J, 4 J, ... samples (``n_windows``).
With ``curve_alpha`` a window whose bearings curve (an F-test) gets the bearing curve of a
constant-velocity contact instead of the line (:mod:`~fusion.passive.crossing.curve`), and a
pair's crossings in opposite directions are separate events (repeated passes are reported).

Pieces:

- :class:`~fusion.passive.line_fit.SlidingLineFit` - recursive least-squares lines over a
  sliding window for many tracks at once, with their covariance;
- :func:`~fusion.passive.crossing.pairs.evaluate_pairs` - equation (2), the in-range check and
  inequalities (3)/(4) for all pairs at once;
- :class:`~fusion.passive.crossing.detector.CrossingDetector` - the streaming component
  (``step``), window ladder and alert de-duplication;
- :mod:`~fusion.passive.crossing.curve` - constant-velocity bearing curves, their F-test
  against the line, and the crossing time and interval of two curves;
- :mod:`~fusion.passive.crossing.merge` - simultaneous bearings of one track merged;
- :mod:`~fusion.passive.crossing.interval` and :mod:`~fusion.passive.crossing.timing` - the
  confidence interval of ``t_c`` and the terms of equation (2);
- :mod:`~fusion.passive.crossing.stream` and :mod:`~fusion.passive.crossing.summary` - the
  detector over chunked tables, and per-pair summaries;
- :func:`~fusion.passive.crossing.batch.detect_crossings` - the batch entry point for a bearing
  table sampled irregularly, and :func:`~fusion.passive.crossing.settings.crossing_settings` -
  window, horizon and period in seconds from the data.
"""

from fusion._deprecated import moved_names
from fusion.passive.bearing_grid import ResampledBearings, estimate_period, resample_bearings
from fusion.passive.crossing import settings as _settings
from fusion.passive.crossing.batch import detect_crossings
from fusion.passive.crossing.detector import CrossingDetector
from fusion.passive.crossing.pairs import evaluate_pairs
from fusion.passive.crossing.settings import *  # noqa: F403 (its __all__: defaults, settings)
from fusion.passive.crossing.types import AlertKind, CrossingAlert, PairCheck
from fusion.passive.line_fit import LineStats, SlidingLineFit

__all__ = [
    *_settings.__all__,
    "Alert",
    "AlertKind",
    "CrossingAlert",
    "CrossingDetector",
    "LineStats",
    "PairCheck",
    "ResampledBearings",
    "SlidingLineFit",
    "detect_crossings",
    "estimate_period",
    "evaluate_pairs",
    "resample_bearings",
]

#: Short name of :class:`CrossingAlert`.
Alert = CrossingAlert

#: Scores of alerts against true crossings, moved to :mod:`fusion.metrics.crossings`; served here
#: with a DeprecationWarning for one release.
__getattr__ = moved_names(
    __name__, "fusion.metrics.crossing_alerts",
    ["CrossingScore", "IntervalScore", "score_alerts", "score_intervals"],
    shown="fusion.metrics.crossings",
)
