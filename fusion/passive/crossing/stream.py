"""Crossing detection on bearing tables read in chunks: the grid resampling made streaming.

:func:`fusion.passive.crossing.detect_crossings` puts a whole bearing table on the grid
``t0 + k K`` (:func:`~fusion.passive.bearing_grid.resample_bearings`) and steps a
:class:`~fusion.passive.crossing.detector.CrossingDetector` one grid time at a time. The detector
is online; the resampling looks ahead only a little (a grid value needs the next cell mean of its
track, or the knowledge that none comes within ``max_gap_s``). :class:`StreamingGrid` does the
same resampling on rows arriving in time order, in chunks, and hands out each grid time as soon as
every track's value there is decided, so :func:`detect_crossings_streamed` needs memory for a
chunk and a few cells per track rather than the whole table, and gives the alerts of the batch
path bit for bit.

Exactness: every value is computed with the batch path's operations in the batch path's order
(unwrap with its cumulative correction carried, cell sums accumulated in file order, ``np.interp``
on the same bracketing cell means). One case needs the future: a grid point a hair (at most
``1e-9 K``) after the last cell mean of a track that then falls silent -- its value is that mean
if the track has ended, the interpolation towards the next mean if the track resumes. After
``10 max_gap_s + 2 K`` of silence the track is taken as ended; should it resume after all,
:class:`GridAssumptionBroken` is raised. The caller then makes one more pass
(:func:`scan_long_gaps`: the cell mean after every gap longer than ``max_gap_s``) and starts
again with that knowledge, which leaves nothing to assume.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion._validation import check_grid
from fusion.passive.crossing.batch import step_grid, warn_unpaired
from fusion.passive.crossing.detector import CrossingDetector
from fusion.passive.crossing.types import CrossingAlert

__all__ = ["GridAssumptionBroken", "StreamingGrid", "detect_crossings_streamed", "scan_long_gaps"]

_TAU = 2.0 * np.pi


class GridAssumptionBroken(RuntimeError):
    """A track taken as ended (silent for longer than the look-ahead) resumed (module notes)."""


@dataclass
class _Track:
    """Resampling state of one track (internal, mutable)."""

    p_last: float = math.nan  # last bearing, rad, as read
    csum: float | None = None  # unwrap correction accumulated so far (None before the 2nd row)
    open_cell: int | None = None  # cell of the samples not yet averaged into a knot
    open_t: float = 0.0  # their sums (accumulated in file order, as np.bincount does)
    open_y: float = 0.0
    open_n: int = 0
    open_first: float = math.nan  # first sample time of the open cell
    kt: list[float] = field(default_factory=list)  # final knots not yet passed (times, s)
    ky: list[float] = field(default_factory=list)  # ... and unwrapped bearings, deg
    first_knot: float | None = None
    n_knots: int = 0
    k_next: int | None = None  # next grid index to decide
    assumed_end: bool = False


class StreamingGrid:
    """Resample bearing tracks arriving in time order onto the grid ``origin + k K``.

    Parameters
    ----------
    period_s : float
        Grid period K, s.
    origin_s : float
        Grid origin ``t0``, s: the earliest sample time of the table (the batch default).
    max_gap_s : float, optional
        As in :func:`~fusion.passive.bearing_grid.resample_bearings` (default ``3 K``).
    next_knots : mapping, optional
        :attr:`long_gaps` of a first pass over the same rows (:func:`scan_long_gaps`): with
        it nothing is assumed about tracks that fall silent (module notes), so
        :class:`GridAssumptionBroken` is never raised.

    Notes
    -----
    Feed chunks of rows with :meth:`push` (rows in non-decreasing time over the whole table,
    negative track ids dropped), then call :meth:`finish`; each returns the grid rows decided
    since the previous call, sorted by time then track id, exactly the rows of
    :func:`~fusion.passive.bearing_grid.resample_bearings` on the whole table, in its order.
    """

    def __init__(
        self,
        *,
        period_s: float,
        origin_s: float,
        max_gap_s: float | None = None,
        next_knots: Mapping[int, Mapping[float, tuple[float, float]]] | None = None,
    ) -> None:
        if not (np.isfinite(period_s) and period_s > 0):
            raise ValueError(f"period K must be > 0 s, got {period_s!r}")
        self.K = float(period_s)
        self.t0 = float(origin_s)
        self.gap = 3.0 * self.K if max_gap_s is None else float(max_gap_s)
        if not self.gap > 0:
            raise ValueError(f"max_gap_s must be > 0, got {max_gap_s!r}")
        self.eps = 1e-9 * self.K
        self.lag = 10.0 * self.gap + 2.0 * self.K  # silence after which a track is taken as ended
        self._known = next_knots
        #: Per track, each cell mean followed by the next one more than `max_gap_s` later:
        #: ``{track: {t_m: (t_next, bearing_next)}}`` (unwrapped deg), as far as pushed.
        self.long_gaps: dict[int, dict[float, tuple[float, float]]] = {}
        self._scan = False
        self._tracks: dict[int, _Track] = {}
        self._t_read = -np.inf
        self._out_k: list[NDArray[np.int64]] = []
        self._out_id: list[NDArray[np.int64]] = []
        self._out_b: list[NDArray[np.float64]] = []

    # ----------------------------------------------------------------------------------------
    def _cell(self, t: NDArray[np.float64]) -> NDArray[np.int64]:
        return np.floor((t - self.t0) / self.K + 0.5).astype(np.int64)

    def _k_lo(self, t: float) -> int:
        return int(np.ceil((t - self.t0) / self.K - 1e-9))

    def _k_hi(self, t: float) -> int:
        return int(np.floor((t - self.t0) / self.K + 1e-9))

    def _grid(self, k: NDArray[np.int64]) -> NDArray[np.float64]:
        return self.t0 + k * self.K

    # ----------------------------------------------------------------------------------------
    def push(self, track_id: NDArray, time: NDArray, bearing_deg: NDArray) -> tuple[
            NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        """Add rows (in time order, after those pushed before); the grid rows now decided.

        Returns
        -------
        track_id, time, bearing_deg : ndarray
            Grid rows, sorted by time then track id (``bearing_deg`` in [0, 360)).
        """
        tid = np.asarray(track_id)
        tt = np.asarray(time, dtype=float)
        bb = np.asarray(bearing_deg, dtype=float)
        keep = tid >= 0
        tid, tt, bb = tid[keep].astype(np.int64), tt[keep], bb[keep]
        if tt.size:
            if tt[0] < self._t_read or np.any(np.diff(tt) < 0):
                raise ValueError("rows must come in non-decreasing time")
            for k in np.unique(tid).tolist():
                m = tid == k
                self._add(int(k), tt[m], bb[m])
            self._t_read = float(tt[-1])
        c_read = int(self._cell(np.array([self._t_read]))[0]) if np.isfinite(self._t_read) else None
        for k_id, tr in self._tracks.items():
            if tr.open_cell is not None and c_read is not None and tr.open_cell < c_read:
                self._close_cell(k_id, tr)
        return self._decide(final=False)

    def finish(self) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        """Close the table: the remaining grid rows."""
        for k_id, tr in self._tracks.items():
            if tr.open_cell is not None:
                self._close_cell(k_id, tr)
        return self._decide(final=True)

    # ----------------------------------------------------------------------------------------
    def _add(self, k: int, t: NDArray[np.float64], b: NDArray[np.float64]) -> None:
        tr = self._tracks.get(k)
        if tr is None:
            tr = self._tracks[k] = _Track()
        if tr.assumed_end:
            raise GridAssumptionBroken(f"track {k} resumed at {t[0]:g} s after it was taken as "
                                       "ended")
        p = np.radians(b)
        # np.unwrap (period 2 pi, discont pi) with its cumulative correction carried over
        if np.isnan(tr.p_last):
            first = p[:1]
            p_rest = p[1:]
            prev = p[:-1]
        else:
            first = p[:0]
            p_rest = p
            prev = np.concatenate([[tr.p_last], p[:-1]])
        dd = p_rest - prev
        ddmod = np.mod(dd + np.pi, _TAU) - np.pi
        np.copyto(ddmod, np.pi, where=(ddmod == -np.pi) & (dd > 0))
        ph = ddmod - dd
        np.copyto(ph, 0, where=np.abs(dd) < np.pi)
        if ph.size:
            cs = np.cumsum(ph) if tr.csum is None else np.cumsum(np.concatenate([[tr.csum], ph]))[1:]
            tr.csum = float(cs[-1])
            up = np.concatenate([first, p_rest + cs])
        else:
            up = first
        tr.p_last = float(p[-1])
        unw = np.degrees(up)
        # equal times do not occur within a labelled track; np.bincount's mean of one sample
        ys = (0.0 + unw) / 1
        cells = self._cell(t)
        # sums per cell in file order, the open cell's running sums first
        if tr.open_cell is not None:
            cells_all = np.concatenate([[tr.open_cell], cells])
            t_all = np.concatenate([[tr.open_t], t])
            y_all = np.concatenate([[tr.open_y], ys])
            n_prev = tr.open_n
            first_all = np.concatenate([[tr.open_first], t])
        else:
            cells_all, t_all, y_all, n_prev, first_all = cells, t, ys, 0, t
        starts = np.flatnonzero(np.concatenate([[True], cells_all[1:] != cells_all[:-1]]))
        ids = np.cumsum(np.concatenate([[True], cells_all[1:] != cells_all[:-1]])) - 1
        st = np.bincount(ids, weights=t_all)
        sy = np.bincount(ids, weights=y_all)
        cn = np.bincount(ids)
        if n_prev:
            cn[0] += n_prev - 1  # the carried sums stand for n_prev samples
        n_cells = starts.size
        for i in range(n_cells - 1):  # every cell but the last is complete
            self._knot(k, tr, float(st[i] / cn[i]), float(sy[i] / cn[i]))
        tr.open_cell = int(cells_all[starts[-1]])
        tr.open_t, tr.open_y, tr.open_n = float(st[-1]), float(sy[-1]), int(cn[-1])
        tr.open_first = float(first_all[starts[-1]])

    def _close_cell(self, k_id: int, tr: _Track) -> None:
        self._knot(k_id, tr, tr.open_t / tr.open_n, tr.open_y / tr.open_n)
        tr.open_cell = None

    def _knot(self, k_id: int, tr: _Track, t: float, y: float) -> None:
        """A final cell mean of a track (its last knot stays in `tr.kt` until passed)."""
        if tr.kt and t - tr.kt[-1] > self.gap:
            self.long_gaps.setdefault(k_id, {})[tr.kt[-1]] = (t, y)
        tr.kt.append(t)
        tr.ky.append(y)
        tr.n_knots += 1
        if tr.first_knot is None:
            tr.first_knot = t
            tr.k_next = self._k_lo(t)
        if self._scan:
            del tr.kt[:-1], tr.ky[:-1]

    # ----------------------------------------------------------------------------------------
    def _next_knot(self, k_id: int, t_m: float) -> tuple[float, float] | None:
        """The knot after `t_m` if a first pass saw one more than max_gap_s later."""
        return self._known.get(k_id, {}).get(t_m) if self._known is not None else None

    def _decide(self, *, final: bool):
        if self._scan:  # a pass for the long gaps only
            return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
        horizon = None if final else self._unseen_horizon()
        for k_id, tr in self._tracks.items():
            d = self._decide_track(k_id, tr, final=final)
            if not final:
                horizon = d if horizon is None else min(horizon, d)
        ks = np.concatenate(self._out_k) if self._out_k else np.zeros(0, np.int64)
        ids = np.concatenate(self._out_id) if self._out_id else np.zeros(0, np.int64)
        bs = np.concatenate(self._out_b) if self._out_b else np.zeros(0)
        if final:
            ready = np.ones(ks.size, bool)
        else:
            ready = ks <= horizon
        self._out_k, self._out_id, self._out_b = [ks[~ready]], [ids[~ready]], [bs[~ready]]
        ks, ids, bs = ks[ready], ids[ready], bs[ready]
        order = np.lexsort((ids, ks))
        return ids[order], self._grid(ks[order]), bs[order]

    def _unseen_horizon(self) -> int:
        """Grid indices no track still unseen (or without a knot) can reach."""
        if not np.isfinite(self._t_read):
            return -(1 << 62)
        return int(np.ceil((self._t_read - self.t0) / self.K)) - 2

    def _emit(self, k_id: int, k: NDArray[np.int64], vals: NDArray[np.float64]) -> None:
        if k.size:
            self._out_k.append(k.astype(np.int64))
            self._out_id.append(np.full(k.size, k_id, np.int64))
            self._out_b.append(np.mod(vals, 360.0))

    def _decide_track(self, k_id: int, tr: _Track, *, final: bool) -> int:
        """Decide the grid points of one track that can be; the last index decided for it."""
        if tr.first_knot is None:  # no knot yet: nothing before its first sample
            lb = tr.open_first if tr.open_cell is not None else self._t_read
            return int(np.ceil((lb - self.t0) / self.K)) - 2
        eps = self.eps
        kt, ky = tr.kt, tr.ky
        silent = tr.open_cell is None and self._t_read > kt[-1] + self.lag
        resumes = (tr.n_knots == 1 and silent and not final
                   and self._next_knot(k_id, kt[0]) is not None)
        if tr.n_knots == 1 and not resumes:
            if not (final or silent):
                return tr.k_next - 1  # one knot or more: the rule differs (batch notes)
            # the batch rule of a track of one knot: its value where the grid is within eps
            ks = np.arange(tr.k_next, self._k_hi(kt[0]) + 1, dtype=np.int64)
            g = self._grid(ks)
            ok = np.abs(g - kt[0]) <= eps
            self._emit(k_id, ks[ok], np.full(int(ok.sum()), ky[0]))
            if ks.size:
                tr.k_next = int(ks[-1]) + 1
                # with more knots the grid would be clipped to the knot, or interpolated past it
                tr.assumed_end = tr.assumed_end or (not final and self._known is None
                                                    and bool(np.any(g != kt[0])))
        else:
            self._interpolate(k_id, tr)
        return self._past_last_knot(k_id, tr, final=final, silent=silent)

    def _interpolate(self, k_id: int, tr: _Track) -> None:
        """Grid points up to the last final knot (two or more knots): the batch interpolation."""
        kt, ky, eps = tr.kt, tr.ky, self.eps
        k_hi = self._k_hi(kt[-1])
        check_grid(k_hi + 1 - tr.k_next, f"track {k_id}: a time grid of {self.K:g} s steps from "
                   f"{self._grid(tr.k_next):g} s to {kt[-1]:g} s")
        ks = np.arange(tr.k_next, k_hi + 1, dtype=np.int64)
        g = self._grid(ks)
        inside = g <= kt[-1]
        ks, g = ks[inside], g[inside]
        if ks.size:
            ts, ys = np.asarray(kt), np.asarray(ky)
            gc = np.maximum(g, tr.first_knot)  # np.clip(grid, ts[0], ts[-1]) of the batch
            vals = np.interp(gc, ts, ys)
            if ts.size == 1:  # only gc == ts[0] here (knots before it were passed)
                ok = gc == ts[0]
            else:
                j = np.clip(np.searchsorted(ts, gc, side="right") - 1, 0, ts.size - 2)
                on_sample = np.isclose(gc, ts[j], rtol=0, atol=eps) | np.isclose(
                    gc, ts[j + 1], rtol=0, atol=eps)
                ok = on_sample | ((ts[j + 1] - ts[j]) <= self.gap)
            self._emit(k_id, ks[ok], vals[ok])
            tr.k_next = int(ks[-1]) + 1
        # keep the knots still needed: from the last one at or before the next grid point
        drop = int(np.searchsorted(np.asarray(kt), self.t0 + tr.k_next * self.K,
                                   side="right")) - 1
        if drop > 0:
            del kt[:drop], ky[:drop]

    def _past_last_knot(self, k_id: int, tr: _Track, *, final: bool, silent: bool) -> int:
        """Grid points after the last final knot; the last index decided."""
        t_m, y_m, eps = tr.kt[-1], tr.ky[-1], self.eps
        lb = tr.open_first if tr.open_cell is not None else self._t_read  # next knot >= lb
        k_hi = self._k_hi(t_m)
        while True:
            k0 = tr.k_next
            g0 = self.t0 + k0 * self.K
            if g0 - t_m <= eps or k0 <= k_hi:
                # a hair past the knot: its value if the track ended, else interpolated
                if tr.open_cell is not None or not (final or silent):
                    return k0 - 1
                nxt = None if final else self._next_knot(k_id, t_m)
                if nxt is not None:  # it resumes (a first pass saw it): interpolated
                    ts, ys = np.array([t_m, nxt[0]]), np.array([y_m, nxt[1]])
                    g = np.array([g0])
                    ok = (np.isclose(g, ts[0], rtol=0, atol=eps)
                          | np.isclose(g, ts[1], rtol=0, atol=eps) | (ts[1] - ts[0] <= self.gap))
                    if ok[0]:
                        self._emit(k_id, np.array([k0]), np.interp(g, ts, ys))
                elif k0 <= k_hi:  # it ended: the batch clips the grid to its last knot
                    self._emit(k_id, np.array([k0]), np.array([y_m]))
                tr.assumed_end = tr.assumed_end or (not final and self._known is None)
                tr.k_next = k0 + 1
                continue
            if final:
                return _NEVER  # the track has ended: no more grid points
            if lb > t_m + self.gap and lb > g0 + eps:
                # no grid value before the next knot: the gap is too long
                k_stop = int(np.floor((lb - eps - self.t0) / self.K))
                while self.t0 + k_stop * self.K + eps >= lb:
                    k_stop -= 1
                tr.k_next = max(k0 + 1, k_stop + 1)
                if tr.open_cell is None:
                    return tr.k_next - 1
                continue
            return k0 - 1


_NEVER = 1 << 62


def scan_long_gaps(
    chunks: Iterable[tuple[NDArray, NDArray, NDArray]],
    *,
    period_s: float,
    origin_s: float,
    max_gap_s: float | None = None,
) -> dict[int, dict[float, tuple[float, float]]]:
    """A pass over the rows that only builds the cell means: :attr:`StreamingGrid.long_gaps`.

    Given to :class:`StreamingGrid` (``next_knots``), it lets a second pass decide the grid
    points of tracks that fall silent without assuming anything (module notes). Memory: one
    entry per gap longer than `max_gap_s`.
    """
    grid = StreamingGrid(period_s=period_s, origin_s=origin_s, max_gap_s=max_gap_s)
    grid._scan = True
    for tid, tt, bb in chunks:
        grid.push(tid, tt, bb)
    grid.finish()
    return grid.long_gaps


def detect_crossings_streamed(
    chunks: Iterable[tuple[NDArray, NDArray, NDArray]],
    *,
    origin_s: float,
    next_knots: Mapping[int, Mapping[float, tuple[float, float]]] | None = None,
    K: float,
    **options: Any,
) -> list[CrossingAlert]:
    """Crossing alerts of a bearing table read in chunks (streaming entry point).

    Parameters
    ----------
    chunks : iterable of (track_id, time, bearing_deg) arrays
        The table's rows in chunks, in non-decreasing time over the whole table (rows of track
        -1 are ignored); e.g. the columns of :func:`fusion.io.iter_bearings`' chunks.
    origin_s : float
        Grid origin, s: the earliest time of a labelled track
        (:attr:`BearingSummary.t_min_s`), the origin the batch path takes.
    next_knots : mapping, optional
        :func:`scan_long_gaps` of the same rows: nothing assumed, never a
        :class:`GridAssumptionBroken`.
    K : float
        Grid period, s.
    **options
        The other keywords of :class:`CrossingDetector`, as in
        :func:`~fusion.passive.crossing.detect_crossings`.

    Returns
    -------
    list of CrossingAlert
        The alerts of :func:`~fusion.passive.crossing.detect_crossings` on the whole table, in
        its order.

    Raises
    ------
    GridAssumptionBroken
        A track resumed after it had been taken as ended (module notes); run the batch path.

    Notes
    -----
    *Target Track Crossing Prediction/Detection* takes a bearing of every track every K
    seconds (FIG. 2, block 104A onwards); the grid rows of :class:`StreamingGrid` are those
    samples, and each grid time is one :meth:`CrossingDetector.step
    <fusion.passive.crossing.detector.CrossingDetector.step>` as in the batch path, so the
    equations (2)-(4) and the intervals are evaluated on the same numbers in the same order.

    Examples
    --------
    >>> t = np.arange(0.0, 200.0, 10.0)
    >>> rows = (np.tile([0, 1], t.size), np.repeat(t, 2),
    ...         np.column_stack([10 + 0.1 * t, 20 - 0.1 * t]).ravel())
    >>> alerts = detect_crossings_streamed([rows], origin_s=0.0, J=5, K=10.0)
    >>> sorted({a.kind.value for a in alerts})
    ['detected', 'predicted']
    """
    det = CrossingDetector(K=K, **options)
    grid = StreamingGrid(period_s=det.K, origin_s=origin_s, max_gap_s=det.max_gap_s,
                         next_knots=next_knots)
    alerts: list[CrossingAlert] = []
    ids_seen: list[NDArray[np.int64]] = []

    def steps(rows: tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]) -> None:
        ids_seen.append(rows[0])
        alerts.extend(step_grid(det, *rows))

    for tid, tt, bb in chunks:
        steps(grid.push(tid, tt, bb))
    steps(grid.finish())
    warn_unpaired(det, np.concatenate(ids_seen))
    return alerts

