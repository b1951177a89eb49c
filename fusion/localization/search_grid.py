"""Search grids sized by the array: the box to search, its coarse grid, ranges to the sensors.

Grids follow the array, not the data set: :class:`SearchRegion` centres a box on the sensors'
centroid, ``extent_factor`` array apertures wide on each side horizontally (vertically the water
column when given), and picks the isotropic spacing that fits ``max_points`` grid points;
:class:`SearchGrid` is a regular grid (a plane is a grid with one depth) and
:func:`sensor_distances` caches the ranges of a grid used for every window of one array.

Notes
-----
*Localization of Short Duration Periodic Signals*, steps 56-62: the surfaces are sampled on a
plane at an assumed depth (eq. 17-18) or on a volume over depths (step 62).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.types import frozen_array

__all__ = ["SearchGrid", "SearchRegion", "array_aperture", "sensor_distances"]



def array_aperture(sensors: ArrayLike) -> float:
    """Largest distance between two sensors, m."""
    s = np.asarray(sensors, dtype=float)
    return float(np.max(np.linalg.norm(s[:, None] - s[None], axis=-1)))


@dataclass(frozen=True)
class SearchGrid:
    """A regular axis-aligned grid of candidate source positions (``ij`` order).

    Attributes
    ----------
    x, y, z : ndarray, shape (nx,), (ny,), (nz,)
        Increasing axis coordinates, m (an axis may hold one value: a plane or a line).
    """

    x: NDArray[np.float64]
    y: NDArray[np.float64]
    z: NDArray[np.float64]

    def __post_init__(self) -> None:
        for name in ("x", "y", "z"):
            a = np.array(getattr(self, name), dtype=float).reshape(-1)
            if a.size < 1 or not np.all(np.isfinite(a)) or np.any(np.diff(a) <= 0):
                raise ValueError(f"grid axis {name} must be finite, non-empty and increasing")
            object.__setattr__(self, name, frozen_array(a))

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(nx, ny, nz)``."""
        return (self.x.size, self.y.size, self.z.size)

    @property
    def size(self) -> int:
        """Number of grid points."""
        return self.x.size * self.y.size * self.z.size

    @property
    def step(self) -> float:
        """Largest spacing along the axes that have more than one point, m (0 for one point)."""
        cached = self.__dict__.get("_step")
        if cached is None:  # computed once per grid (the refinement asks for it on every level)
            steps = [float(np.max(np.diff(a))) for a in (self.x, self.y, self.z) if a.size > 1]
            cached = max(steps) if steps else 0.0
            object.__setattr__(self, "_step", cached)
        return cached

    def points(self, start: int = 0, stop: int | None = None) -> NDArray[np.float64]:
        """Grid points ``start:stop`` in flat (C, ``ij``) order, shape (k, 3), m."""
        stop = self.size if stop is None else min(stop, self.size)
        if start == 0 and stop == self.size:  # the whole grid: the same values, broadcast
            out = np.empty((*self.shape, 3))
            out[..., 0] = self.x[:, None, None]
            out[..., 1] = self.y[None, :, None]
            out[..., 2] = self.z[None, None, :]
            return out.reshape(-1, 3)
        i, j, k = np.unravel_index(np.arange(start, stop), self.shape)
        return np.column_stack([self.x[i], self.y[j], self.z[k]])

    @classmethod
    def centred(cls, centre: ArrayLike, step: float, half: int, *, lo: ArrayLike | None = None,
                hi: ArrayLike | None = None) -> SearchGrid:
        """Cube of ``2 half + 1`` points per axis, spacing `step` m, around `centre` (clipped).

        An axis whose bounds coincide (``lo == hi``) holds that one value.
        """
        ctr = np.asarray(centre, dtype=float)
        offs = step * np.arange(-half, half + 1)
        axes = []
        for a in range(3):
            ax = ctr[a] + offs
            if lo is not None and hi is not None:  # increasing: clipping leaves runs at the ends
                ax = np.clip(ax, lo[a], hi[a])
                ax = ax[np.concatenate(([True], ax[1:] != ax[:-1]))]
            axes.append(ax)
        if lo is None or hi is None or not np.isfinite(np.concatenate((ctr, lo, hi))).all():
            return cls(*axes)
        # finite, and strictly increasing by construction (a clipped non-decreasing sequence
        # without its repeats): the checks and copies of __post_init__ are skipped
        grid = object.__new__(cls)
        for name, ax in zip("xyz", axes, strict=True):
            ax.setflags(write=False)
            object.__setattr__(grid, name, ax)
        return grid


