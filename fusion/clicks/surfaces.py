"""Deprecated import path: use :mod:`fusion.localization.surfaces`; this module goes in the next release.

Why: localization (TDOAs to sources and tracks) is its own package, :mod:`fusion.localization`.
"""

from fusion._deprecated import moved_names

# served by __getattr__
__all__ = [  # noqa: F822
    "IntensityVolume", "SearchGrid", "SearchRegion", "WindowTdoas", "array_aperture",
    "associated_intensity", "fine_step", "intensity_volume", "refine_peak", "scan_depth",
    "sensor_distances", "smoothing_sigma", "tdoa_intensities"
]

__getattr__ = moved_names(
    __name__, "fusion.localization.surfaces", __all__, shown="fusion.localization.surfaces"
)
