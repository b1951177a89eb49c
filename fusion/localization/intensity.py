"""Hyperbolic intensity surfaces of a window's TDOAs (eq. 16-18).

A window's validated TDOAs (:class:`~fusion.localization.window_tdoas.WindowTdoas`) are drawn as
smoothed hyperbolas on a grid: each TDOA ``m`` gives the intensity ``I_m`` of eq. (16); their
sum is eq. (17); the sum of products of pairs weighted by the cross-pair association ``alpha``
is eq. (18), computed from the ``I_m`` once as one quadratic form per grid point,
``I^T alpha I``. A plane at an assumed depth and a 3-D volume over depths use the same code (a
plane is a volume with one depth). The delay smoothing ``sigma_t`` of eq. (16) is the TDOA sigma
widened by the delay a cell spans, :func:`smoothing_sigma`, so a coarse grid never misses a
hyperbola.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (14)-(18) (steps 56-60) and step 62 (a
volume over depths). Evaluation is chunked over grid points (``chunk_points``), so memory stays
at ``chunk_points x M`` floats whatever the grid size. Eq. (16) is evaluated from the ranges
to the sensors held sensor by sensor (contiguous rows, cached for the coarse grid), TDOA row by
TDOA row in passes of ``_SUB_POINTS`` points, and handed to eq. (17)/(18) in the memory order
of the column form (``d[:, first] - d[:, second]``), so that their sums add in the same order:
the same bits as the column form, in about half its time.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.localization.search_grid import SearchGrid
from fusion.localization.window_tdoas import WindowTdoas
from fusion.types import frozen_array

__all__ = [
    "IntensityVolume",
    "associated_intensity",
    "check_equation",
    "combine_intensities",
    "intensity_volume",
    "smoothing_sigma",
    "tdoa_intensities",
]


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
    groups : ndarray of int, shape (M,), optional
        The measurement each TDOA column reads (see :func:`combine_intensities`); None: one
        column per measurement.
    """

    grid: SearchGrid
    values: NDArray[np.float64]
    equation: int
    sigma_t: NDArray[np.float64]
    groups: NDArray[np.intp] | None = None

    def peak(self) -> tuple[NDArray[np.float64], float]:
        """Grid point of the largest value (m) and that value."""
        k = int(np.argmax(self.values))
        return self.grid.points(k, k + 1)[0], float(self.values.reshape(-1)[k])


def check_equation(equation: int, tdoas: WindowTdoas) -> None:
    """Raise ValueError unless `equation` is 17, or 18 with ``alpha`` present."""
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
    groups: ArrayLike | None = None,
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
    groups : array_like of int, shape (M,), optional, keyword-only
        The measurement each TDOA column reads (:func:`combine_intensities`).

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
    check_equation(equation, tdoas)
    if int(chunk_points) < 1:
        raise ValueError(f"chunk_points must be a positive integer, got {chunk_points!r}")
    sig = smoothing_sigma(tdoas.sigmas, grid.step, c=tdoas.c, cells=cells)
    out = np.empty(grid.size)
    if distances is not None and np.shape(distances) != (grid.size, tdoas.sensors.shape[0]):
        raise ValueError(f"distances must have shape ({grid.size}, {tdoas.sensors.shape[0]}), "
                         f"got {np.shape(distances)}")
    by_sensor = None if distances is None else _by_sensor(distances)
    for start in range(0, grid.size, int(chunk_points)):
        stop = min(start + int(chunk_points), grid.size)
        if by_sensor is None:  # the ranges |p - s_i| of WindowTdoas.predicted, by sensor
            diff = grid.points(start, stop)[None, :, :] - tdoas.sensors[:, None, :]
            i, alpha = _ranged_intensities(np.sqrt((diff**2).sum(-1)), 0, stop - start, tdoas,
                                           sig, groups)
        else:
            i, alpha = _ranged_intensities(by_sensor, start, stop, tdoas, sig, groups)
        out[start:stop] = i.sum(axis=1) if equation == 17 else associated_intensity(i, alpha)
    return IntensityVolume(grid, out.reshape(grid.shape), equation, sig,
                           None if groups is None else np.asarray(groups, dtype=np.intp))


#: Grid points per pass of the per-TDOA arithmetic on cached ranges (its arrays stay in cache).
_SUB_POINTS = 1024


def _by_sensor(distances: NDArray[np.float64]) -> NDArray[np.float64]:
    """The ranges (P, n) as contiguous rows per sensor (n, P): a view when they are stored so
    (:func:`fusion.localization.search_grid.sensor_distances`)."""
    return np.ascontiguousarray(np.asarray(distances, dtype=float).T)


