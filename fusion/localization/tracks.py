"""Source tracks across processing windows, smoothed on a constant-velocity factor graph.

Successive windows' sources (:class:`fusion.localization.localize.SourceFix`) are linked into tracks
(step 52's association across time, and paragraph [0046]: stepping the window forward "a sense
of the movement of the source is developed"). Two kinds of evidence link a source to a track:

* **TDOA links** (when given): the time association of the front end maps each TDOA of a window
  to a TDOA of the previous window; a source and the track's last source that share at least
  ``min_shared_tdoas`` linked TDOAs (of weight > 0.5 in both) are the same whale;
* **position gating** otherwise: the Mahalanobis distance of the source from the track's last
  fix, with the two fixes' covariances plus the motion possible at ``max_speed`` over the gap,
  below ``gate_chi2``.

Sources are assigned to tracks by :func:`scipy.optimize.linear_sum_assignment` (TDOA links
first, then distance); unassigned sources start tracks; a track not extended for more than
``max_gap`` windows ends. Fixes without a finite covariance (unobservable) are not tracked.

Each track is then smoothed on a GTSAM factor graph: states ``x_k = [p (3), v (3)]`` (m, m/s),
constant-velocity motion ``x_{k+1} = F x_k + w`` with white-noise acceleration of spectral
density ``q`` (a slow-motion prior: :func:`factors.motion.wna_sqrt_information`), and a position
measurement per fix with the fix's covariance. Everything is linear, so the factors are
built-in ``JacobianFactor`` s in ``LinearContainerFactor`` s (no Python callback); one
Gauss-Newton step solves the graph and ``gtsam.Marginals`` gives the smoothed covariances.

Notes
-----
*Localization of Short Duration Periodic Signals*, steps 52 and 60-62; the design notes'
"Factor graphs" (built-in linear factors for linear motion models).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import gtsam
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from factors.motion import transition_matrix, wna_sqrt_information
from fusion.localization.localize import SourceFix
from fusion.types import frozen_array

__all__ = ["SourceTracker", "Track", "WindowSources"]

_LOG = logging.getLogger(__name__)

#: Cost of an impossible assignment.
_FORBIDDEN = 1e12



@dataclass(frozen=True)
class WindowSources:
    """The sources of one window, for tracking.

    Attributes
    ----------
    time_s : float
        Time of the window (e.g. its centre), s.
    sources : tuple of SourceFix
        The window's sources.
    tdoa_links : ndarray of int, shape (M,), optional
        For each TDOA of this window, the index of the TDOA of the previous window it is
        associated with across time, or -1; None when no time association is available.
    """

    time_s: float
    sources: tuple[SourceFix, ...] = ()
    tdoa_links: NDArray[np.intp] | None = None

    def __post_init__(self) -> None:
        if not np.isfinite(self.time_s):
            raise ValueError(f"time_s must be finite, got {self.time_s!r}")
        object.__setattr__(self, "sources", tuple(self.sources))
        if self.tdoa_links is not None:
            links = frozen_array(self.tdoa_links, np.intp).reshape(-1)
            for f in self.sources:
                if f.weights.shape != links.shape:
                    raise ValueError(f"tdoa_links has {links.size} entries but a source weighs "
                                     f"{f.weights.size} TDOAs")
            object.__setattr__(self, "tdoa_links", links)


@dataclass(frozen=True)
class Track:
    """One source followed across windows.

    Attributes
    ----------
    track_id : int
        Track number (0, 1, ... in order of creation).
    times : ndarray, shape (n,)
        Window times, s.
    positions : ndarray, shape (n, 3)
        Smoothed positions, m.
    velocities : ndarray, shape (n, 3)
        Smoothed velocities, m/s (zero for a one-point track).
    covariances : ndarray, shape (n, 3, 3)
        Smoothed position covariances, m^2.
    raw_positions : ndarray, shape (n, 3)
        The window fixes, m.
    windows : ndarray of int, shape (n,)
        Index of each point's window.
    sources : ndarray of int, shape (n,)
        Index of each point's source within its window.
    """

    track_id: int
    times: NDArray[np.float64]
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    covariances: NDArray[np.float64]
    raw_positions: NDArray[np.float64]
    windows: NDArray[np.intp] = field(default_factory=lambda: frozen_array([], np.intp))
    sources: NDArray[np.intp] = field(default_factory=lambda: frozen_array([], np.intp))

    def __post_init__(self) -> None:
        for name in ("times", "positions", "velocities", "covariances", "raw_positions"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        for name in ("windows", "sources"):
            object.__setattr__(self, name, frozen_array(getattr(self, name), np.intp))

    def to_dict(self) -> dict[str, Any]:
        """The track in the ``tracks`` form of the project's ``localize`` output (formats, 2)."""
        return {"id": int(self.track_id),
                "points": [{"t": float(t), "x": float(p[0]), "y": float(p[1]), "z": float(p[2])}
                           for t, p in zip(self.times, self.positions, strict=True)]}


