"""Candidate source positions: the local maxima of an intensity volume (step 62).

The association-weighted volume of eq. (18) over depths has many local maxima; the strongest
become the candidate solutions that compete for the TDOAs (:mod:`fusion.localization.competition`).
:class:`CandidateFinder` finds the 3-D local maxima with :func:`scipy.ndimage.maximum_filter`,
keeps those above a fraction of the largest, optionally refines each on finer grids
(:func:`fusion.localization.peak_search.refine_peak`) and rescans its depth, suppresses near-duplicates
and returns at most ``max_candidates``, strongest first.

Notes
-----
*Localization of Short Duration Periodic Signals*, paragraph [0047] (step 62): a
three-dimensional peak picking of the volume gives candidate positions for the competition.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import maximum_filter

from fusion.localization.intensity import IntensityVolume
from fusion.localization.peak_search import refine_peak, scan_depth
from fusion.localization.window_tdoas import WindowTdoas

__all__ = ["CandidateFinder", "Candidates"]

_LOG = logging.getLogger(__name__)

#: Refinement levels run before the depth scan (the rest run after it).
_SCAN_AFTER_LEVELS = 2


@dataclass(frozen=True)
class Candidates:
    """Candidate source positions, strongest first.

    Attributes
    ----------
    positions : ndarray, shape (K, 3)
        Positions, m.
    intensities : ndarray, shape (K,)
        Intensity of the volume at each (after refinement: at the finest level's smoothing).
    relative : ndarray, shape (K,)
        Coarse-grid intensity over the volume's largest value, in (0, 1].
    step : float
        Grid spacing the positions are resolved to, m.
    """

    positions: NDArray[np.float64]
    intensities: NDArray[np.float64]
    relative: NDArray[np.float64]
    step: float

    @property
    def k(self) -> int:
        """Number of candidates."""
        return int(self.positions.shape[0])


class CandidateFinder:
    """Pick candidate positions from the local maxima of an intensity volume.

    Parameters
    ----------
    max_candidates : int, keyword-only
        Largest number of candidates returned (K). Default 8.
    min_relative : float, keyword-only
        Smallest local maximum kept, as a fraction of the volume's largest value. Default 0.05.
    footprint : int, keyword-only
        Width (grid points, odd) of the neighbourhood a local maximum dominates. Default 3.
    refine_levels : int, keyword-only
        Coarse-to-fine levels run on each maximum (0: the grid point itself). Default 2.
    refine_half : int, keyword-only
        Half-width in points of each refinement grid (3 times finer than the last, so the
        default 3 spans one coarser cell each side).
    min_separation_cells : float, keyword-only
        Two candidates closer than this many coarse cells are one (the weaker is dropped).
    scan_depth : bool, keyword-only
        After the first two refinement levels, scan the whole vertical range of the box at the
        refined ``x, y`` (:func:`fusion.localization.peak_search.scan_depth`) and move to a better depth
        if there is one, then refine on (default True; needs `lo`, `hi` and a volume with
        several depths).

    Examples
    --------
    >>> from fusion.localization.surfaces import SearchGrid
    >>> g = SearchGrid(np.arange(5.0), np.arange(5.0), [0.0])
    >>> vals = np.zeros((5, 5, 1)); vals[1, 1, 0] = 2.0; vals[3, 4, 0] = 1.0
    >>> c = CandidateFinder(refine_levels=0).find(IntensityVolume(g, vals, 17, np.ones(1)))
    >>> c.positions
    array([[1., 1., 0.],
           [3., 4., 0.]])
    """

    def __init__(
        self,
        *,
        max_candidates: int = 8,
        min_relative: float = 0.05,
        footprint: int = 3,
        refine_levels: int = 2,
        refine_half: int = 3,
        min_separation_cells: float = 1.5,
        scan_depth: bool = True,
    ) -> None:
        if int(max_candidates) != max_candidates or max_candidates < 1:
            raise ValueError(f"max_candidates must be a positive integer, got {max_candidates!r}")
        if not 0.0 <= min_relative < 1.0:
            raise ValueError(f"min_relative must lie in [0, 1), got {min_relative!r}")
        if int(footprint) != footprint or footprint < 3 or footprint % 2 == 0:
            raise ValueError(f"footprint must be an odd integer >= 3, got {footprint!r}")
        if int(refine_levels) != refine_levels or refine_levels < 0:
            raise ValueError(f"refine_levels must be an integer >= 0, got {refine_levels!r}")
        if int(refine_half) != refine_half or refine_half < 1:
            raise ValueError(f"refine_half must be a positive integer, got {refine_half!r}")
        if not min_separation_cells >= 0.0:
            raise ValueError(f"min_separation_cells must be >= 0, got {min_separation_cells!r}")
        self.max_candidates = int(max_candidates)
        self.min_relative = float(min_relative)
        self.footprint = int(footprint)
        self.refine_levels = int(refine_levels)
        self.refine_half = int(refine_half)
        self.scan_depth = bool(scan_depth)
        self.min_separation_cells = float(min_separation_cells)

    def _maxima(self, volume: IntensityVolume) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        """Flat indices and values of the local maxima above the floor, strongest first."""
        v = volume.values
        top = float(v.max()) if v.size else 0.0
        if not top > 0.0:
            return np.zeros(0, np.intp), np.zeros(0)
        # a point is a local maximum if no neighbour in the footprint exceeds it
        peak = (v == maximum_filter(v, size=self.footprint, mode="nearest"))
        peak &= v >= self.min_relative * top
        idx = np.flatnonzero(peak)
        vals = v.reshape(-1)[idx]
        order = np.argsort(-vals, kind="stable")
        return idx[order], vals[order]

    def _suppress(self, positions: NDArray[np.float64], radius: float, limit: int | None = None
                  ) -> NDArray[np.intp]:
        """Indices kept by greedy non-maximum suppression (input strongest first).

        A point is kept when no kept point lies within `radius`; each kept point suppresses
        the later points within `radius` at once. Stops after `limit` kept points.
        """
        n = positions.shape[0]
        suppressed = np.zeros(n, dtype=bool)
        kept: list[int] = []
        for k in range(n):
            if suppressed[k]:
                continue
            kept.append(k)
            if limit is not None and len(kept) >= limit:
                break
            d = np.sqrt(np.sum((positions[k + 1:] - positions[k]) ** 2, axis=1))
            suppressed[k + 1:] |= d <= radius
        return np.array(kept, dtype=np.intp)

    def find(
        self,
        volume: IntensityVolume,
        tdoas: WindowTdoas | None = None,
        *,
        lo: NDArray[np.float64] | None = None,
        hi: NDArray[np.float64] | None = None,
    ) -> Candidates:
        """Candidates of one volume.

        Parameters
        ----------
        volume : IntensityVolume
            Intensity of eq. (17) or (18) on a grid.
        tdoas : WindowTdoas, optional
            The TDOAs the volume was made from; needed to refine (``refine_levels > 0``).
        lo, hi : ndarray, shape (3,), optional, keyword-only
            Bounds of the search box for the refinement, m.

        Returns
        -------
        Candidates
            At most `max_candidates`, strongest first (possibly none).
        """
        idx, vals = self._maxima(volume)
        step = volume.grid.step
        top = float(vals[0]) if vals.size else 1.0
        # suppress plateaus / neighbours on the coarse grid, then cap (refinement costs)
        pos = volume.grid.points(0, None)[idx] if idx.size else np.zeros((0, 3))
        keep = self._suppress(pos, self.min_separation_cells * step, self.max_candidates)
        pos, vals = pos[keep], vals[keep]
        rel = vals / top
        inten = vals.copy()
        fine = step
        if self.refine_levels and tdoas is not None and pos.shape[0]:
            scan = (self.scan_depth and volume.grid.shape[2] > 1 and lo is not None
                    and hi is not None)
            first = min(self.refine_levels, _SCAN_AFTER_LEVELS) if scan else self.refine_levels
            for k in range(pos.shape[0]):
                pos[k], inten[k], fine = refine_peak(tdoas, pos[k], step, equation=volume.equation,
                                                     levels=first, half=self.refine_half,
                                                     lo=lo, hi=hi, groups=volume.groups)
                rest = self.refine_levels - first
                if scan:  # the depth of a vertical ridge: scan it at the refined x, y
                    p, v = scan_depth(tdoas, pos[k], fine, (float(lo[2]), float(hi[2])),
                                      equation=volume.equation, groups=volume.groups)
                    if v > inten[k]:  # then refine around the new depth from one level up
                        pos[k], inten[k], rest, fine = p, v, rest + 1, 3.0 * fine
                if rest:
                    pos[k], inten[k], fine = refine_peak(tdoas, pos[k], fine,
                                                         equation=volume.equation, levels=rest,
                                                         half=self.refine_half, lo=lo, hi=hi,
                                                         groups=volume.groups)
            # two coarse maxima refined onto one peak are one candidate
            order = np.argsort(-inten, kind="stable")
            pos, inten, rel = pos[order], inten[order], rel[order]
            keep = self._suppress(pos, self.min_separation_cells * fine)
            pos, inten, rel = pos[keep], inten[keep], rel[keep]
        k = min(self.max_candidates, pos.shape[0])
        _LOG.debug("%d local maxima above %.3g of the largest; %d candidates", idx.size,
                   self.min_relative, k)
        return Candidates(pos[:k], inten[:k], rel[:k], float(fine))
