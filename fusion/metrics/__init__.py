"""Evaluation metrics: how well estimates match simulated or recorded truth.

One module per kind of result, used by tests, benchmarks, examples and the demo:

- :mod:`~fusion.metrics.crossings` -- track identities through crossings (kept, swapped, lost)
  and crossing-alert scores.
"""