@dataclass
class _Open:
    """A track being built: (window, source) of each point."""

    points: list[tuple[int, int]]


class SourceTracker:
    """Link window sources into tracks and smooth each on a constant-velocity graph.

    Parameters
    ----------
    q : float, keyword-only
        Acceleration power spectral density of the motion prior, m^2/s^3 (default 0.01: a
        whale turning or changing speed by about 0.1 m/s over a few seconds).
    max_speed : float, keyword-only
        Largest source speed the position gate allows, m/s (default 5).
    gate_chi2 : float, keyword-only
        Position gate on the squared Mahalanobis distance (default 16.27: chi-square, 3 degrees
        of freedom, 0.999).
    min_shared_tdoas : int, keyword-only
        Linked TDOAs that make a source the continuation of a track (default 2).
    max_gap : int, keyword-only
        Windows a track may miss and still be extended (default 1).

    Examples
    --------
    >>> from fusion.localization.localize import SourceFix
    >>> def fix(p):
    ...     return SourceFix(position=p, covariance=np.eye(3), information=np.eye(3),
    ...                      weights=np.ones(4), tdoas_used=4, residual_rms_s=0.0,
    ...                      condition_number=1.0, observable=True, mirror_ambiguous=False,
    ...                      mirror_position=np.full(3, np.nan))
    >>> wins = [WindowSources(2.0 * k, (fix([2.0 * k, 0.0, -500.0]),)) for k in range(4)]
    >>> tracks = SourceTracker().track(wins)
    >>> len(tracks), np.round(tracks[0].velocities[-1], 3)
    (1, array([1., 0., 0.]))
    """

    def __init__(
        self,
        *,
        q: float = 0.01,
        max_speed: float = 5.0,
        gate_chi2: float = 16.27,
        min_shared_tdoas: int = 2,
        max_gap: int = 1,
    ) -> None:
        for name, v in (("q", q), ("max_speed", max_speed), ("gate_chi2", gate_chi2)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive and finite, got {v!r}")
        if int(min_shared_tdoas) != min_shared_tdoas or min_shared_tdoas < 1:
            raise ValueError(f"min_shared_tdoas must be a positive integer, got {min_shared_tdoas!r}")
        if int(max_gap) != max_gap or max_gap < 0:
            raise ValueError(f"max_gap must be an integer >= 0, got {max_gap!r}")
        self.q = float(q)
        self.max_speed = float(max_speed)
        self.gate_chi2 = float(gate_chi2)
        self.min_shared_tdoas = int(min_shared_tdoas)
        self.max_gap = int(max_gap)

    # ------------------------------------------------------------------ linking
    def _shared(self, prev: SourceFix, cur: SourceFix, links: NDArray[np.intp]) -> int:
        """Linked TDOAs held by both fixes (weight > 0.5)."""
        held_prev = np.flatnonzero(prev.weights > 0.5)
        held = (cur.weights > 0.5) & (links >= 0)
        return int(np.isin(links[held], held_prev).sum())

    def _distance2(self, track: _Open, windows: Sequence[WindowSources], w: int, s: int) -> float:
        """Squared Mahalanobis distance of source s of window w from the track's last fix.

        The difference has the covariance of both fixes plus the motion possible at
        `max_speed` over the time between them (uniform in direction: ``(v dt)^2 / 3`` per axis).
        """
        wl, sl = track.points[-1]
        last = windows[wl].sources[sl]
        cur = windows[w].sources[s]
        dt = windows[w].time_s - windows[wl].time_s
        s_cov = last.covariance + cur.covariance + (self.max_speed * dt) ** 2 / 3.0 * np.eye(3)
        d = cur.position - last.position
        return float(d @ np.linalg.solve(s_cov, d))

    def _link(self, open_tracks: list[_Open], windows: Sequence[WindowSources], w: int,
              usable: list[int]) -> dict[int, int]:
        """Assignment source index -> open-track index for window w."""
        if not open_tracks or not usable:
            return {}
        links = windows[w].tdoa_links
        cost = np.full((len(open_tracks), len(usable)), _FORBIDDEN)
        for ti, tr in enumerate(open_tracks):
            wl, sl = tr.points[-1]
            if w - wl - 1 > self.max_gap:
                continue
            for si, s in enumerate(usable):
                if links is not None and wl == w - 1:
                    shared = self._shared(windows[wl].sources[sl], windows[w].sources[s], links)
                    if shared >= self.min_shared_tdoas:
                        cost[ti, si] = -1e6 * shared  # TDOA continuity outranks any distance
                        continue
                d2 = self._distance2(tr, windows, w, s)
                if d2 <= self.gate_chi2:
                    cost[ti, si] = d2
        rows, cols = linear_sum_assignment(cost)
        return {usable[c]: r for r, c in zip(rows, cols, strict=True) if cost[r, c] < _FORBIDDEN}

    # ------------------------------------------------------------------ entry point
    def track(self, windows: Sequence[WindowSources]) -> tuple[Track, ...]:
        """Link the sources of consecutive windows into tracks and smooth each track.

        Parameters
        ----------
        windows : sequence of WindowSources
            The windows in time order (strictly increasing ``time_s``).

        Returns
        -------
        tuple of Track
            In order of creation.
        """
        times = np.array([w.time_s for w in windows], dtype=float)
        if times.size > 1 and np.any(np.diff(times) <= 0):
            raise ValueError("windows must be in strictly increasing time order")
        open_tracks: list[_Open] = []
        closed: list[_Open] = []
        for w, win in enumerate(windows):
            usable = [s for s, f in enumerate(win.sources) if np.all(np.isfinite(f.covariance))]
            if len(usable) < len(win.sources):
                _LOG.info("window %d: %d fixes without a finite covariance not tracked", w,
                          len(win.sources) - len(usable))
            assigned = self._link(open_tracks, windows, w, usable)
            for s in usable:
                if s in assigned:
                    open_tracks[assigned[s]].points.append((w, s))
                else:
                    open_tracks.append(_Open([(w, s)]))
            still = [t for t in open_tracks if w - t.points[-1][0] <= self.max_gap]
            closed += [t for t in open_tracks if w - t.points[-1][0] > self.max_gap]
            open_tracks = still
        every = sorted(closed + open_tracks, key=lambda t: t.points[0])
        return tuple(self._smooth(k, t, windows) for k, t in enumerate(every))

    # ------------------------------------------------------------------ smoothing
    def _smooth(self, track_id: int, tr: _Open, windows: Sequence[WindowSources]) -> Track:
        fixes = [windows[w].sources[s] for w, s in tr.points]
        t = np.array([windows[w].time_s for w, _ in tr.points])
        z = np.array([f.position for f in fixes])
        cov = np.array([f.covariance for f in fixes])
        win = [w for w, _ in tr.points]
        src = [s for _, s in tr.points]
        if t.size == 1:
            return Track(track_id, t, z, np.zeros((1, 3)), cov, z, win, src)
        x0 = np.hstack([z, np.gradient(z, t, axis=0)])  # linearisation point [p, v]
        keys = [gtsam.symbol("s", k) for k in range(t.size)]
        linear = gtsam.GaussianFactorGraph()
        point = gtsam.Values()
        h = np.hstack([np.eye(3), np.zeros((3, 3))])  # position measurement z = H x
        for k in range(t.size):
            point.insert(keys[k], x0[k])
            # measurement: e = H (x0 + dx) - z with the fix covariance C, whitened by hand
            # (a JacobianFactor takes only a diagonal model): W = L^-1 with C = L L^T
            w = np.linalg.inv(np.linalg.cholesky(cov[k]))
            linear.push_back(gtsam.JacobianFactor(keys[k], w @ h, w @ (z[k] - h @ x0[k]),
                                                  gtsam.noiseModel.Unit.Create(3)))
        dt = np.diff(t)
        r = wna_sqrt_information(dt, self.q, 3)  # (n-1, 6, 6), R^T R = Q^-1
        unit = gtsam.noiseModel.Unit.Create(6)
        for k in range(dt.size):
            f = transition_matrix(dt[k], 3)
            # motion: R (x_{k+1} - F x_k) = [-R F, R] [dx_k; dx_{k+1}] - b,  b = -R e_0
            e0 = x0[k + 1] - f @ x0[k]
            linear.push_back(gtsam.JacobianFactor(keys[k], -r[k] @ f, keys[k + 1], r[k],
                                                  -r[k] @ e0, unit))
        graph = gtsam.LinearContainerFactor.ConvertLinearGraph(linear, point)
        try:
            result = gtsam.GaussNewtonOptimizer(graph, point).optimize()
            marginals = gtsam.Marginals(graph, result)
            states = np.array([result.atVector(k) for k in keys])
            pcov = np.array([marginals.marginalCovariance(k)[:3, :3] for k in keys])
        except RuntimeError:  # Cholesky refuses: fixes metres wide beside a stiff motion model
            states, pcov = _dense_solve(linear, keys, x0)
        return Track(track_id, t, states[:, :3], states[:, 3:], pcov, z, win, src)


def _dense_solve(linear: gtsam.GaussianFactorGraph, keys: list[int], x0: NDArray
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The linear smoothing problem solved by QR of its dense whitened Jacobian: states
    ``x0 + dx`` (n, 6) and position covariances (n, 3, 3), where GTSAM's Cholesky refuses."""
    order = gtsam.Ordering()
    for k in keys:
        order.push_back(k)
    a, b = linear.jacobian(order)
    q, r = np.linalg.qr(a)
    dx = np.linalg.solve(r, q.T @ b)
    r_inv = np.linalg.solve(r, np.eye(r.shape[0]))
    cov = r_inv @ r_inv.T
    n = len(keys)
    states = x0 + dx.reshape(n, 6)
    pcov = np.array([cov[6 * k:6 * k + 3, 6 * k:6 * k + 3] for k in range(n)])
    return states, pcov
