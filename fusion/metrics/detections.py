"""Scores of click detections against true click times.

The functions are defined beside the click front end (:mod:`fusion.clicks.scoring`) and listed
here so that every evaluation metric is found under :mod:`fusion.metrics`.
"""

from fusion.clicks.scoring import ClickScore, match_times, score_clicks

__all__ = ["ClickScore", "match_times", "score_clicks"]
