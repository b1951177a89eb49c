"""Hyperbolic intensity surfaces of a window's TDOAs (eq. 16-18) on grids sized by the array.

A window's validated TDOAs (:class:`WindowTdoas`) are drawn as smoothed hyperbolas on a grid:
each TDOA ``m`` gives the intensity ``I_m`` of eq. (16); their sum is eq. (17); the sum of
products of pairs weighted by the cross-pair association ``alpha`` is eq. (18), computed from the
``I_m`` once as one quadratic form per grid point, ``I^T alpha I``. A plane at an assumed depth
and a 3-D volume over depths use the same code (a plane is a volume with one depth).

Grids follow the array, not the data set: :class:`SearchRegion` centres a box on the sensors'
centroid, ``extent_factor`` array apertures wide on each side horizontally (vertically the water
column when given), and picks the isotropic spacing that fits ``max_points`` grid points. The
delay smoothing ``sigma_t`` of eq. (16) is the TDOA sigma widened by the delay a cell spans,
:func:`smoothing_sigma`, so a coarse grid never misses a hyperbola; :func:`refine_peak` zooms in
(coarse to fine) until one TDOA sigma spans about two cells near the array.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (14)-(18) (steps 56-60) and step 62 (a
volume over depths). Evaluation is chunked over grid points (``chunk_points``), so memory stays
at ``chunk_points x M`` floats whatever the grid size.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.tdoa_model import TdoaModel, check_speed

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


def _frozen(a: ArrayLike, dtype: type = float) -> NDArray:
    out = np.array(a, dtype=dtype)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class WindowTdoas:
    """The validated TDOAs of one processing window, with their array (checked, read-only).

    Attributes
    ----------
    sensors : ndarray, shape (n, 3)
        Sensor positions, m.
    pairs : ndarray of int, shape (M, 2)
        Sensor pair ``(i, j)`` of each TDOA.
    taus : ndarray, shape (M,)
        Delays, arrival at ``i`` minus arrival at ``j``, s.
    sigmas : ndarray, shape (M,)
        Standard deviation of each delay, s (> 0).
    c : float
        Sound speed, m/s.
    alpha : ndarray, shape (M, M), optional
        Cross-pair association of eq. (13): symmetric, non-negative, finite; None when the
        window has no association measure.
    """

    sensors: NDArray[np.float64]
    pairs: NDArray[np.intp]
    taus: NDArray[np.float64]
    sigmas: NDArray[np.float64]
    c: float
    alpha: NDArray[np.float64] | None = None
    _model: TdoaModel = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        model = TdoaModel.build(self.sensors, self.pairs, self.taus)  # checks shapes and values
        m = model.m
        sig = np.broadcast_to(np.asarray(self.sigmas, dtype=float), (m,))
        if not np.all(np.isfinite(sig) & (sig > 0)):
            raise ValueError("sigmas must be positive and finite (one per TDOA, s)")
        object.__setattr__(self, "c", check_speed(self.c))
        object.__setattr__(self, "sensors", _frozen(model.sensors))
        object.__setattr__(self, "pairs", _frozen(model.pairs, np.intp))
        object.__setattr__(self, "taus", _frozen(model.taus))
        object.__setattr__(self, "sigmas", _frozen(sig))
        object.__setattr__(self, "_model", model)
        if self.alpha is not None:
            a = np.array(self.alpha, dtype=float)
            if a.shape != (m, m):
                raise ValueError(f"alpha must have shape ({m}, {m}) to match the TDOAs, got {a.shape}")
            if not np.all(np.isfinite(a)) or np.any(a < 0):
                raise ValueError("alpha must be finite and non-negative")
            if not np.allclose(a, a.T, rtol=1e-9, atol=1e-12):
                raise ValueError("alpha must be symmetric (alpha[l, m] == alpha[m, l])")
            object.__setattr__(self, "alpha", _frozen(0.5 * (a + a.T)))

    @property
    def m(self) -> int:
        """Number of TDOAs."""
        return int(self.taus.shape[0])

    @property
    def model(self) -> TdoaModel:
        """The measurement model of all TDOAs (:class:`factors.tdoa_model.TdoaModel`)."""
        return self._model

    @property
    def max_delay_s(self) -> NDArray[np.float64]:
        """Largest physically possible ``|tau|`` of each TDOA, ``|s_i - s_j|/c``, s, shape (M,)."""
        s = self.sensors
        return np.linalg.norm(s[self.pairs[:, 0]] - s[self.pairs[:, 1]], axis=1) / self.c

    def subset(self, index: ArrayLike) -> WindowTdoas:
        """The TDOAs at `index` (int array or boolean mask), with their part of ``alpha``."""
        idx = np.arange(self.m)[np.asarray(index)]
        alpha = None if self.alpha is None else self.alpha[np.ix_(idx, idx)]
        return WindowTdoas(self.sensors, self.pairs[idx], self.taus[idx], self.sigmas[idx],
                           c=self.c, alpha=alpha)

    def predicted(self, positions: ArrayLike) -> NDArray[np.float64]:
        """Model delays ``d_m`` (eq. 14) at positions (..., 3) m: shape (..., M), s."""
        p = np.asarray(positions, dtype=float)
        d = np.sqrt(((p[..., None, :] - self.sensors) ** 2).sum(-1))  # |p - s_i|, (..., n)
        return (d[..., self.pairs[:, 0]] - d[..., self.pairs[:, 1]]) / self.c  # eq. (14)


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
            object.__setattr__(self, name, _frozen(a))

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(nx, ny, nz)``."""
        return (self.x.size, self.y.size, self.z.size)

    @property
    def size(self) -> int:
        """Number of grid points."""
        return int(np.prod(self.shape))

    @property
    def step(self) -> float:
        """Largest spacing along the axes that have more than one point, m (0 for one point)."""
        steps = [float(np.max(np.diff(a))) for a in (self.x, self.y, self.z) if a.size > 1]
        return max(steps) if steps else 0.0

    def points(self, start: int = 0, stop: int | None = None) -> NDArray[np.float64]:
        """Grid points ``start:stop`` in flat (C, ``ij``) order, shape (k, 3), m."""
        stop = self.size if stop is None else min(stop, self.size)
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
            if lo is not None and hi is not None:
                ax = np.unique(np.clip(ax, lo[a], hi[a]))
            axes.append(ax)
        return cls(*axes)


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


