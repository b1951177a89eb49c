"""Deprecated import path: use :mod:`fusion.metrics.crossing_alerts`; this module goes in the next release.

Why: scores against truth live in :mod:`fusion.metrics` only.
"""

from fusion._deprecated import moved_names

__all__ = ["CrossingScore", "IntervalScore", "score_alerts", "score_intervals"]  # noqa: F822 (served by __getattr__)

__getattr__ = moved_names(
    __name__, "fusion.metrics.crossing_alerts", __all__, shown="fusion.metrics.crossings"
)
