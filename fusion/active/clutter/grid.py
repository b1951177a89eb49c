"""Grid clutter map: where detections come back ping after ping, counted in fixed cells.

Implements Section 2.4 ("Clutter map") of "Target tracking using fuzzy logic association": every
detection position is stored per event (ping); a location from which detections arrive on more
than a set fraction of the events becomes a *hotspot*, and the distance from a new detection to
the nearest hotspot is one input of the fuzzy association (rule "IF hotspot is near THEN rank is
low", Section 4).

The paper does not say how "a location" is defined, nor how big a hotspot is. Here:

- *Neighbourhood count.* Space is cut into square cells of side ``cell_m``; a cell counts as
  *visited* on a ping when a detection of that ping falls in the cell or in one of its eight
  neighbours (a 3 x 3 smoothing of the per-ping occupancy), so that a fixed feature whose echoes
  scatter across cell borders still visits its cells on every ping. A cell is *hot* when it holds
  at least one detection and has been visited on at least ``min_pings`` pings and on more than
  ``fraction`` of all pings seen so far.
- *Hotspots are clusters with an extent.* Hot cells that touch (8-connectivity) form one hotspot.
  Its centre is the mean of the detections stored in its cells and its covariance ``C`` is their
  sample covariance, raised to at least the mean position-error covariance ``E`` of those
  detections (a feature cannot look smaller than the position error of one detection): the
  eigenvalues of ``E^-1/2 C E^-1/2`` are raised to at least 1, so the result contains both
  ellipses. ``E`` is the mean of the per-detection covariances given to :meth:`ClutterMap.update`
  (e.g. bistatic error ellipses, long across the line of sight of a far receiver), or
  ``position_sigma_m**2 I`` for detections given without one. The hotspot *region* is the
  ellipse ``(p - c)^T C^-1 (p - c) <= g^2`` with ``g^2`` the chi-square quantile (2 degrees of
  freedom) of ``extent_probability``: the region that holds that fraction of the feature's echoes.
- *Distance to a hotspot* is the distance from a point to that region along the line from the
  hotspot centre: ``|p - c| (1 - g / m)`` with ``m`` the Mahalanobis distance of ``p``, and 0 inside
  the region. So an echo of the feature that position noise has thrown to the edge of its spread
  is still "near" the hotspot, whereas a distance to the centre alone would call it far.
- *Hotspots stand still.* A cluster whose detections drift over ping time (least-squares drift
  of position on time significant at ``drift_probability`` against the scatter left around the
  drift) is a moving object, e.g. a slow target seen by several receivers, not a hotspot. The
  test needs a few pings of history: on the ``min_pings``-th ping a slow target and a feature
  look alike.

A target moving at speed ``v`` with ping interval ``T`` stays in one 3 x 3 neighbourhood for about
``3 cell_m / (v T)`` pings, so it can pass the ``fraction`` test only early in a run (at ping ``n``
it needs more than ``0.4 n`` visits); a bottom feature echoing on most pings passes both tests
from its ``min_pings``-th ping on. The defaults (``cell_m`` = 150 m, about 1.5 times the position
error of a detection; ``min_pings`` = 3, the shortest track a tracker confirms) let the map flag a
feature before a 3-of-4 track on it can be confirmed. ``fraction`` = 0.4 rather than 1/2: a
feature seen by one receiver that echoes on 70 % of its pings has at most half of the pings
visited with probability 0.15 after 10 pings and 0.05 after 20 (binomial), and drops off the map
for those pings, long enough for a track to form on it; at 0.4 these probabilities are 0.05 and
0.005. The price is that a slow target's first positions stay hot a few pings longer; the
tracker's motion test (:func:`fusion.active.motion.motion_statistic`) keeps a target's tentative
track alive there. The map is sparse (only visited cells are
stored), unbounded in extent, and updated online, one ping at a time.
"""

from __future__ import annotations

import logging

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.stats import chi2