def smoothing_sigma(sigmas: ArrayLike, step: float, *, c: float, cells: float = 1.0
                    ) -> NDArray[np.float64]:
    """Delay smoothing ``sigma_t`` of eq. (16) for a grid of spacing `step`.

    Parameters
    ----------
    sigmas : array_like, shape (M,)
        TDOA standard deviations, s.
    step : float
        Grid spacing, m.
    c : float, keyword-only
        Sound speed, m/s.
    cells : float, keyword-only
        Grid cells whose delay span is added (in quadrature) to the TDOA sigma.

    Returns
    -------
    ndarray, shape (M,)
        ``sqrt(sigma_m^2 + (cells step / c)^2)``, s: a hyperbola passing anywhere through a
        cell keeps a sizeable intensity at the cell's centre (the delay changes by at most
        ``2 step / c`` per cell).
    """
    s = np.asarray(sigmas, dtype=float)
    return np.sqrt(s**2 + (cells * step / c) ** 2)


def tdoa_intensities(points: ArrayLike, tdoas: WindowTdoas, sigma_t: ArrayLike
                     ) -> NDArray[np.float64]:
    """Per-TDOA intensities ``I_m`` of eq. (16) at points.

    Parameters
    ----------
    points : array_like, shape (P, 3)
        Positions, m.
    tdoas : WindowTdoas
        The TDOAs.
    sigma_t : float or array_like, shape (M,)
        Delay smoothing, s.

    Returns
    -------
    ndarray, shape (P, M)
        ``exp(-(d_m(p) - tau_m)^2 / (2 sigma_t^2))``.
    """
    r = (tdoas.predicted(points) - tdoas.taus) / np.asarray(sigma_t, dtype=float)
    return np.exp(-0.5 * r * r)  # eq. (16)


