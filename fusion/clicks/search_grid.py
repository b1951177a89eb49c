"""Deprecated import path: use :mod:`fusion.localization.search_grid`; this module goes in the next release.

Why: localization (TDOAs to sources and tracks) is its own package, :mod:`fusion.localization`.
"""

from fusion._deprecated import moved_names

# served by __getattr__
__all__ = [  # noqa: F822
    "SearchGrid", "SearchRegion", "array_aperture", "sensor_distances"
]

__getattr__ = moved_names(
    __name__, "fusion.localization.search_grid", __all__, shown="fusion.localization.search_grid"
)
