"""Scoring of passive tracks against truth: moved to :mod:`fusion.metrics.tracks`.

The names are re-exported here so that older imports keep working.
"""

from fusion.metrics.tracks import PassiveScore, ScoredTrack, score_tracks

__all__ = ["PassiveScore", "ScoredTrack", "score_tracks"]
