"""Deprecated import path: use :mod:`fusion.pipelines.passive` instead; this module goes in the next release.

Why: the pipeline's parts are a package.
"""

from fusion._deprecated import moved_names

__all__ = ["BearingMeasurement", "LineStarter", "PeakMeasurer", "StartCandidate"]  # noqa: F822 (served by __getattr__)

__getattr__ = moved_names(
    __name__, "fusion.pipelines.passive.measure", __all__, shown="fusion.pipelines.passive"
)