def _ranged_intensities(by_sensor: NDArray[np.float64], start: int, stop: int,
                        tdoas: WindowTdoas, sig: NDArray[np.float64], groups: ArrayLike | None
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """Eq. (16) of grid points ``start:stop`` from the cached ranges, each measurement's best
    column taken when `groups` are given (:func:`combine_intensities`), and the ``alpha`` of
    the columns returned.

    The arithmetic of :func:`tdoa_intensities` and :func:`_best_column`, value for value,
    done per TDOA row over passes of :data:`_SUB_POINTS` points (rows of contiguous ranges,
    not gathered columns), and returned in the memory order the column form has (columns
    outermost without `groups`, rows outermost with them), so the sums and products that
    follow add in the same order: the same bits.
    """
    first, second = tdoas.pairs[:, 0], tdoas.pairs[:, 1]
    taus, sg = tdoas.taus[:, None], sig[:, None]
    n = stop - start
    alpha = tdoas.alpha
    if groups is None:
        cols = np.empty((tdoas.m, n))
    else:
        best, ranks = _column_ranks(np.asarray(groups, dtype=np.intp).tobytes())
        rows = np.empty((n, best.size))
        alpha = None if alpha is None else np.asarray(alpha)[np.ix_(best, best)]
    for a in range(start, stop, _SUB_POINTS):
        b = min(a + _SUB_POINTS, stop)
        r = ((by_sensor[first, a:b] - by_sensor[second, a:b]) / tdoas.c - taus) / sg
        i = np.exp(-0.5 * r * r)  # eq. (16), (M, b - a)
        if groups is None:
            cols[:, a - start:b - start] = i
            continue
        top = i[best]
        for slots, columns in ranks:
            top[slots] = np.maximum(top[slots], i[columns])
        rows[a - start:b - start] = top.T
    return (cols.T if groups is None else rows), alpha


def combine_intensities(intensities: ArrayLike, tdoas: WindowTdoas, equation: int,
                        groups: ArrayLike | None = None) -> NDArray[np.float64]:
    """Eq. (17) or eq. (18) from the per-column intensities ``I_m`` of eq. (16).

    Parameters
    ----------
    intensities : array_like, shape (P, M)
        ``I_m`` of each column at P points (:func:`tdoa_intensities`).
    tdoas : WindowTdoas
        The TDOA columns (``alpha`` for eq. 18).
    equation : {17, 18}
        Which intensity.
    groups : array_like of int, shape (M,), optional
        The measurement each column reads (one measured delay read along several propagation
        paths, :mod:`fusion.localization.surface_paths`): a measurement's intensity is the largest of
        its columns' (the union of its hyperbolas, counted once), and eq. (18) uses the
        association of each measurement's first column.

    Returns
    -------
    ndarray, shape (P,)

    Examples
    --------
    >>> s = np.array([[0, 0, 0], [100.0, 0, 0]])
    >>> w = WindowTdoas(s, np.array([[0, 1], [0, 1]]), [0.0, 0.0], [1e-4, 1e-4], c=1500.0)
    >>> combine_intensities([[1.0, 0.5]], w, 17), combine_intensities([[1.0, 0.5]], w, 17, [0, 0])
    (array([1.5]), array([1.]))
    """
    i = np.asarray(intensities, dtype=float)
    alpha = tdoas.alpha
    if groups is not None:
        i, first = _best_column(i, np.asarray(groups, dtype=np.intp))
        alpha = None if alpha is None else np.asarray(alpha)[np.ix_(first, first)]
    if equation == 17:
        return i.sum(axis=1)  # eq. (17)
    return associated_intensity(i, alpha)  # eq. (18)


def _best_column(intensities: NDArray[np.float64], groups: NDArray[np.intp]
                 ) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Largest column of each group (groups in increasing order) and each group's first column.

    The columns of a group are taken in rank order (first, second, ... column of the group):
    one vectorised maximum per rank (at most the number of path pairs), on contiguous copies
    rather than a strided ``maximum.reduceat`` over the permuted columns; the same values.
    """
    first, ranks = _column_ranks(groups.tobytes())
    out = intensities[:, first]
    for slots, columns in ranks:
        out[:, slots] = np.maximum(out[:, slots], intensities[:, columns])
    # row-major like the input: the sums and products that follow then add in the same order
    return np.ascontiguousarray(out), first


@lru_cache(maxsize=256)
def _column_ranks(groups: bytes) -> tuple[NDArray[np.intp], tuple]:
    """Of the groups (intp bytes): each group's first column, and per further rank r the group
    slots and columns of rank r (the plan of :func:`_best_column`, the same for every surface
    of a window)."""
    g = np.frombuffer(groups, dtype=np.intp)
    order = np.argsort(g, kind="stable")
    sorted_g = g[order]
    starts = np.flatnonzero(np.r_[True, sorted_g[1:] != sorted_g[:-1]])
    which = np.cumsum(np.r_[False, sorted_g[1:] != sorted_g[:-1]])  # group slot of each column
    rank = np.arange(order.size) - starts[which]  # position of each column in its group
    ranks = tuple((frozen_array(which[rank == r], np.intp), frozen_array(order[rank == r], np.intp))
                  for r in range(1, int(rank.max(initial=0)) + 1))
    return frozen_array(order[starts], np.intp), ranks
