"""Deprecated import path: use :mod:`fusion.metrics.detections`; this module goes in the next release.

Why: evaluation metrics live in :mod:`fusion.metrics` only.
"""

from fusion._deprecated import moved_names

__all__ = ["ClickScore", "match_times", "score_clicks"]  # noqa: F822 (served by __getattr__)

__getattr__ = moved_names(
    __name__, "fusion.metrics.detections", __all__, shown="fusion.metrics.detections"
)