from fusion.active.clutter.base import ClutterMapBase, Hotspots, floor_covariance

__all__ = ["ClutterMap"]

logger = logging.getLogger(__name__)

# Cell indices are packed into one int64 key: (ix + _OFF) * _SPAN + (iy + _OFF).
_SPAN = np.int64(1 << 31)
_OFF = np.int64(1 << 30)
# Per-cell sums: x, y, xx, xy, yy, t, tt, tx, ty (t: ping time relative to the first ping), then
# the position-error covariance of the detections: cxx, cxy, cyy.
_NSUM = 12
_NEIGHBOURS = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)], dtype=np.int64)


class ClutterMap(ClutterMapBase):
    """Online grid clutter map with clustered hotspots (Section 2.4 of the paper).

    Parameters
    ----------
    cell_m : float, optional
        Grid cell side, m (default 150).
    fraction : float, optional
        A cell is hot when visited on more than this fraction of the pings seen (default 0.4),
        in (0, 1).
    min_pings : int, optional
        ... and on at least this many pings (default 3), >= 1.
    position_sigma_m : float, optional
        Position error of one detection per axis, m (default 100), for detections given to
        :meth:`update` without a covariance: the smallest spread a hotspot can have.
    extent_probability : float, optional
        Fraction of a hotspot's echoes inside its region (default 0.99), in (0, 1).
    drift_probability : float, optional
        Confidence of the drift test (default 0.99), in (0, 1): a cluster whose echoes move
        significantly over ping time is a moving object, not a hotspot.

    Notes
    -----
    :meth:`update` adds one ping; :meth:`hotspots` lists the current hotspots (cached until the
    next update); :meth:`distance` gives the distance from any points to the nearest hotspot
    region (``inf`` when there is none).

    Examples
    --------
    >>> cmap = ClutterMap(cell_m=100.0, position_sigma_m=20.0)
    >>> for _ in range(3):
    ...     cmap.update([[1000.0, 2000.0]])
    >>> d = cmap.distance([[1000.0, 2300.0], [1000.0, 2030.0]])
    >>> round(float(d[0]), 1), float(d[1])
    (239.3, 0.0)
    """

    def __init__(
        self,
        *,
        cell_m: float = 150.0,
        fraction: float = 0.4,
        min_pings: int = 3,
        position_sigma_m: float = 100.0,
        extent_probability: float = 0.99,
        drift_probability: float = 0.99,
    ) -> None:
        if not np.isfinite(cell_m) or cell_m <= 0:
            raise ValueError(f"cell_m must be a positive number, got {cell_m!r}")
        if not 0.0 < fraction < 1.0:
            raise ValueError(f"fraction must lie in (0, 1), got {fraction!r}")
        if isinstance(min_pings, bool) or int(min_pings) != min_pings or min_pings < 1:
            raise ValueError(f"min_pings must be an integer >= 1, got {min_pings!r}")
        if not np.isfinite(position_sigma_m) or position_sigma_m <= 0:
            raise ValueError(f"position_sigma_m must be a positive number, got {position_sigma_m!r}")
        if not 0.0 < extent_probability < 1.0:
            raise ValueError(f"extent_probability must lie in (0, 1), got {extent_probability!r}")
        self.cell_m = float(cell_m)
        self.fraction = float(fraction)
        self.min_pings = int(min_pings)
        self.position_sigma_m = float(position_sigma_m)
        self.extent_probability = float(extent_probability)
        self._gate = float(np.sqrt(chi2.ppf(self.extent_probability, 2)))
        if not 0.0 < drift_probability < 1.0:
            raise ValueError(f"drift_probability must lie in (0, 1), got {drift_probability!r}")
        self.drift_probability = float(drift_probability)
        self._drift_gate = float(chi2.ppf(self.drift_probability, 2))
        self.n_pings = 0
        self._t0: float | None = None
        # Sorted cell keys and, per cell: pings visited, detections inside, and the sums of
        # _NSUM moments of the detections' positions and ping times.
        self._keys = np.zeros(0, dtype=np.int64)
        self._visits = np.zeros(0, dtype=np.int64)
        self._count = np.zeros(0, dtype=np.int64)
        self._sum = np.zeros((0, _NSUM))
        self._cache: Hotspots | None = None

    def empty_copy(self) -> ClutterMap:
        """A map with the same options and no content."""
        return ClutterMap(cell_m=self.cell_m, fraction=self.fraction, min_pings=self.min_pings,
                          position_sigma_m=self.position_sigma_m,
                          extent_probability=self.extent_probability,
                          drift_probability=self.drift_probability)

    # ------------------------------------------------------------------------------------
    def _cells(self, xy: NDArray[np.float64]) -> NDArray[np.int64]:
        return np.floor(xy / self.cell_m).astype(np.int64)

    @staticmethod
    def _pack(ij: NDArray[np.int64]) -> NDArray[np.int64]:
        return (ij[:, 0] + _OFF) * _SPAN + (ij[:, 1] + _OFF)

    def _insert(self, new_keys: NDArray[np.int64]) -> None:
        """Add cells (sorted unique keys) not yet stored, keeping the keys sorted."""
        if self._keys.size:
            at = np.searchsorted(self._keys, new_keys)
            known = self._keys[np.minimum(at, self._keys.size - 1)] == new_keys
        else:
            at = np.zeros(new_keys.size, dtype=np.int64)
            known = np.zeros(new_keys.size, dtype=bool)
        fresh = ~known
        if not fresh.any():
            return
        # Insertion without re-sorting: new_keys is sorted, so are the insertion points.
        at = at[fresh]
        self._keys = np.insert(self._keys, at, new_keys[fresh])
        self._visits = np.insert(self._visits, at, 0)
        self._count = np.insert(self._count, at, 0)
        self._sum = np.insert(self._sum, at, 0.0, axis=0)

    def _add_ping(self, pts: NDArray[np.float64], c: NDArray[np.float64], t: float) -> None:
        """Count one ping's detections in their cells (:meth:`ClutterMapBase.update`); the mean
        of their covariances is the floor of a hotspot's extent."""
        if pts.shape[0] == 0:
            return
        cells = self._cells(pts)
        own = self._pack(cells)
        # Cells visited on this ping: each detection's cell and its 8 neighbours, once each.
        visited = np.unique(self._pack((cells[:, None, :] + _NEIGHBOURS[None]).reshape(-1, 2)))
        self._insert(visited)
        self._visits[np.searchsorted(self._keys, visited)] += 1
        idx = np.searchsorted(self._keys, own)
        np.add.at(self._count, idx, 1)
        x, y = pts[:, 0], pts[:, 1]
        tt = np.full(x.size, t)
        np.add.at(self._sum, idx, np.column_stack([x, y, x * x, x * y, y * y, tt, tt * t,
                                                   tt * x, tt * y, c[:, 0, 0], c[:, 0, 1],
                                                   c[:, 1, 1]]))

    def hotspots(self) -> Hotspots:
        """The current hotspots.

        Returns
        -------
        Hotspots
            One per group of touching hot cells (cells holding a detection, visited on
            ``>= min_pings`` pings and on more than ``fraction`` of all pings).
        """
        if self._cache is not None:
            return self._cache
        hot = np.flatnonzero(
            (self._visits >= self.min_pings)
            & (self._visits > self.fraction * self.n_pings)
            & (self._count > 0)
        )
        if hot.size == 0:
            self._cache = Hotspots(np.zeros((0, 2)), np.zeros((0, 2, 2)), self._gate,
                                   np.zeros(0, np.int64), np.zeros(0, np.int64), self.n_pings)
            return self._cache
        # Touching hot cells (8-connectivity) form one hotspot.
        keys = self._keys[hot]
        ij = np.column_stack([keys // _SPAN - _OFF, keys % _SPAN - _OFF])
        nb = self._pack((ij[:, None, :] + _NEIGHBOURS[None]).reshape(-1, 2))
        pos = np.minimum(np.searchsorted(keys, nb), keys.size - 1)
        edge = keys[pos] == nb
        rows = np.repeat(np.arange(keys.size), _NEIGHBOURS.shape[0])[edge]
        graph = coo_matrix((np.ones(rows.size), (rows, pos[edge])), shape=(keys.size, keys.size))
        n_spots, label = connected_components(graph, directed=False)
        count = np.bincount(label, weights=self._count[hot], minlength=n_spots)
        m = np.stack([np.bincount(label, weights=self._sum[hot, k], minlength=n_spots)
                      for k in range(_NSUM)], axis=1) / count[:, None]
        mean = m[:, :2]
        cov = np.empty((n_spots, 2, 2))
        cov[:, 0, 0] = m[:, 2] - mean[:, 0] ** 2
        cov[:, 0, 1] = cov[:, 1, 0] = m[:, 3] - mean[:, 0] * mean[:, 1]
        cov[:, 1, 1] = m[:, 4] - mean[:, 1] ** 2
        # No hotspot looks smaller than the position error of one detection.
        err = np.empty((n_spots, 2, 2))
        err[:, 0, 0], err[:, 1, 1] = m[:, 9], m[:, 11]
        err[:, 0, 1] = err[:, 1, 0] = m[:, 10]
        cov = floor_covariance(cov, err)
        visits = np.zeros(n_spots, np.int64)
        np.maximum.at(visits, label, self._visits[hot])
        cells = np.bincount(label, minlength=n_spots).astype(np.int64)
        keep = ~self._drifting(count, m, err)
        if not keep.all():
            logger.debug("clutter map: %d drifting cluster(s) are no hotspot", int((~keep).sum()))
        self._cache = Hotspots(mean[keep], cov[keep], self._gate, visits[keep], cells[keep],
                               self.n_pings)
        return self._cache

    def _drifting(
        self, count: NDArray[np.float64], m: NDArray[np.float64], err: NDArray[np.float64]
    ) -> NDArray[np.bool_]:
        """Clusters whose echoes move: least-squares drift significant at drift_probability.

        The drift ``v = cov(t, p) / var(t)`` of the detections' positions over ping time has
        covariance ``C_res / (n var(t))`` (``C_res``: the covariance left after removing the
        drift, floored at the mean position-error covariance ``err``); a cluster is drifting when
        ``v^T (C_res / (n var(t)))^-1 v`` exceeds the chi-square quantile (2 degrees of freedom).
        """
        var_t = m[:, 6] - m[:, 5] ** 2
        moving = np.zeros(count.size, dtype=bool)
        ok = var_t > 0
        if not ok.any():
            return moving
        vt = np.column_stack([m[ok, 7] - m[ok, 5] * m[ok, 0], m[ok, 8] - m[ok, 5] * m[ok, 1]])
        v = vt / var_t[ok, None]                                      # m/s
        raw = np.empty((int(ok.sum()), 2, 2))
        mean = m[ok, :2]
        raw[:, 0, 0] = m[ok, 2] - mean[:, 0] ** 2
        raw[:, 0, 1] = raw[:, 1, 0] = m[ok, 3] - mean[:, 0] * mean[:, 1]
        raw[:, 1, 1] = m[ok, 4] - mean[:, 1] ** 2
        res = floor_covariance(raw - np.einsum("ni,nj->nij", v, v) * var_t[ok, None, None], err[ok])
        cv = res / (count[ok] * var_t[ok])[:, None, None]
        det = cv[:, 0, 0] * cv[:, 1, 1] - cv[:, 0, 1] ** 2
        q = (v[:, 0] ** 2 * cv[:, 1, 1] - 2 * v[:, 0] * v[:, 1] * cv[:, 0, 1]
             + v[:, 1] ** 2 * cv[:, 0, 0]) / det
        moving[ok] = q > self._drift_gate
        return moving
