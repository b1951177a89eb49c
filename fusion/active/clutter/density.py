"""Density clutter map: where returns recur, judged with each detection's own error ellipse.

Section 2.4 of "Target tracking using fuzzy logic association" ("Clutter map"): detections are
stored event by event, new ones are associated with earlier ones, and a location from which
detections come back on more than a set fraction of the events becomes a hotspot. A grid of fixed
cells (:class:`fusion.active.clutter.grid.ClutterMap`) assumes that a feature's echoes land in one
place; bistatic echoes do not: their errors are ellipses of 50-200 m along the bistatic ellipse
and of a degree or so of bearing across it, different for every receiver and geometry. Here the
association of echoes is the statistical one:

- *Recurrence.* Two detections ``i``, ``j`` of different pings are echoes of one place when
  ``(p_i - p_j)^T (R_i + R_j + 2 F)^-1 (p_i - p_j) <= g^2``, with ``R`` each detection's own
  position-error covariance, ``F = feature_sigma_m^2 I`` the spread of a feature's echo points and
  ``g^2`` the chi-square quantile (2 degrees of freedom) of ``probability``. The *recurrence* of a
  detection is the number of distinct pings, its own included, with an echo of its place, across
  all receivers: a kernel density over positions counted in pings, each kernel the detection's own
  error ellipse. A detection is *hot* when its recurrence is at least ``min_pings`` and more than
  ``fraction`` of the pings seen.
- *Hotspots.* Hot detections (that pass the drift test below) linked by the relation above form
  clusters (connected components); a cluster whose echoes span fewer than ``min_pings`` pings is
  dropped;
  a cluster's centre is the mean of its detections and its covariance their sample covariance,
  raised to at least their mean error covariance plus ``F``
  (:func:`fusion.active.clutter.base.floor_covariance`). Its region is the ellipse holding
  ``extent_probability`` of its echoes, as in the grid map.
- *Hotspots stand still.* A slow target seen by several receivers recurs too, for a while. For
  each candidate hot detection, the echoes of its place (itself and every detection linked to
  it) are fitted with a constant velocity by generalised least squares, each weighted by
  ``(R_j + F)^-1``; when the chi-square statistic of that velocity (2 degrees of freedom)
  exceeds the quantile of ``drift_probability`` the detection sits among moving echoes and is
  not hot. (The test trusts the stated errors: they are learnt from the data,
  :mod:`fusion.active.noise`; scaling by the residual scatter let clutter in a neighbourhood hide
  a target's drift.)

Compared with the grid, nothing depends on where cell borders fall or on a cell size tied to one
error level, and a feature seen by a far receiver (long ellipses) and a near one (short ellipses)
is one hotspot. The cost is a search of earlier detections near each new one (a k-d tree over
the stored positions).

The drift fit is kept up to date as pings come and go: each stored detection carries the sums of
its normal equations (its weight ``(R + F)^-1`` is inverted once), a new link adds the other
end's terms to both ends and a forgotten detection's terms are taken off its neighbours', so a
ping costs its own links and those of the ping forgotten, not the whole remembered history. A
detection whose statistic lies within ``1e-6`` (relative) of the gate is refitted from its
neighbourhood in the original order of summation, so the verdicts do not depend on rounding.
"""

from __future__ import annotations

import logging

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from scipy.stats import chi2

from fusion.active.clutter.base import ClutterMapBase, Hotspots, floor_covariance

__all__ = ["DensityClutterMap"]

logger = logging.getLogger(__name__)


#: Relative distance to the drift gate under which the running sums are not trusted (refit).
_REFIT_MARGIN = 1e-6


def _moments(W: NDArray[np.float64], p: NDArray[np.float64],
             dt: NDArray[np.float64]) -> NDArray[np.float64]:
    """Terms of the drift fit's normal equations, one row of 16 per echo.

    ``W`` (m, 2, 2) weights, ``p`` (m, 2) positions, m, ``dt`` (m,) times relative to the fitted
    detection, s; columns ``W, W dt, W dt^2`` (4 each, row-major) and ``W p, W p dt`` (2 each).
    """
    Wf = W.reshape(-1, 4)
    Wp = np.einsum("nij,nj->ni", W, p)
    return np.column_stack([Wf, Wf * dt[:, None], Wf * (dt * dt)[:, None], Wp, Wp * dt[:, None]])


