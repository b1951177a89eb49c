"""Deprecated import path: use :mod:`fusion.localization.intensity`; this module goes in the next release.

Why: localization (TDOAs to sources and tracks) is its own package, :mod:`fusion.localization`.
"""

from fusion._deprecated import moved_names

# served by __getattr__
__all__ = [  # noqa: F822
    "IntensityVolume", "associated_intensity", "check_equation", "combine_intensities",
    "intensity_volume", "smoothing_sigma", "tdoa_intensities"
]

__getattr__ = moved_names(
    __name__, "fusion.localization.intensity", __all__, shown="fusion.localization.intensity"
)