def associated_intensity(intensities: ArrayLike, alpha: ArrayLike) -> NDArray[np.float64]:
    """Association-weighted intensity of eq. (18) from the per-TDOA intensities.

    Parameters
    ----------
    intensities : array_like, shape (P, M)
        ``I_m`` at P points (:func:`tdoa_intensities`).
    alpha : array_like, shape (M, M)
        Association measure ``alpha_lm``.

    Returns
    -------
    ndarray, shape (P,)
        ``sum_{l, m} alpha_lm I_l I_m``, one quadratic form ``I^T alpha I`` per point.

    Examples
    --------
    >>> i = np.array([[1.0, 0.5], [0.0, 1.0]])
    >>> associated_intensity(i, np.ones((2, 2)))  # (I_1 + I_2)^2
    array([2.25, 1.  ])
    """
    i = np.asarray(intensities, dtype=float)
    return np.einsum("pm,pm->p", i @ np.asarray(alpha, dtype=float), i)  # eq. (18)


@dataclass(frozen=True)
class IntensityVolume:
    """An intensity surface (eq. 17 or 18) sampled on a grid.

    Attributes
    ----------
    grid : SearchGrid
        Where it was sampled.
    values : ndarray, shape grid.shape
        Intensity at each grid point (eq. 17: TDOAs; eq. 18: association-weighted pairs).
    equation : int
        17 or 18.
    sigma_t : ndarray, shape (M,)
        Delay smoothing used, s.
    """

    grid: SearchGrid
    values: NDArray[np.float64]
    equation: int
    sigma_t: NDArray[np.float64]

    def peak(self) -> tuple[NDArray[np.float64], float]:
        """Grid point of the largest value (m) and that value."""
        k = int(np.argmax(self.values))
        return self.grid.points(k, k + 1)[0], float(self.values.reshape(-1)[k])


def _check_equation(equation: int, tdoas: WindowTdoas) -> None:
    if equation not in (17, 18):
        raise ValueError(f"equation must be 17 (sum) or 18 (association-weighted), got {equation!r}")
    if equation == 18 and tdoas.alpha is None:
        raise ValueError("eq. (18) needs the association matrix alpha (WindowTdoas.alpha is None)")


def intensity_volume(
    tdoas: WindowTdoas,
    grid: SearchGrid,
    *,
    equation: int = 18,
    cells: float = 1.0,
    chunk_points: int = 8192,
    distances: NDArray[np.float64] | None = None,
) -> IntensityVolume:
    """Sample the intensity of eq. (17) or (18) on a grid, in chunks of points.

    Parameters
    ----------
    tdoas : WindowTdoas
        The window's TDOAs (``alpha`` required for eq. 18).
    grid : SearchGrid
        Grid (:meth:`SearchRegion.volume`, :meth:`SearchRegion.plane`, ...).
    equation : {17, 18}, keyword-only
        Plain sum of hyperbolas (17) or association-weighted sum of pairs (18).
    cells : float, keyword-only
        Smoothing in grid cells (:func:`smoothing_sigma`).
    chunk_points : int, keyword-only
        Grid points evaluated at once (memory ``chunk_points x M`` floats).
    distances : ndarray, shape (grid.size, n), optional, keyword-only
        Ranges from the grid points to the sensors, m (:func:`sensor_distances`): a cache for
        grids used again and again (the coarse grid of every window of one array).

    Returns
    -------
    IntensityVolume

    Notes
    -----
    Eq. (16)-(18) of *Localization of Short Duration Periodic Signals*; eq. (18) from the
    per-TDOA intensities computed once (the text's suggestion), as ``I^T alpha I``.

    Examples
    --------
    >>> s = np.array([[0, 0, 0], [100.0, 0, 0], [0, 100, 0], [0, 0, 100]])
    >>> pairs = np.array([[0, 1], [0, 2], [0, 3]])
    >>> w = WindowTdoas(s, pairs, [0.0, 0.0, 0.0], [1e-4] * 3, c=1500.0)
    >>> v = intensity_volume(w, SearchGrid.centred([50, 50, 50], 10.0, 2), equation=17)
    >>> v.peak()
    (array([50., 50., 50.]), 3.0)
    """
    _check_equation(equation, tdoas)
    if int(chunk_points) < 1:
        raise ValueError(f"chunk_points must be a positive integer, got {chunk_points!r}")
    sig = smoothing_sigma(tdoas.sigmas, grid.step, c=tdoas.c, cells=cells)
    out = np.empty(grid.size)
    first, second = tdoas.pairs[:, 0], tdoas.pairs[:, 1]
    if distances is not None and np.shape(distances) != (grid.size, tdoas.sensors.shape[0]):
        raise ValueError(f"distances must have shape ({grid.size}, {tdoas.sensors.shape[0]}), "
                         f"got {np.shape(distances)}")
    for start in range(0, grid.size, int(chunk_points)):
        stop = min(start + int(chunk_points), grid.size)
        if distances is None:
            i = tdoa_intensities(grid.points(start, stop), tdoas, sig)
        else:  # eq. (16) from the cached ranges |p - s_i|
            d = distances[start:stop]
            r = ((d[:, first] - d[:, second]) / tdoas.c - tdoas.taus) / sig
            i = np.exp(-0.5 * r * r)
        out[start:start + i.shape[0]] = (i.sum(axis=1) if equation == 17  # eq. (17)
                                         else associated_intensity(i, tdoas.alpha))  # eq. (18)
    return IntensityVolume(grid, out.reshape(grid.shape), equation, sig)