def _add_rows(acc: NDArray[np.float64], owner: NDArray[np.int64],
              rows: NDArray[np.float64]) -> None:
    """``acc[owner[k]] += rows[k]`` for every k (repeated owners summed)."""
    if owner.size:
        # One bincount over (owner, column) cells: each cell sums its rows in order k, as a
        # bincount per column would (the same floating-point result).
        m = acc.shape[1]
        cells = (owner[:, None] * m + np.arange(m)).ravel()
        acc += np.bincount(cells, weights=rows.ravel(), minlength=acc.size).reshape(acc.shape)


def _components(n: int, edges: NDArray[np.integer]) -> tuple[int, NDArray[np.int64]]:
    """Connected components of an undirected graph on ``n`` nodes with links ``edges`` (k, 2).

    Labels are numbered in the order of each component's smallest node, as
    :func:`scipy.sparse.csgraph.connected_components` numbers them; computed by propagating
    the smallest node index along the links with pointer jumping (a few vectorised passes),
    without building a sparse matrix (whose set-up dominated a ping of a few hundred links).
    """
    root = np.arange(n, dtype=np.int64)
    if edges.shape[0]:
        a, b = edges[:, 0].astype(np.int64), edges[:, 1].astype(np.int64)
        while True:
            new = root.copy()
            np.minimum.at(new, a, root[b])
            np.minimum.at(new, b, root[a])
            new = new[new]
            if np.array_equal(new, root):
                break
            root = new
    first, label = np.unique(root, return_inverse=True)
    return int(first.size), label.reshape(-1).astype(np.int64)


def _largest_eigenvalue(c: NDArray[np.float64]) -> NDArray[np.float64]:
    """Largest eigenvalue of each symmetric 2 x 2 matrix of a stack (closed form)."""
    half_tr = 0.5 * (c[:, 0, 0] + c[:, 1, 1])
    return half_tr + np.hypot(0.5 * (c[:, 0, 0] - c[:, 1, 1]), c[:, 0, 1])


def _mahalanobis2(d: NDArray[np.float64], S: NDArray[np.float64]) -> NDArray[np.float64]:
    """``d^T S^-1 d`` for stacks of 2-vectors and 2 x 2 covariances (closed-form inverse)."""
    det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] ** 2
    return (d[:, 0] ** 2 * S[:, 1, 1] - 2.0 * d[:, 0] * d[:, 1] * S[:, 0, 1]
            + d[:, 1] ** 2 * S[:, 0, 0]) / det


