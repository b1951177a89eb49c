"""Spatial clutter intensity: false returns per ping and square metre, estimated from the data.

The likelihood ratio of a detection against clutter, ``N(nu; 0, S) / lambda(z)``, needs the
clutter intensity ``lambda`` where the detection lies. Random clutter varies over the field (and
with the sea state, the sonar's threshold and the receiver), so it is estimated from the
detections themselves rather than set: ``lambda(x)`` is a kernel density of the remembered
detections with a Gaussian kernel of standard deviation ``bandwidth_m`` per axis, divided by the
number of pings remembered,

``lambda(x) = (1 / n_pings) sum_j N(x; p_j, B)``, ``B = bandwidth_m^2 I``, floored at
``min_intensity``.

It is evaluated on a grid: the detections are binned (cloud in cell) into square cells of
``bandwidth_m / 4``, the histogram is smoothed with the Gaussian kernel (the truncated kernel of
:func:`scipy.ndimage.gaussian_filter`) and read at the query points by bilinear interpolation,
so its cost does not grow with the number of detections near a query. The smoothing is done
only at the cells the reading needs (the four around each query point), by the separable
kernel's rows and columns: a ping asks for a few dozen points, and smoothing the whole grid
cost a tenth of the ping (issue 20, ping speed); the values agree with the whole-grid filter
to rounding (``tests/active/test_ping_speed_parts.py``). A detection's own
position error (typically a few hundred metres) is small beside the bandwidth and is left out of
the kernel. Target echoes are a small part of the sum where clutter is dense; where it is sparse
they raise ``lambda`` near the target's recent path, which only makes the tracker more cautious
there. Bottom hotspots, far narrower than the
kernel, are added by the track score from the clutter map
(:meth:`fusion.active.track_score.TrackScorer.observe`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["ClutterIntensity"]

#: Grid cells per bandwidth.
_CELLS_PER_BANDWIDTH = 4
#: Largest grid side, cells (a wider field gets coarser cells).
_MAX_CELLS = 512


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
        left out (default 1000 m): their position says little about where clutter arises.

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
        self._pings: list[NDArray[np.float64]] = []
        self.updates = 0
        self._grid: tuple[NDArray[np.float64], NDArray[np.float64], float] | None = None

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
            Position-error covariances, m^2 (only to leave out very uncertain detections).
        """
        pts = np.asarray(xy, dtype=float).reshape(-1, 2) if np.size(xy) else np.zeros((0, 2))
        if not np.all(np.isfinite(pts)):
            raise ValueError("clutter intensity: positions must be finite")
        if cov is not None and pts.shape[0]:
            c = np.asarray(cov, dtype=float).reshape(-1, 2, 2)
            if c.shape[0] != pts.shape[0]:
                raise ValueError("clutter intensity: one covariance per position")
            tr, det = c[:, 0, 0] + c[:, 1, 1], c[:, 0, 0] * c[:, 1, 1] - c[:, 0, 1] ** 2
            big = 0.5 * (tr + np.sqrt(np.maximum(tr * tr - 4 * det, 0.0)))  # largest eigenvalue
            self.last_kept = ~(big > self.max_sigma_m**2)
            pts = pts[self.last_kept]
        else:
            self.last_kept = np.ones(pts.shape[0], dtype=bool)
        self._pings.append(pts)
        self.updates += 1
        if len(self._pings) > self.memory_pings:
            self._pings.pop(0)
        self._grid = None

    def _smoothed(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float] | None:
        """Binned histogram (detections per cell, all remembered pings), its origin and cell
        size; the kernel is applied where the estimate is read (:meth:`intensity`)."""
        if self._grid is not None:
            return self._grid
        pts = np.concatenate(self._pings) if self._pings else np.zeros((0, 2))
        if pts.shape[0] == 0:
            return None
        pad = 4.0 * self.bandwidth_m
        lo, hi = pts.min(axis=0) - pad, pts.max(axis=0) + pad
        cell = max(self.bandwidth_m / _CELLS_PER_BANDWIDTH, float(np.max(hi - lo)) / _MAX_CELLS)
        shape = np.ceil((hi - lo) / cell).astype(int) + 2
        # Cloud-in-cell binning: each detection is shared by the four cell centres around it
        # (centre of cell i at lo + (i + 1/2) cell), bilinearly, so the histogram keeps its
        # position to well under a cell. One bincount over the four corners in turn.
        u = (pts - lo) / cell - 0.5
        i0 = np.floor(u).astype(int)
        f = u - i0
        flat, share = [], []
        for di, wi in ((0, 1.0 - f[:, 0]), (1, f[:, 0])):
            for dj, wj in ((0, 1.0 - f[:, 1]), (1, f[:, 1])):
                flat.append((i0[:, 0] + di) * shape[1] + i0[:, 1] + dj)
                share.append(wi * wj)
        hist = np.bincount(np.concatenate(flat), weights=np.concatenate(share),
                           minlength=int(shape[0] * shape[1])).reshape(shape)
        self._grid = (hist, lo, cell)
        return self._grid

    def _kernel_rows(self, centre: NDArray[np.int64], n: int, cell: float) -> NDArray[np.float64]:
        """Rows of the smoothing operator along one axis: ``out[a, i]`` = weight of cell ``i``
        in the smoothed value at cell ``centre[a]`` (the normalised Gaussian of
        :func:`scipy.ndimage.gaussian_filter`, standard deviation ``bandwidth_m / cell`` cells,
        truncated at 4 of them; zero beyond the grid, its ``mode="constant"``)."""
        sigma = self.bandwidth_m / cell
        radius = int(4.0 * sigma + 0.5)
        k = np.arange(-radius, radius + 1)
        w = np.exp(-0.5 / (sigma * sigma) * k * k)
        w /= w.sum()
        off = np.arange(n)[None, :] - centre[:, None]
        return np.where(np.abs(off) <= radius, w[np.clip(off + radius, 0, 2 * radius)], 0.0)

    def self_intensity(self) -> float:
        """What one remembered detection adds to the estimate at its own position, per m^2
        per ping: ``1 / (n_pings 2 pi (bandwidth^2 + cell^2 / 3))`` (the kernel's peak; the
        cloud-in-cell binning and the bilinear reading each widen it by a tent of one cell,
        variance ``cell^2 / 6`` per axis). 0 before any detection.

        Subtracting it from :meth:`intensity` at a detection of the latest ping gives the
        leave-one-out estimate there: the clutter intensity at a detection judged from the
        other detections, not raised by the detection itself (on the first pings, where
        ``n_pings`` is small, a detection's own kernel can be ten times the clutter around it).
        """
        var = self._kernel_variance()
        return 0.0 if var is None else 1.0 / (self.n_pings * 2.0 * np.pi * var)

    def _kernel_variance(self) -> float | None:
        """Per-axis variance of one detection's kernel as read back, m^2: ``bandwidth^2 +
        cell^2 / 3`` (None before any detection)."""
        grid = self._smoothed()
        return None if grid is None else self.bandwidth_m**2 + grid[2] * grid[2] / 3.0

    def kernel_intensity(self, xy: ArrayLike, sources: ArrayLike,
                         updates: ArrayLike) -> float:
        """What remembered detections add to the estimate at a point, per m^2 per ping.

        Parameters
        ----------
        xy : array_like, shape (2,)
            The point, m.
        sources : array_like, shape (m, 2)
            Detections that were added, m.
        updates : array_like of int, shape (m,)
            :attr:`updates` after the :meth:`update` that added each; those the estimator has
            forgotten (``memory_pings`` updates ago or more) add nothing.

        Returns
        -------
        float
            ``(1 / n_pings) sum_j N(x; p_j, (bandwidth^2 + cell^2 / 3) I)`` over the sources
            still remembered: the kernel of :meth:`self_intensity`, centred on each source.
        """
        var = self._kernel_variance()
        src = np.asarray(sources, dtype=float).reshape(-1, 2)
        keep = self.updates - np.asarray(updates, dtype=np.int64).reshape(-1) < self.memory_pings
        if var is None or not keep.any():
            return 0.0
        d2 = np.sum((src[keep] - np.asarray(xy, dtype=float).reshape(1, 2)) ** 2, axis=1)
        return float(np.sum(np.exp(-0.5 * d2 / var)) / (self.n_pings * 2.0 * np.pi * var))

    def intensity(self, xy: ArrayLike) -> NDArray[np.float64]:
        """Clutter intensity at points, detections per m^2 per ping.

        Parameters
        ----------
        xy : array_like, shape (k, 2)
            Points, m.

        Returns
        -------
        ndarray, shape (k,)
            ``(1 / n_pings) sum_j N(x; p_j, B)`` over the remembered detections (on the
            grid), at least ``min_intensity`` (the floor alone before any detection).
        """
        pts = np.asarray(xy, dtype=float).reshape(-1, 2) if np.size(xy) else np.zeros((0, 2))
        grid = self._smoothed()
        if grid is None or pts.shape[0] == 0:
            return np.full(pts.shape[0], self.min_intensity)
        hist, lo, cell = grid
        # Cell centres sit at lo + (i + 1/2) cell; the smoothed histogram is needed only at the
        # four cells around each point (bilinear reading), so the separable kernel is applied
        # to those rows and columns alone, not to the whole grid.
        u = (pts - lo) / cell - 0.5
        i0 = np.floor(u).astype(np.int64)
        f = u - i0
        rows = np.unique(np.concatenate([i0[:, 0], i0[:, 0] + 1]))
        cols = np.unique(np.concatenate([i0[:, 1], i0[:, 1] + 1]))
        sub = (self._kernel_rows(rows, hist.shape[0], cell) @ hist
               @ self._kernel_rows(cols, hist.shape[1], cell).T)
        r0, c0 = np.searchsorted(rows, i0[:, 0]), np.searchsorted(cols, i0[:, 1])
        val = ((1.0 - f[:, 0]) * ((1.0 - f[:, 1]) * sub[r0, c0] + f[:, 1] * sub[r0, c0 + 1])
               + f[:, 0] * ((1.0 - f[:, 1]) * sub[r0 + 1, c0] + f[:, 1] * sub[r0 + 1, c0 + 1]))
        return np.maximum(val / (cell * cell * self.n_pings), self.min_intensity)
