"""Pipelines: the stages of one kind of data chained, with ``step()`` for streaming and ``run()``.

- :mod:`fusion.pipelines.passive` -- passive narrowband beam/frequency/time scans: acquisition,
  fixed-lag bearing graphs, track quality, crossings (:class:`~fusion.pipelines.passive.
  PassivePipeline`), a package with one module per part.
- :mod:`fusion.pipelines.bearing_smoothing`, :mod:`~fusion.pipelines.bearing_crossings`,
  :mod:`~fusion.pipelines.track_quality`, :mod:`~fusion.pipelines.active_tracking` -- one table
  in, the settings its command estimates fitted to it, results out: the functions ``fusion
  smooth``, ``crossings``, ``tqi`` and ``track`` call, exported as :func:`fusion.smooth_bearings`,
  :func:`fusion.find_crossings`, :func:`fusion.track_quality`, :func:`fusion.track_detections`.
- :mod:`fusion.pipelines.clicks` -- the click front end (``frontend``, ``stream``, ``chunks``,
  ``training``), a package; :mod:`fusion.pipelines.localization` -- its TDOAs to sources.

Import the pipeline modules themselves; this package imports nothing, so that loading one
pipeline does not load the others' dependencies.
"""

# The package imports none of its modules (each loads only its own dependencies when
# imported); `from fusion.pipelines import *` imports them all. Deprecated old paths
# (``click_training``, ``passive_measure``, ``passive_scoring``, ``passive_types``) still import,
# with a warning, but are not listed.
__all__ = [
    "active_tracking",
    "bearing_crossings",
    "bearing_smoothing",
    "clicks",
    "from_recording",
    "localization",
    "passive",
    "sound_speed",
    "track_quality",
]
