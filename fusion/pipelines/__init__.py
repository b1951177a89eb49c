"""Pipelines: the stages of one kind of data chained, with ``step()`` for streaming and ``run()``.

- :mod:`fusion.pipelines.passive` -- passive narrowband beam/frequency/time scans: acquisition,
  fixed-lag bearing graphs, track quality, crossings (:class:`~fusion.pipelines.passive.
  PassivePipeline`), a package with one module per part.

Import the pipeline modules themselves; this package imports nothing, so that loading one
pipeline does not load the others' dependencies.
"""
