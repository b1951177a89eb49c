"""Intensity surfaces of a window's TDOAs (eq. 16-18) on grids sized by the array.

One import path for the surface layer, whose parts live in one module per role:

:mod:`fusion.localization.window_tdoas`  the window's TDOAs with their array (:class:`WindowTdoas`)
:mod:`fusion.localization.search_grid`   the search box and grids sized by the array, sensor ranges
:mod:`fusion.localization.intensity`     eq. (16)-(18) on a grid (:func:`intensity_volume`)
:mod:`fusion.localization.peak_search`   coarse-to-fine peak refinement and the depth scan

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (14)-(18) (steps 56-60) and step 62.
"""

from __future__ import annotations

from fusion.localization.intensity import (
    IntensityVolume,
    associated_intensity,
    intensity_volume,
    smoothing_sigma,
    tdoa_intensities,
)
from fusion.localization.peak_search import fine_step, refine_peak, scan_depth
from fusion.localization.search_grid import SearchGrid, SearchRegion, array_aperture, sensor_distances
from fusion.localization.window_tdoas import WindowTdoas

__all__ = [
    "IntensityVolume",
    "SearchGrid",
    "SearchRegion",
    "WindowTdoas",
    "array_aperture",
    "associated_intensity",
    "fine_step",
    "intensity_volume",
    "refine_peak",
    "scan_depth",
    "sensor_distances",
    "smoothing_sigma",
    "tdoa_intensities",
]
