"""Coarse-to-fine search of a peak of the intensity surfaces, and the depth of a fix.

:func:`refine_peak` zooms in around a coarse grid's maximum (coarse to fine) until one TDOA
sigma spans about two cells near the array (:func:`fine_step`); :func:`scan_depth` scans the
vertical line through a horizontal fix (the long vertical ridge of a near-planar array).

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (17)-(18) and step 62 (depth from a
volume over depths).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.localization.intensity import (
    check_equation,
    combine_intensities,
    intensity_volume,
    smoothing_sigma,
    tdoa_intensities,
)
from fusion.localization.search_grid import SearchGrid
from fusion.localization.window_tdoas import WindowTdoas

__all__ = ["fine_step", "refine_peak", "scan_depth"]


def fine_step(tdoas: WindowTdoas) -> float:
    """Spacing at which one TDOA sigma spans about two cells near the array, m.

    Near the array the delay changes by up to ``2/c`` s per metre (about ``1/c`` typically), so
    ``min(sigma) c / 2`` puts at least one cell, typically two, in one sigma.
    """
    return float(np.min(tdoas.sigmas) * tdoas.c / 2.0)


def scan_depth(
    tdoas: WindowTdoas,
    point: ArrayLike,
    step: float,
    z_range: tuple[float, float],
    *,
    equation: int = 18,
    cells: float = 1.0,
    max_points: int = 512,
    groups: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], float]:
    """Best height on the vertical line through `point` (the depth of a horizontal fix).

    Parameters
    ----------
    tdoas : WindowTdoas
        The TDOAs.
    point : array_like, shape (3,)
        Position whose ``x, y`` are kept, m.
    step : float
        Vertical spacing (and smoothing scale) of the scan, m.
    z_range : (float, float)
        Lowest and highest ``z`` scanned, m.
    max_points : int, keyword-only
        Largest number of heights (the spacing widens to fit).
    equation, cells, groups : keyword-only
        As in :func:`refine_peak`.

    Returns
    -------
    position : ndarray, shape (3,)
        ``(x, y, z_best)``, m.
    value : float
        Intensity there.

    Notes
    -----
    Step 62 of the localization text takes depth from a volume over depths. On a coarse grid of
    a (near-)planar bottom array the intensity is a long vertical ridge whose local maximum can
    sit far from the source's depth; a fine scan of the ridge at the refined ``x, y`` finds it.
    """
    check_equation(equation, tdoas)
    p = np.asarray(point, dtype=float)
    n = int(min(max_points, max(2, np.ceil((z_range[1] - z_range[0]) / step) + 1)))
    z = np.linspace(z_range[0], z_range[1], n)
    column = np.column_stack([np.full(n, p[0]), np.full(n, p[1]), z])
    sig = smoothing_sigma(tdoas.sigmas, max(step, float(z[1] - z[0])), c=tdoas.c, cells=cells)
    i = tdoa_intensities(column, tdoas, sig)
    values = combine_intensities(i, tdoas, equation, groups)
    k = int(np.argmax(values))
    return column[k], float(values[k])


def refine_peak(
    tdoas: WindowTdoas,
    start: ArrayLike,
    step: float,
    *,
    equation: int = 18,
    levels: int | None = None,
    shrink: float = 3.0,
    half: int = 4,
    cells: float = 1.0,
    lo: ArrayLike | None = None,
    hi: ArrayLike | None = None,
    groups: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], float, float]:
    """Coarse-to-fine search for a peak of eq. (17)/(18) near `start`.

    Each level lays a ``(2 half + 1)^3`` grid `shrink` times finer than the last around the
    best point so far, re-smoothed for its spacing, and moves to its maximum.

    Parameters
    ----------
    tdoas : WindowTdoas
        The TDOAs.
    start : array_like, shape (3,)
        Peak of the coarser grid, m.
    step : float
        Spacing of that grid, m.
    equation : {17, 18}, keyword-only
        Which intensity.
    levels : int, optional, keyword-only
        Number of levels; default until the spacing reaches :func:`fine_step`.
    shrink : float, keyword-only
        Spacing ratio between levels (> 1).
    half : int, keyword-only
        Grid half-width in points (the grid spans ``half / shrink`` coarser cells each side).
    cells : float, keyword-only
        Smoothing in grid cells (:func:`smoothing_sigma`).
    lo, hi : array_like, shape (3,), optional, keyword-only
        Bounds of the search box, m (a plane: ``lo[2] == hi[2]``).
    groups : array_like of int, shape (M,), optional, keyword-only
        The measurement each TDOA column reads
        (:func:`fusion.localization.intensity.combine_intensities`).

    Returns
    -------
    position : ndarray, shape (3,)
        Refined peak, m.
    value : float
        Intensity there (with the last level's smoothing).
    step : float
        Spacing of the last level, m.
    """
    check_equation(equation, tdoas)
    if not shrink > 1.0 or int(half) < 1:
        raise ValueError(f"shrink must exceed 1 and half be >= 1, got {shrink!r}, {half!r}")
    if levels is None:
        target = fine_step(tdoas)
        levels = max(0, int(np.ceil(np.log(max(step, target) / target) / np.log(shrink))))
    pos = np.asarray(start, dtype=float).copy()
    if int(levels) == 0:
        i = tdoa_intensities(pos[None], tdoas, smoothing_sigma(tdoas.sigmas, step, c=tdoas.c,
                                                                cells=cells))
        return pos, float(combine_intensities(i, tdoas, equation, groups)[0]), step
    for _ in range(int(levels)):
        step = step / shrink
        grid = SearchGrid.centred(pos, step, int(half), lo=lo, hi=hi)
        vol = intensity_volume(tdoas, grid, equation=equation, cells=cells, groups=groups)
        pos, value = vol.peak()
    return pos, value, step
