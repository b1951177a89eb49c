"""Spatial clutter intensity: false returns per ping and square metre, estimated from the data.

The likelihood ratio of a detection against clutter, ``N(nu; 0, S) / lambda(z)``, needs the
clutter intensity ``lambda`` where the detection lies. Random clutter and bottom hotspots make it
vary over the field (and with the sea state, the sonar's threshold and the receiver), so it is
estimated from the detections themselves rather than set: ``lambda(x)`` is a kernel density of
the remembered detections, each spread by its own position-error covariance ``R_j`` plus a
smoothing bandwidth ``B = bandwidth_m^2 I``, divided by the number of pings remembered:

``lambda(x) = (1 / n_pings) sum_j N(x; p_j, R_j + B)``, floored at ``min_intensity``.

Target echoes are a small part of the sum where clutter is dense; where it is sparse they raise
``lambda`` near the target's recent path, which only makes the tracker more cautious there.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

__all__ = ["ClutterIntensity"]


class ClutterIntensity:
    """Kernel estimate of the clutter intensity over the field, updated one ping at a time.

    Parameters
    ----------
    bandwidth_m : float, optional
        Smoothing standard deviation per axis, m (default 1000), > 0.
    memory_pings : int, optional
        Pings remembered (default 20), >= 1.
    min_intensity : float, optional
        Floor of the estimate, detections per m^2 per ping (default 1e-9: one per 1000 km^2),
        > 0.
    max_sigma_m : float, optional
        Detections whose error ellipse exceeds this standard deviation along its major axis are
        left out (default 1000 m).

    Examples
    --------
    >>> ci = ClutterIntensity(bandwidth_m=500.0)
    >>> rng = np.random.default_rng(0)
    >>> for _ in range(10):
    ...     ci.update(rng.uniform(-5000, 5000, (100, 2)))    # 1 per km^2 per ping
    >>> bool(0.5e-6 < ci.intensity([[0.0, 0.0]])[0] < 2e-6)
    True
    """

    def __init__(
        self,
        *,
        bandwidth_m: float = 1000.0,
        memory_pings: int = 20,
        min_intensity: float = 1e-9,
        max_sigma_m: float = 1000.0,
    ) -> None:
        for name, v in (("bandwidth_m", bandwidth_m), ("min_intensity", min_intensity),
                        ("max_sigma_m", max_sigma_m)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive, got {v!r}")
        if int(memory_pings) != memory_pings or memory_pings < 1:
            raise ValueError(f"memory_pings must be an integer >= 1, got {memory_pings!r}")
        self.bandwidth_m = float(bandwidth_m)
        self.memory_pings = int(memory_pings)
        self.min_intensity = float(min_intensity)
        self.max_sigma_m = float(max_sigma_m)
        self.reset()

    def reset(self) -> None:
        """Forget all detections."""
        self._pings: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = []
        self._tree: cKDTree | None = None
        self._xy = np.zeros((0, 2))
        self._cov = np.zeros((0, 2, 2))

    def empty_copy(self) -> ClutterIntensity:
        """An estimator with the same options and no content."""
        return ClutterIntensity(bandwidth_m=self.bandwidth_m, memory_pings=self.memory_pings,
                                min_intensity=self.min_intensity, max_sigma_m=self.max_sigma_m)

    @property
    def n_pings(self) -> int:
        """Pings remembered."""
        return len(self._pings)

    def update(self, xy: ArrayLike, cov: ArrayLike | None = None) -> None:
        """Add one ping's detections (n may be 0: the ping still counts).

        Parameters
        ----------
        xy : array_like, shape (n, 2)
            Positions, m.
        cov : array_like, shape (n, 2, 2), optional
            Position-error covariances, m^2 (default 0).
        """
        pts = np.asarray(xy, dtype=float).reshape(-1, 2) if np.size(xy) else np.zeros((0, 2))
        c = (np.zeros((pts.shape[0], 2, 2)) if cov is None
             else np.asarray(cov, dtype=float).reshape(-1, 2, 2))
        if c.shape[0] != pts.shape[0] or not (np.all(np.isfinite(pts)) and np.all(np.isfinite(c))):
            raise ValueError("clutter intensity: positions and covariances must be finite, "
                             "one covariance per position")
        small = np.linalg.eigvalsh(c)[:, -1] <= self.max_sigma_m**2 if len(c) else np.zeros(0, bool)
        self._pings.append((pts[small], c[small]))
        if len(self._pings) > self.memory_pings:
            self._pings.pop(0)
        self._xy = np.concatenate([p for p, _ in self._pings])
        self._cov = np.concatenate([k for _, k in self._pings])
        self._tree = cKDTree(self._xy) if self._xy.shape[0] else None

    def intensity(self, xy: ArrayLike) -> NDArray[np.float64]:
        """Clutter intensity at points, detections per m^2 per ping.

        Parameters
        ----------
        xy : array_like, shape (k, 2)
            Points, m.

        Returns
        -------
        ndarray, shape (k,)
            ``(1 / n_pings) sum_j N(x; p_j, R_j + B)`` over the remembered detections within
            three of the widest kernel's widths, at least ``min_intensity`` (the floor alone before any ping).
        """
        pts = np.asarray(xy, dtype=float).reshape(-1, 2) if np.size(xy) else np.zeros((0, 2))
        out = np.full(pts.shape[0], self.min_intensity)
        if self._tree is None or pts.shape[0] == 0:
            return out
        reach = 3.0 * np.sqrt(self.bandwidth_m**2 + self.max_sigma_m**2)
        found = self._tree.query_ball_point(pts, reach)
        sizes = np.fromiter((len(f) for f in found), np.int64, len(found))
        if not sizes.sum():
            return out
        i = np.repeat(np.arange(len(found)), sizes)
        j = np.fromiter((x for f in found for x in f), np.int64, int(sizes.sum()))
        S = self._cov[j] + np.eye(2) * self.bandwidth_m**2
        det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] ** 2
        d = pts[i] - self._xy[j]
        m2 = (d[:, 0] ** 2 * S[:, 1, 1] - 2.0 * d[:, 0] * d[:, 1] * S[:, 0, 1]
              + d[:, 1] ** 2 * S[:, 0, 0]) / det
        dens = np.exp(-0.5 * m2) / (2.0 * np.pi * np.sqrt(det))
        total = np.bincount(i, weights=dens, minlength=pts.shape[0]) / self.n_pings
        return np.maximum(total, self.min_intensity)
