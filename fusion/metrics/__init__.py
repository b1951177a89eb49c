"""Evaluation metrics: how well estimates match simulated or recorded truth.

One module per kind of result, used by tests, benchmarks, examples and the demo:

- :mod:`~fusion.metrics.crossings` -- track identities through crossings (kept, swapped, lost;
  :func:`~fusion.metrics.crossings.crossing_outcomes`) and crossing-alert scores (defined in
  :mod:`~fusion.metrics.crossing_alerts`: :func:`~fusion.metrics.crossing_alerts.score_alerts`,
  :func:`~fusion.metrics.crossing_alerts.score_intervals`).
- :mod:`~fusion.metrics.tracks` -- passive bearing tracks against a scenario's truth (RMSE,
  identities, end delays; :func:`~fusion.metrics.tracks.score_tracks`).
- :mod:`~fusion.metrics.tqi` -- track quality indicator outputs (declaration lag, state changes).
- :mod:`~fusion.metrics.localization` -- fixes matched to true sources per window
  (:func:`~fusion.metrics.localization.match_fixes`) and estimates with covariances (NEES).
- :mod:`~fusion.metrics.detections` -- click detections against a simulated scenario's true
  click times (:func:`~fusion.metrics.detections.score_clicks`).
- :mod:`~fusion.metrics.multistatic` -- multistatic tracker output against the simulated target
  (coverage, false tracks, identity switches; :func:`~fusion.metrics.multistatic.score_tracks`).

Nothing outside this package scores against truth, and no estimator imports it
(``tests/test_architecture.py`` checks both).

Importing this package imports none of them; import the module you need.
"""

# The package imports none of its modules (each loads only its own dependencies when
# imported); `from fusion.metrics import *` imports them all.
__all__ = [
    "crossings",
    "detections",
    "localization",
    "tqi",
    "tracks",
]
