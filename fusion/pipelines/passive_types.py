"""Deprecated import path: use :mod:`fusion.pipelines.passive` instead; this module goes in the next release.

Why: the pipeline's parts are a package.
"""

from fusion._deprecated import moved_names

__all__ = [  # noqa: F822 (served by __getattr__)
    "Click", "PassiveResult", "PassiveTrack", "Scan", "ScanResult", "SmootherSettings",
    "TrackEnd", "TrackStart", "TrackUpdate", "scans_of",
]

__getattr__ = moved_names(
    __name__, "fusion.pipelines.passive.types", __all__, shown="fusion.pipelines.passive"
)
