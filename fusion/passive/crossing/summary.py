"""One pass over a bearing table's chunks: what the crossing settings need of the whole table.

:func:`~fusion.passive.crossing.settings.crossing_settings` takes the median time step within
tracks and the median track span from the data. Read in chunks, the table is not held at once;
:class:`BearingStats` collects, chunk by chunk, exactly the numbers those medians need (first and
last time per track, the distinct steps with their counts), so the settings of the streamed path
are those of the whole-table path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["BearingStats", "BearingSummary"]


@dataclass(frozen=True)
class BearingSummary:
    """What the crossing settings need of a bearing table, from one pass over its chunks.

    Attributes
    ----------
    track_ids : ndarray of int64, shape (n_tracks,)
        Labelled tracks (``track_id >= 0``), sorted.
    first_s, last_s : ndarray, shape (n_tracks,)
        Each track's first and last sample time, s.
    step_s : float or None
        Median positive time step within tracks, s (:func:`~fusion.passive.bearing_grid.
        estimate_period` of the whole table); None when no track has two distinct times.
    t_min_s : float
        Earliest sample time of a labelled track, s (the grid origin).
    n_unknown : int
        Rows of track -1.
    time_ordered : bool
        Rows of labelled tracks come in non-decreasing time over the whole file (what
        :class:`StreamingGrid` needs).
    """

    track_ids: NDArray[np.int64]
    first_s: NDArray[np.float64]
    last_s: NDArray[np.float64]
    step_s: float | None
    t_min_s: float
    n_unknown: int
    time_ordered: bool

    @property
    def spans_s(self) -> NDArray[np.float64]:
        """Each track's time span, s (``np.ptp`` of its times)."""
        return self.last_s - self.first_s


class BearingStats:
    """Accumulate a :class:`BearingSummary` over chunks of a bearing table (rows of each
    track in time order, as the chunked reader checks).

    The median step is exact: the distinct steps are kept with their counts (a few values for
    regularly sampled data, at most one per row otherwise).
    """

    def __init__(self) -> None:
        self._ids = np.zeros(0, np.int64)
        self._first = np.zeros(0)
        self._last = np.zeros(0)
        self._steps = np.zeros(0)
        self._counts = np.zeros(0, np.int64)
        self._n_unknown = 0
        self._t_prev = -np.inf
        self._ordered = True

    def add(self, track_id: NDArray, time: NDArray) -> None:
        """Add the rows of one chunk (in file order)."""
        tid = np.asarray(track_id, dtype=np.int64)
        tt = np.asarray(time, dtype=float)
        known = tid >= 0
        self._n_unknown += int(np.sum(~known))
        tid, tt = tid[known], tt[known]
        if tid.size == 0:
            return
        if tt[0] < self._t_prev or np.any(np.diff(tt) < 0):
            self._ordered = False
        self._t_prev = max(self._t_prev, float(tt.max()))
        g = np.argsort(tid, kind="stable")
        kg, tg = tid[g], tt[g]
        head = np.concatenate([[True], kg[1:] != kg[:-1]])
        tail = np.concatenate([kg[1:] != kg[:-1], [True]])
        # steps within the chunk, and from each track's last time of earlier chunks
        steps = [np.diff(tg)[~head[1:]]]
        pos = np.minimum(np.searchsorted(self._ids, kg[head]), max(self._ids.size - 1, 0))
        seen = (self._ids[pos] == kg[head]) if self._ids.size else np.zeros(int(head.sum()), bool)
        steps.append(tg[head][seen] - self._last[pos[seen]])
        d = np.concatenate(steps)
        d = d[d > 0]
        if d.size:  # distinct steps with their counts
            vals, inv = np.unique(np.concatenate([self._steps, d]), return_inverse=True)
            counts = np.bincount(inv, weights=np.concatenate([self._counts, np.ones(d.size)]))
            self._steps, self._counts = vals, np.rint(counts).astype(np.int64)
        # first and last time of each track
        new = ~seen
        ids = np.concatenate([self._ids, kg[head][new]])
        first = np.concatenate([self._first, tg[head][new]])
        last = np.concatenate([self._last, np.zeros(int(new.sum()))])
        order = np.argsort(ids, kind="stable")
        self._ids, self._first, last = ids[order], first[order], last[order]
        last[np.searchsorted(self._ids, kg[tail])] = tg[tail]
        self._last = last

    def summary(self) -> BearingSummary:
        """The summary of the rows added so far."""
        step = None
        n = int(self._counts.sum())
        if n:
            cum = np.cumsum(self._counts)
            lo = float(self._steps[np.searchsorted(cum, (n - 1) // 2, side="right")])
            hi = float(self._steps[np.searchsorted(cum, n // 2, side="right")])
            # np.median of the whole multiset: the middle value, or the mean of the two
            step = float(np.median(np.array([lo, hi]) if n % 2 == 0 else np.array([lo])))
        t_min = float(self._first.min()) if self._first.size else np.nan
        return BearingSummary(self._ids.copy(), self._first.copy(), self._last.copy(), step,
                              t_min, self._n_unknown, self._ordered)