@dataclass(frozen=True)
class SearchRegion:
    """Where to look for sources, derived from the array's own size.

    Attributes
    ----------
    extent_factor : float
        Half-width of the horizontal search box in array apertures (largest sensor separation),
        around the sensors' centroid. Default 1.
    water_column : (float, float), optional
        ``(z_bottom, z_surface)``, m (z up): the vertical search range. Default: the centroid's
        ``z`` plus or minus ``extent_factor`` apertures.
    max_points : int
        Budget of points of the coarse grid (the spacing is the isotropic one that fits).
    """

    extent_factor: float = 2.0
    water_column: tuple[float, float] | None = None
    max_points: int = 32_768

    def __post_init__(self) -> None:
        if not (np.isfinite(self.extent_factor) and self.extent_factor > 0):
            raise ValueError(f"extent_factor must be positive, got {self.extent_factor!r}")
        if self.water_column is not None:
            lo, hi = (float(v) for v in self.water_column)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(f"water_column must be (z_bottom, z_surface) with z_bottom < "
                                 f"z_surface, got {self.water_column!r}")
        if int(self.max_points) != self.max_points or self.max_points < 27:
            raise ValueError(f"max_points must be an integer >= 27, got {self.max_points!r}")

    def bounds(self, sensors: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Corners ``lo``, ``hi`` (3,) of the search box, m."""
        s = np.asarray(sensors, dtype=float)
        centre = s.mean(axis=0)
        half = self.extent_factor * array_aperture(s)
        lo, hi = centre - half, centre + half
        if self.water_column is not None:
            lo[2], hi[2] = self.water_column
        return lo, hi

    def volume(self, sensors: ArrayLike) -> SearchGrid:
        """Coarse 3-D grid over the box, at most about `max_points` points."""
        lo, hi = self.bounds(sensors)
        ext = hi - lo
        step = float(np.cbrt(np.prod(ext) / self.max_points))
        return SearchGrid(*(np.linspace(lo[a], hi[a], max(3, int(ext[a] / step) + 1))
                            for a in range(3)))

    def plane(self, sensors: ArrayLike, z: float) -> SearchGrid:
        """Coarse 2-D grid over the box at the assumed height `z` (m, z up)."""
        lo, hi = self.bounds(sensors)
        ext = hi - lo
        step = float(np.sqrt(ext[0] * ext[1] / self.max_points))
        return SearchGrid(np.linspace(lo[0], hi[0], max(3, int(ext[0] / step) + 1)),
                          np.linspace(lo[1], hi[1], max(3, int(ext[1] / step) + 1)), [float(z)])


def sensor_distances(grid: SearchGrid, sensors: ArrayLike, *, chunk_points: int = 8192
                     ) -> NDArray[np.float64]:
    """Ranges ``|p - s_i|`` from every grid point to every sensor, shape (grid.size, n), m.

    Stored sensor by sensor (a transposed view of an (n, grid.size) array): the intensities
    read each sensor's ranges as contiguous rows.
    """
    s = np.asarray(sensors, dtype=float)
    centre = s.mean(axis=0)
    sc = s - centre  # centred: |p - s|^2 = |p|^2 + |s|^2 - 2 p.s loses little precision
    out = np.empty((s.shape[0], grid.size))  # stored by sensor (rows of ranges), returned (P, n)
    for start in range(0, grid.size, int(chunk_points)):
        p = grid.points(start, start + int(chunk_points)) - centre
        d2 = (p * p).sum(1)[:, None] + (sc * sc).sum(1)[None, :] - 2.0 * (p @ sc.T)
        out[:, start:start + p.shape[0]] = np.sqrt(np.maximum(d2, 0.0)).T
    return out.T