def sensor_distances(grid: SearchGrid, sensors: ArrayLike, *, chunk_points: int = 8192
                     ) -> NDArray[np.float64]:
    """Ranges ``|p - s_i|`` from every grid point to every sensor, shape (grid.size, n), m."""
    s = np.asarray(sensors, dtype=float)
    centre = s.mean(axis=0)
    sc = s - centre  # centred: |p - s|^2 = |p|^2 + |s|^2 - 2 p.s loses little precision
    out = np.empty((grid.size, s.shape[0]))
    for start in range(0, grid.size, int(chunk_points)):
        p = grid.points(start, start + int(chunk_points)) - centre
        d2 = (p * p).sum(1)[:, None] + (sc * sc).sum(1)[None, :] - 2.0 * (p @ sc.T)
        out[start:start + p.shape[0]] = np.sqrt(np.maximum(d2, 0.0))
    return out


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
    equation : {17, 18}, keyword-only
        Which intensity.
    cells : float, keyword-only
        Smoothing in grid cells (:func:`smoothing_sigma`).
    max_points : int, keyword-only
        Largest number of heights (the spacing widens to fit).

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
    _check_equation(equation, tdoas)
    p = np.asarray(point, dtype=float)
    n = int(min(max_points, max(2, np.ceil((z_range[1] - z_range[0]) / step) + 1)))
    z = np.linspace(z_range[0], z_range[1], n)
    column = np.column_stack([np.full(n, p[0]), np.full(n, p[1]), z])
    sig = smoothing_sigma(tdoas.sigmas, max(step, float(z[1] - z[0])), c=tdoas.c, cells=cells)
    i = tdoa_intensities(column, tdoas, sig)
    values = i.sum(axis=1) if equation == 17 else associated_intensity(i, tdoas.alpha)
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

    Returns
    -------
    position : ndarray, shape (3,)
        Refined peak, m.
    value : float
        Intensity there (with the last level's smoothing).
    step : float
        Spacing of the last level, m.
    """
    _check_equation(equation, tdoas)
    if not shrink > 1.0 or int(half) < 1:
        raise ValueError(f"shrink must exceed 1 and half be >= 1, got {shrink!r}, {half!r}")
    if levels is None:
        target = fine_step(tdoas)
        levels = max(0, int(np.ceil(np.log(max(step, target) / target) / np.log(shrink))))
    pos = np.asarray(start, dtype=float).copy()
    if int(levels) == 0:
        i = tdoa_intensities(pos[None], tdoas, smoothing_sigma(tdoas.sigmas, step, c=tdoas.c,
                                                                cells=cells))
        value = i.sum() if equation == 17 else associated_intensity(i, tdoas.alpha)[0]
        return pos, float(value), step
    for _ in range(int(levels)):
        step = step / shrink
        grid = SearchGrid.centred(pos, step, int(half), lo=lo, hi=hi)
        vol = intensity_volume(tdoas, grid, equation=equation, cells=cells)
        pos, value = vol.peak()
    return pos, value, step
