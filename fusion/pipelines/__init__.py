"""Pipelines: the stages of one kind of data chained, with ``step()`` for streaming and ``run()``.

- :mod:`fusion.pipelines.passive` -- passive narrowband beam/frequency/time scans: acquisition,
  fixed-lag bearing graphs, track quality, crossings (:class:`~fusion.pipelines.passive.
  PassivePipeline`); its parts in ``passive_*`` modules.

Import the pipeline modules themselves; this package imports nothing, so that loading one
pipeline does not load the others' dependencies.
"""