class DensityClutterMap(ClutterMapBase):
    """Online clutter map that learns where returns recur, whatever their spread.

    Parameters
    ----------
    probability : float, optional
        Confidence of the "same place" test between two echoes (default 0.99), in (0, 1).
    fraction : float, optional
        A detection is hot when its place recurs on more than this fraction of the pings seen
        (default 0.4), in (0, 1).
    min_pings : int, optional
        ... and on at least this many pings (default 6), >= 1: a slow target seen by several
        receivers recurs too for a few pings, before its drift is significant.
    position_sigma_m : float, optional
        Position error per axis of detections given to :meth:`update` without a covariance, m
        (default 100), > 0.
    feature_sigma_m : float, optional
        Spread of a feature's echo points per axis, m (default 30), >= 0.
    extent_probability : float, optional
        Fraction of a hotspot's echoes inside its region (default 0.99), in (0, 1).
    drift_probability : float, optional
        Confidence of the drift test (default 0.99), in (0, 1).
    max_sigma_m : float, optional
        Detections whose error ellipse has a standard deviation above this along its major
        axis are not stored (default 500 m): an ellipse kilometres long (an echo near the
        source-receiver baseline, where the range sum hardly fixes the position) is "the same
        place" as everything around it and would make a hotspot of the whole area.
    memory_pings : int, optional
        Pings remembered (default None: all); older detections are forgotten and the fraction
        test counts only the remembered pings.

    Notes
    -----
    See the module docstring for the model. :meth:`update` adds one ping; :meth:`hotspots`
    lists the current hotspots (cached until the next update).

    Examples
    --------
    >>> cmap = DensityClutterMap(min_pings=3, position_sigma_m=20.0)
    >>> for _ in range(3):
    ...     cmap.update([[1000.0, 2000.0]])
    >>> d = cmap.distance([[1000.0, 2300.0], [1000.0, 2030.0]])
    >>> bool(d[0] > 100.0), float(d[1])
    (True, 0.0)
    """

    def __init__(
        self,
        *,
        probability: float = 0.99,
        fraction: float = 0.4,
        min_pings: int = 6,
        position_sigma_m: float = 100.0,
        feature_sigma_m: float = 30.0,
        extent_probability: float = 0.99,
        drift_probability: float = 0.99,
        max_sigma_m: float = 500.0,
        memory_pings: int | None = None,
    ) -> None:
        for name, v in (("probability", probability), ("fraction", fraction),
                        ("extent_probability", extent_probability),
                        ("drift_probability", drift_probability)):
            if not 0.0 < v < 1.0:
                raise ValueError(f"{name} must lie in (0, 1), got {v!r}")
        if isinstance(min_pings, bool) or int(min_pings) != min_pings or min_pings < 1:
            raise ValueError(f"min_pings must be an integer >= 1, got {min_pings!r}")
        if not np.isfinite(position_sigma_m) or position_sigma_m <= 0:
            raise ValueError(f"position_sigma_m must be a positive number, got {position_sigma_m!r}")
        if not np.isfinite(feature_sigma_m) or feature_sigma_m < 0:
            raise ValueError(f"feature_sigma_m must be >= 0, got {feature_sigma_m!r}")
        if not np.isfinite(max_sigma_m) or max_sigma_m <= 0:
            raise ValueError(f"max_sigma_m must be a positive number, got {max_sigma_m!r}")
        if memory_pings is not None and (int(memory_pings) != memory_pings or memory_pings < 2):
            raise ValueError(f"memory_pings must be an integer >= 2, got {memory_pings!r}")
        self.probability = float(probability)
        self.fraction = float(fraction)
        self.min_pings = int(min_pings)
        self.position_sigma_m = float(position_sigma_m)
        self.feature_sigma_m = float(feature_sigma_m)
        self.extent_probability = float(extent_probability)
        self.drift_probability = float(drift_probability)
        self.max_sigma_m = float(max_sigma_m)
        self.memory_pings = None if memory_pings is None else int(memory_pings)
        self._g2 = float(chi2.ppf(self.probability, 2))
        self._gate = float(np.sqrt(chi2.ppf(self.extent_probability, 2)))
        self._drift_gate = float(chi2.ppf(self.drift_probability, 2))
        self._F = np.eye(2) * self.feature_sigma_m**2
        self.n_pings = 0
        self._t0: float | None = None
        self._xy = np.zeros((0, 2))
        self._cov = np.zeros((0, 2, 2))
        self._ping = np.zeros(0, np.int64)     # ping number of each stored detection
        self._t = np.zeros(0)                   # ping time relative to the first ping, s
        self._seen = np.zeros((0, 0), dtype=bool)  # (detections, remembered pings)
        self._first = 0                         # ping number of column 0 of _seen
        self._edges = np.zeros((0, 2), np.int32)  # stored-index pairs, newer end first
        self._lam_stored = 0.0                  # largest error variance of a stored detection
        self._W = np.zeros((0, 2, 2))           # (R + F)^-1 of each stored detection
        self._mom = np.zeros((0, 16))           # drift-fit sums over each neighbourhood
        self._deg = np.zeros(0, np.int64)       # links of each stored detection
        self._cache: Hotspots | None = None

    def empty_copy(self) -> DensityClutterMap:
        """A map with the same options and no content."""
        return DensityClutterMap(
            probability=self.probability, fraction=self.fraction, min_pings=self.min_pings,
            position_sigma_m=self.position_sigma_m, feature_sigma_m=self.feature_sigma_m,
            extent_probability=self.extent_probability,
            drift_probability=self.drift_probability, max_sigma_m=self.max_sigma_m,
            memory_pings=self.memory_pings)

    def _add_ping(self, pts: NDArray[np.float64], c: NDArray[np.float64], t_rel: float) -> None:
        """Store one ping's detections (:meth:`ClutterMapBase.update`): those whose error
        ellipse is no longer than `max_sigma_m`, linked to the stored ones they match."""
        lam = _largest_eigenvalue(c)
        small = lam <= self.max_sigma_m**2
        pts, c, lam = pts[small], c[small], lam[small]
        k = self.n_pings - 1
        self._seen = np.concatenate([self._seen, np.zeros((self._seen.shape[0], 1), bool)], axis=1)
        n_old, n_new = self._xy.shape[0], pts.shape[0]
        seen_new = np.zeros((n_new, self._seen.shape[1]), dtype=bool)
        seen_new[:, k - self._first] = True
        edges = np.zeros((0, 2), np.int32)
        W = np.linalg.inv(c + self._F)
        mom = np.concatenate([self._mom, _moments(W, pts, np.zeros(n_new))])
        deg = np.concatenate([self._deg, np.zeros(n_new, np.int64)])
        if n_old and n_new:
            i, j = self._candidates(pts, lam)
            if i.size:
                S = c[i] + self._cov[j] + 2.0 * self._F
                ok = _mahalanobis2(pts[i] - self._xy[j], S) <= self._g2
                i, j = i[ok], j[ok]
                self._seen[j, k - self._first] = True
                seen_new[i, self._ping[j] - self._first] = True
                edges = np.column_stack([i + n_old, j]).astype(np.int32)
                dt = self._t[j] - t_rel
                _add_rows(mom, i + n_old, _moments(self._W[j], self._xy[j], dt))
                _add_rows(mom, j, _moments(W[i], pts[i], -dt))
                deg += np.bincount(edges.ravel(), minlength=deg.size)
        self._mom, self._deg = mom, deg
        self._W = np.concatenate([self._W, W])
        self._xy = np.concatenate([self._xy, pts])
        self._cov = np.concatenate([self._cov, c])
        if n_new:
            self._lam_stored = max(self._lam_stored, float(np.max(lam)))
        self._ping = np.concatenate([self._ping, np.full(n_new, k, np.int64)])
        self._t = np.concatenate([self._t, np.full(n_new, t_rel)])
        self._seen = np.concatenate([self._seen, seen_new])
        self._edges = np.concatenate([self._edges, edges])
        if self.memory_pings is not None and self.n_pings - self._first > self.memory_pings:
            self._forget(self.n_pings - self.memory_pings)

    def _candidates(self, pts: NDArray, lam: NDArray) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Pairs (new, stored) within the Euclidean reach of the Mahalanobis test (`lam`: the
        largest eigenvalue of each new detection's covariance)."""
        reach = np.sqrt(self._g2 * (float(np.max(lam)) + self._lam_stored
                                    + 2.0 * self.feature_sigma_m**2))
        pairs = cKDTree(pts).sparse_distance_matrix(cKDTree(self._xy), reach,
                                                    output_type="ndarray")
        return pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)

    def _forget(self, first: int) -> None:
        """Drop detections of pings before `first` and the columns of those pings.

        Detections are stored in ping order, so the forgotten ones are the first ``n_drop``;
        a link's second end is the older one (it was stored when the first came).
        """
        n_drop = int(np.searchsorted(self._ping, first))
        e = self._edges
        if e.size:
            gone = e[:, 1] < n_drop
            cut = e[gone]
            cut = cut[cut[:, 0] >= n_drop]
            # Links with one end forgotten: take that end's terms off the other's sums.
            owner, lost = cut[:, 0], cut[:, 1]
            _add_rows(self._mom, owner, -_moments(self._W[lost], self._xy[lost],
                                                  self._t[lost] - self._t[owner]))
            self._deg -= np.bincount(owner, minlength=self._deg.size)
            self._edges = e[~gone] - n_drop
        keep = slice(n_drop, None)
        self._seen = self._seen[keep, first - self._first:]
        self._W, self._mom, self._deg = self._W[keep], self._mom[keep], self._deg[keep]
        self._xy, self._cov = self._xy[keep], self._cov[keep]
        self._ping, self._t = self._ping[keep], self._t[keep]
        self._first = first

    def recurrence(self) -> NDArray[np.int64]:
        """Pings (remembered) on which each stored detection's place had an echo, its own
        included, shape (n_stored,)."""
        return self._seen.sum(axis=1)

    def hotspots(self) -> Hotspots:
        """The current hotspots.

        Returns
        -------
        Hotspots
            One per cluster of hot, non-drifting detections; ``visits`` is the largest
            recurrence in the cluster and ``cells`` its number of detections.
        """
        if self._cache is not None:
            return self._cache
        n_seen = self.n_pings - self._first
        rec = self.recurrence()
        hot = (rec >= self.min_pings) & (rec > self.fraction * n_seen)
        if hot.any():
            hot[hot] = ~self._drifting(np.flatnonzero(hot))
        hot = np.flatnonzero(hot)
        if hot.size == 0:
            self._cache = Hotspots(np.zeros((0, 2)), np.zeros((0, 2, 2)), self._gate,
                                   np.zeros(0, np.int64), np.zeros(0, np.int64), self.n_pings)
            return self._cache
        pos = np.full(self._xy.shape[0], -1, np.int32)
        pos[hot] = np.arange(hot.size)
        pe = pos[self._edges]
        pe = pe[(pe >= 0).all(axis=1)]
        n_spots, label = _components(hot.size, pe)
        # A hotspot's own echoes must recur: its cluster spans at least min_pings pings (the
        # newest echo of a slow target, whose neighbourhood is too short to show its drift,
        # is no hotspot on its own).
        ping_hot = self._ping[hot]
        span = int(ping_hot.max()) + 1 if ping_hot.size else 1
        pings = np.bincount(np.unique(label.astype(np.int64) * span + ping_hot) // span,
                            minlength=n_spots)
        keep = pings[label] >= self.min_pings
        if not keep.all():
            hot, label = hot[keep], np.unique(label[keep], return_inverse=True)[1].reshape(-1)
            n_spots = int(label.max()) + 1 if label.size else 0
        if hot.size == 0:
            self._cache = Hotspots(np.zeros((0, 2)), np.zeros((0, 2, 2)), self._gate,
                                   np.zeros(0, np.int64), np.zeros(0, np.int64), self.n_pings)
            return self._cache
        xy = self._xy[hot]
        count = np.bincount(label, minlength=n_spots).astype(float)
        mean = np.stack([np.bincount(label, weights=xy[:, a], minlength=n_spots)
                         for a in (0, 1)], axis=1) / count[:, None]
        d = xy - mean[label]
        cov = np.zeros((n_spots, 2, 2))
        np.add.at(cov, label, np.einsum("ni,nj->nij", d, d))
        cov /= count[:, None, None]
        err = np.zeros((n_spots, 2, 2))
        np.add.at(err, label, self._cov[hot])
        err = err / count[:, None, None] + self._F
        visits = np.zeros(n_spots, np.int64)
        np.maximum.at(visits, label, rec[hot])
        self._cache = Hotspots(mean, floor_covariance(cov, err), self._gate, visits,
                               count.astype(np.int64), self.n_pings)
        return self._cache

    def _drifting(self, cand: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Which candidate detections sit among echoes that move (see the module docstring).

        The fit of :meth:`_drifting_refit` from the running sums of each neighbourhood; the
        candidates whose statistic falls within ``_REFIT_MARGIN`` of the gate (or whose normal
        matrix is nearly singular) are refitted by :meth:`_drifting_refit`.
        """
        m = self._mom[cand]
        A = np.zeros((cand.size, 4, 4))
        A[:, :2, :2] = m[:, 0:4].reshape(-1, 2, 2)
        A[:, :2, 2:] = m[:, 4:8].reshape(-1, 2, 2)
        A[:, 2:, 2:] = m[:, 8:12].reshape(-1, 2, 2)
        A[:, 2:, :2] = A[:, :2, 2:]
        b = m[:, 12:16]
        moving = np.zeros(cand.size, dtype=bool)
        fit = self._deg[cand] + 1 >= 3
        if not fit.any():
            return moving
        Af = A[fit]
        det = np.linalg.det(Af)
        scale = np.prod(np.diagonal(Af, axis1=1, axis2=2), axis=1)
        sound = np.abs(det) > 1e-10 * np.abs(scale)
        q = np.full(Af.shape[0], np.nan)
        if sound.any():
            As = Af[sound]
            theta = np.linalg.solve(As, b[fit][sound][..., None])[..., 0]
            cov_v = np.linalg.inv(As)[:, 2:, 2:]
            q[sound] = np.einsum("ni,ni->n", theta[:, 2:],
                                 np.linalg.solve(cov_v, theta[:, 2:][..., None])[..., 0])
        moving[fit] = q > self._drift_gate
        doubt = np.flatnonzero(fit)[~(np.abs(q - self._drift_gate)
                                      > _REFIT_MARGIN * self._drift_gate)]
        if doubt.size:
            moving[doubt] = self._drifting_refit(cand[doubt])
        return moving

    def _drifting_refit(self, cand: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Which candidate detections sit among echoes that move, fitted from scratch.

        For each candidate ``j``, the echoes of its place (``j`` and every stored detection
        linked to it) are fitted with ``p_i = p_0 + v (t_i - t_j) + e_i``,
        ``e_i ~ N(0, R_i + F)``, by generalised least squares; ``j`` drifts when
        ``v^T Cov(v)^-1 v`` is above the chi-square quantile of ``drift_probability``.
        """
        n = self._xy.shape[0]
        slot = np.full(n, -1, np.int64)
        slot[cand] = np.arange(cand.size)
        e = self._edges
        # Members of each candidate's neighbourhood: itself and both ends of its edges.
        owner = np.concatenate([cand, slot[e[:, 0]], slot[e[:, 1]]]) if e.size else cand.copy()
        member = np.concatenate([cand, e[:, 1], e[:, 0]]) if e.size else cand.copy()
        if e.size:
            owner[:cand.size] = np.arange(cand.size)
            ok = owner >= 0
            owner, member = owner[ok], member[ok]
        else:
            owner = np.arange(cand.size)
        W = np.linalg.inv(self._cov[member] + self._F)
        tc = self._t[member] - self._t[cand][owner]
        p = self._xy[member]
        A = np.zeros((cand.size, 4, 4))
        b = np.zeros((cand.size, 4))
        Wp = np.einsum("nij,nj->ni", W, p)
        np.add.at(A[:, :2, :2], owner, W)
        np.add.at(A[:, :2, 2:], owner, W * tc[:, None, None])
        np.add.at(A[:, 2:, 2:], owner, W * (tc * tc)[:, None, None])
        A[:, 2:, :2] = A[:, :2, 2:]
        np.add.at(b[:, :2], owner, Wp)
        np.add.at(b[:, 2:], owner, Wp * tc[:, None])
        size = np.bincount(owner, minlength=cand.size)
        moving = np.zeros(cand.size, dtype=bool)
        fit = (size >= 3) & (np.abs(np.linalg.det(A)) > 0)
        if not fit.any():
            return moving
        Af = A[fit]
        theta = np.linalg.solve(Af, b[fit][..., None])[..., 0]
        cov_v = np.linalg.inv(Af)[:, 2:, 2:]
        q = np.einsum("ni,ni->n", theta[:, 2:], np.linalg.solve(cov_v, theta[:, 2:][..., None])[..., 0])
        moving[fit] = q > self._drift_gate
        return moving
