"""Deprecated import path: use :mod:`fusion.metrics.tracks` instead; this module goes in the next release.

Why: scoring belongs to fusion.metrics.
"""

from fusion._deprecated import moved_names

__all__ = ["PassiveScore", "ScoredTrack", "score_tracks"]  # noqa: F822 (served by __getattr__)

__getattr__ = moved_names(
    __name__, "fusion.metrics.tracks", __all__, shown="fusion.metrics.tracks"
)
