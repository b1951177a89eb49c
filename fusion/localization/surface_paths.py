"""A window's TDOAs read along direct and surface-reflected paths (image sensors).

Bottom-mounted hydrophones hear each click twice: along the direct path and reflected at the sea
surface. The front end's valid TDOAs therefore include delays between surface echoes
(``surface``), and between a direct arrival at one sensor and an echo at the other
(``direct-surface``, ``surface-direct``), besides the direct ones. Read as direct delays they are
clutter that can fit a ghost source; read along their paths they are more delays of the same
whale.

A path reflected at the surface ``z = z_s`` from ``p`` to sensor ``s`` is as long as the direct
path from ``p`` to the sensor's image ``s' = (x, y, 2 z_s - z)``. :func:`surface_paths` appends
the images to the sensors and reads every measured delay four times, once per path pair, on
the real or image sensors: the columns of one measurement compete as one (the competition's
``groups``), and the association ``alpha`` of two columns is that of their measurements. The
surface image of a source explains the same delays with the paths swapped, so the search is
limited to the water column below the surface.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (14): the model delay of a TDOA, here
along each propagation path (the surface reflection is the image method of underwater acoustic
propagation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import surface_image
from fusion.localization.window_tdoas import WindowTdoas
from fusion.types import frozen_array

__all__ = ["PATHS", "SEA_SURFACE_Z", "PathTdoas", "surface_paths"]

#: Height of the sea surface in the project's convention (z up, formats section 2), m.
SEA_SURFACE_Z = 0.0

#: Path pairs of the columns, in column-block order: (path to sensor i, path to sensor j).
PATHS: tuple[str, ...] = ("direct", "surface", "direct-surface", "surface-direct")


@dataclass(frozen=True)
class PathTdoas:
    """A window's TDOAs with one column per (measurement, path pair).

    Attributes
    ----------
    tdoas : WindowTdoas
        Sensors ``(2n, 3)``: the ``n`` real ones, then their surface images; ``4 M`` columns,
        block ``h`` (of :data:`PATHS`) holding every measurement read along path pair ``h``.
    measured : ndarray of int, shape (4 M,)
        The measurement of each column.
    path : ndarray of int, shape (4 M,)
        The path pair of each column (index into :data:`PATHS`).
    n_measured : int
        Number of measured TDOAs, M.
    surface_z : float
        Height of the surface, m.
    """

    tdoas: WindowTdoas
    measured: NDArray[np.intp]
    path: NDArray[np.intp]
    n_measured: int
    surface_z: float

    def collapse(self, weights: ArrayLike) -> NDArray[np.float64]:
        """Column weights summed per measurement: shape (..., 4 M) -> (..., M)."""
        w = np.asarray(weights, dtype=float)
        return w.reshape(w.shape[:-1] + (len(PATHS), self.n_measured)).sum(axis=-2)

    def paths_of(self, weights: ArrayLike) -> NDArray[np.intp]:
        """Path pair of each measurement in one source's column weights (4 M,), -1 if unheld.

        A measurement is held along the path pair of its heaviest column when the weights of
        its columns sum to more than one half.
        """
        w = np.asarray(weights, dtype=float).reshape(len(PATHS), self.n_measured)
        return np.where(w.sum(axis=0) > 0.5, np.argmax(w, axis=0), -1).astype(np.intp)


def surface_paths(tdoas: WindowTdoas, surface_z: float) -> PathTdoas:
    """Read every TDOA along the four direct/surface-reflected path pairs.

    Parameters
    ----------
    tdoas : WindowTdoas
        The window's measured TDOAs, sensors below the surface.
    surface_z : float
        Height of the sea surface, m (0 in the project's convention, z up).

    Returns
    -------
    PathTdoas

    Examples
    --------
    >>> s = np.array([[0.0, 0, -1000], [1000, 0, -1000], [0, 1000, -1000], [500, 500, -990]])
    >>> w = WindowTdoas(s, np.array([[0, 1], [0, 2], [0, 3]]), [0.0, 0.0, 0.0], [1e-5] * 3,
    ...                 c=1500.0)
    >>> p = surface_paths(w, 0.0)
    >>> p.tdoas.m, p.tdoas.sensors[4], p.tdoas.pairs[3 * 2].tolist()  # image of sensor 0; (0, 1')
    (12, array([   0.,    0., 1000.]), [0, 5])
    """
    zs = float(surface_z)
    if not np.isfinite(zs):
        raise ValueError(f"surface_z must be finite, got {surface_z!r}")
    s = np.asarray(tdoas.sensors)
    if not np.all(s[:, 2] < zs):
        raise ValueError(f"every sensor must lie below the surface z = {zs:g} m")
    n, m = s.shape[0], tdoas.m
    images = surface_image(s, zs)
    i, j = np.asarray(tdoas.pairs).T
    # the columns of path pair h: sensor i (or its image), sensor j (or its image)
    first = np.concatenate([i, i + n, i, i + n])
    second = np.concatenate([j, j + n, j + n, j])
    alpha = None if tdoas.alpha is None else np.kron(np.ones((len(PATHS), len(PATHS))),
                                                     np.asarray(tdoas.alpha))
    wide = WindowTdoas(np.vstack([s, images]), np.column_stack([first, second]),
                       np.tile(tdoas.taus, len(PATHS)), np.tile(tdoas.sigmas, len(PATHS)),
                       c=tdoas.c, alpha=alpha)
    return PathTdoas(wide, frozen_array(np.tile(np.arange(m), len(PATHS)), np.intp),
                     frozen_array(np.repeat(np.arange(len(PATHS)), m), np.intp), m, zs)
