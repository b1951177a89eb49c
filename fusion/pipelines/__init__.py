"""Pipelines: the stages of one kind of data chained, with ``step()`` for streaming and ``run()``.

- :mod:`fusion.pipelines.passive` -- passive narrowband beam/frequency/time scans: acquisition,
  fixed-lag bearing graphs, track quality, crossings (:class:`~fusion.pipelines.passive.
  PassivePipeline`), a package with one module per part.

Import the pipeline modules themselves; this package imports nothing, so that loading one
pipeline does not load the others' dependencies.
"""

# The package imports none of its modules (each loads only its own dependencies when
# imported); `from fusion.pipelines import *` imports them all.
__all__ = [
    "bearing_crossings",
    "bearing_smoothing",
    "click_chunks",
    "click_stream",
    "click_training",
    "clicks",
    "from_recording",
    "localization",
    "passive",
    "passive_measure",
    "passive_scoring",
    "passive_types",
    "sound_speed",
    "track_quality",
]
