"""What every clutter map provides: hotspots with an extent, and the distance to them.

Section 2.4 of "Target tracking using fuzzy logic association" ("Clutter map"): the positions of
all detections are stored event by event, and a location from which detections come back on more
than a set fraction of the events becomes a *hotspot*; the distance from a new detection to the
nearest hotspot is an input of the fuzzy rank. The paper does not say what "a location" is; the
implementations differ exactly there (:class:`fusion.active.clutter.grid.ClutterMap`: fixed grid
cells; :class:`fusion.active.clutter.density.DensityClutterMap`: each detection's own error
ellipse). Both report :class:`Hotspots`: clusters with a centre and a covariance, whose *region*
is the ellipse holding a set fraction of the feature's echoes.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["ClutterMapBase", "Hotspots", "floor_covariance"]


def floor_covariance(cov: NDArray[np.float64], err: NDArray[np.float64]) -> NDArray[np.float64]:
    """Raise each 2 x 2 covariance to at least the error covariance ``E`` (Loewner order).

    Parameters
    ----------
    cov, err : ndarray, shape (n, 2, 2)
        Covariances ``C`` and floors ``E`` (positive definite), m^2.

    Returns
    -------
    ndarray, shape (n, 2, 2)
        With ``E = L L^T`` (Cholesky), the eigenvalues of ``L^-1 C L^-T`` raised to at least 1
        and mapped back: the smallest covariance whose ellipse contains both ellipses along
        the eigenvectors of ``E^-1/2 C E^-1/2``. For ``E = sigma^2 I`` every eigenvalue of ``C``
        is raised to at least ``sigma^2``.
    """
    L = np.linalg.cholesky(err)
    Li = np.linalg.inv(L)
    w, v = np.linalg.eigh(Li @ cov @ np.swapaxes(Li, 1, 2))
    inner = np.einsum("nij,nj,nkj->nik", v, np.maximum(w, 1.0), v)
    return L @ inner @ np.swapaxes(L, 1, 2)


@dataclass(frozen=True)
class Hotspots:
    """Hotspots of a clutter map at one moment.

    Attributes
    ----------
    positions : ndarray, shape (n, 2)
        Hotspot centres (x east, y north), m: mean position of the detections in the hotspot's
        cells.
    covariances : ndarray, shape (n, 2, 2)
        Spread of each hotspot's detections, m^2 (sample covariance, raised to at least the mean
        position-error covariance of its detections).
    gate : float
        Mahalanobis radius ``g`` of the hotspot regions (dimensionless).
    visits : ndarray of int, shape (n,)
        Largest number of pings on which a cell of each hotspot was visited.
    cells : ndarray of int, shape (n,)
        Number of hot cells in each hotspot.
    n_pings : int
        Pings seen by the map.
    """

    positions: NDArray[np.float64]
    covariances: NDArray[np.float64]
    gate: float
    visits: NDArray[np.int64]
    cells: NDArray[np.int64]
    n_pings: int

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    def distance(self, xy: ArrayLike) -> NDArray[np.float64]:
        """Distance from each point to the nearest hotspot region.

        Parameters
        ----------
        xy : array_like, shape (k, 2)
            Points (x east, y north), m.

        Returns
        -------
        ndarray, shape (k,)
            ``min over hotspots of |p - c| (1 - g / m)`` clipped at 0 (``m``: Mahalanobis
            distance of ``p`` from the hotspot), m; ``inf`` everywhere when there is no hotspot.
        """
        pts = np.asarray(xy, dtype=float).reshape(-1, 2) if np.size(xy) else np.zeros((0, 2))
        if len(self) == 0:
            return np.full(pts.shape[0], np.inf)
        delta = pts[:, None, :] - self.positions[None]                  # (k, n, 2)
        c = self.covariances
        det = c[:, 0, 0] * c[:, 1, 1] - c[:, 0, 1] ** 2
        # Squared Mahalanobis distance with the closed-form inverse of each 2 x 2 covariance.
        m2 = (delta[..., 0] ** 2 * c[:, 1, 1] - 2.0 * delta[..., 0] * delta[..., 1] * c[:, 0, 1]
              + delta[..., 1] ** 2 * c[:, 0, 0]) / det
        r = np.hypot(delta[..., 0], delta[..., 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            beyond = np.where(m2 > self.gate**2, r * (1.0 - self.gate / np.sqrt(m2)), 0.0)
        return beyond.min(axis=1)



class ClutterMapBase(ABC):
    """An online clutter map: fed one ping at a time, asked for its hotspots.

    Subclasses are configured in their constructor; :meth:`update` adds a ping,
    :meth:`hotspots` lists the current hotspots, :meth:`distance` measures the distance to the
    nearest hotspot region and :meth:`empty_copy` gives a map with the same options and no
    content (a tracker's reset).
    """

    #: Default position-error standard deviation of a detection, m (set by each subclass).
    position_sigma_m: float
    #: Pings seen, time of the first ping (s) and the cached hotspots (set by each subclass).
    n_pings: int
    _t0: float | None
    _cache: object

    def update(
        self, xy: ArrayLike, time: float | None = None, *, cov: ArrayLike | None = None
    ) -> None:
        """Add the detections of one ping.

        Parameters
        ----------
        xy : array_like, shape (n, 2)
            Detection positions (x east, y north), m; n may be 0 (the ping still counts).
        time : float, optional
            Ping time, s (for the drift test); default: the ping's index.
        cov : array_like, shape (n, 2, 2), optional
            Position-error covariance of each detection, m^2, positive definite (default
            ``position_sigma_m**2 I``).

        Raises
        ------
        ValueError
            Wrong shape or non-finite values.
        """
        pts, c = self._checked(xy, cov)
        t_rel = self._next_ping(time)
        self._add_ping(pts, c, t_rel)

    @abstractmethod
    def _add_ping(self, pts: NDArray[np.float64], cov: NDArray[np.float64], t_rel: float) -> None:
        """Store one ping's checked detections (:meth:`update`; the ping is already counted:
        its number is ``n_pings - 1``, its time `t_rel` s from the first ping's)."""

    def _checked(self, xy: ArrayLike, cov: ArrayLike | None) -> tuple[NDArray, NDArray]:
        """A ping's positions (n, 2) and covariances (n, 2, 2), checked; the covariances default
        to ``position_sigma_m**2 I`` (the subclass's option). Both are fresh arrays."""
        pts = np.asarray(xy, dtype=float).reshape(-1, 2) if np.size(xy) else np.zeros((0, 2))
        if not np.all(np.isfinite(pts)):
            raise ValueError("clutter map: detection positions must be finite")
        if cov is None:
            c = np.broadcast_to(np.eye(2) * self.position_sigma_m**2, (pts.shape[0], 2, 2)).copy()
        else:
            c = np.array(cov, dtype=float)
            if c.shape != (pts.shape[0], 2, 2) or not np.all(np.isfinite(c)):
                raise ValueError(f"clutter map: cov must be finite, shape ({pts.shape[0]}, 2, 2), "
                                 f"got shape {c.shape}")
            if np.any(c[:, 0, 0] <= 0) or np.any(c[:, 0, 0] * c[:, 1, 1] - c[:, 0, 1] ** 2 <= 0):
                raise ValueError("clutter map: cov must be positive definite")
        return pts, c

    def _next_ping(self, time: float | None) -> float:
        """Count a new ping and return its time from the first ping's, s (checked finite).

        `time` None stands for the ping's index. Clears the subclass's hotspot cache.
        """
        t = float(self.n_pings if time is None else time)
        if not np.isfinite(t):
            raise ValueError("clutter map: ping time must be finite")
        if self._t0 is None:
            self._t0 = t
        self.n_pings += 1
        self._cache = None
        return t - self._t0

    @abstractmethod
    def hotspots(self) -> Hotspots:
        """The current hotspots."""

    @abstractmethod
    def empty_copy(self) -> ClutterMapBase:
        """A map with the same options and no content."""

    def distance(self, xy: ArrayLike) -> NDArray[np.float64]:
        """Distance from each point to the nearest hotspot region.

        Parameters
        ----------
        xy : array_like, shape (n, 2)
            Points (x east, y north), m.

        Returns
        -------
        ndarray, shape (n,)
            Distance, m (0 inside a hotspot region); ``inf`` everywhere when the map has no
            hotspot. See :meth:`Hotspots.distance`.
        """
        return self.hotspots().distance(xy)
