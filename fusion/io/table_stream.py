"""Chunked readers of the time-series CSV kinds, for commands whose algorithm is online.

:func:`iter_amplitudes`, :func:`iter_bearings` and :func:`iter_detections` yield a file's rows in
chunks (:class:`~fusion.io.tables.TableChunk`) with every check of the whole-file readers of
:mod:`fusion.io.table_kinds` -- header and columns, text, NaN/inf, numbers beyond the bound,
over-long lines and fields, allowed values -- and the row-order checks carried across chunk
boundaries by a :class:`TimeOrderCheck`. Each takes the CSV file `path` and `rows_per_chunk`
(rows per chunk, default 65,536), as :func:`~fusion.io.tables.iter_table` does.

Row order is where a chunked reader differs: the whole-file readers sort rows that are out of time
order (with one warning) and name the first repeated time in track order; a chunked reader cannot
sort what it has already handed on, so it raises :class:`RowOrderError` at the first row out of
order or repeated. Commands catch it and start again with the whole-file reader, which then sorts
(or refuses the repeat with its usual message), so results and messages are those of the
whole-file path. Rows in order -- the usual case for tracker output -- are read once.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from fusion.io._files import _ROWS_PER_CHUNK, PathLike
from fusion.io.table_kinds import DETECTION_CLUES
from fusion.io.tables import TableChunk, iter_table

__all__ = [
    "RowOrderError",
    "TimeOrderCheck",
    "iter_amplitudes",
    "iter_bearings",
    "iter_detections",
]


class RowOrderError(ValueError):
    """A row is out of time order, or repeats a time, within its group (found while streaming).

    A :class:`ValueError`, so a command that does not catch it still reports one line; commands
    that read in chunks catch it and read the whole file instead (module notes).
    """


class TimeOrderCheck:
    """Check that each group's rows come in time order, across the chunks of one file.

    Parameters
    ----------
    source : str
        File name for messages.
    time : str, optional
        Column of times (``"event"`` for detections).
    by : str or None, optional
        Column of group keys (``"track_id"``); None: one group.
    distinct : bool, optional
        Two rows of one group at the same time are refused as well.
    ignore_key : int or None, optional
        Group whose rows may share times (track -1, detections of unknown origin); they must
        still come in time order.

    Notes
    -----
    The check keeps the last time of every group seen so far (memory: one entry per group), so
    a row is compared with its group's previous row even when a chunk boundary lies between
    them. Rows of different groups may interleave freely.
    """

    def __init__(
        self,
        *,
        source: str,
        time: str = "time",
        by: str | None = None,
        distinct: bool = True,
        ignore_key: int | None = None,
    ) -> None:
        self.source = source
        self.time = time
        self.by = by
        self.distinct = bool(distinct)
        self.ignore_key = ignore_key
        self._keys = np.zeros(0, np.int64)  # groups seen, sorted
        self._last = np.zeros(0)  # last time of each

    def check(self, chunk: TableChunk) -> None:
        """Raise :class:`RowOrderError` at the chunk's first row out of order; else remember it.

        Parameters
        ----------
        chunk : TableChunk
            The next chunk of the file (chunks in file order).
        """
        t = np.asarray(chunk.table[self.time], dtype=float)
        n = t.size
        if n == 0:
            return
        keys = (np.asarray(chunk.table[self.by], dtype=np.int64) if self.by is not None
                else np.zeros(n, np.int64))
        g = np.argsort(keys, kind="stable")  # each group's rows, in file order
        kg, tg = keys[g], t[g]
        first = np.ones(n, bool)
        first[1:] = kg[1:] != kg[:-1]
        prev = np.empty(n)
        prev[1:] = tg[:-1]
        # a group's first row in this chunk is compared with its last row of earlier chunks
        prev_first = np.full(int(first.sum()), -np.inf)
        if self._keys.size:
            kf = kg[first]
            pos = np.minimum(np.searchsorted(self._keys, kf), self._keys.size - 1)
            seen = self._keys[pos] == kf
            prev_first[seen] = self._last[pos[seen]]
        prev[first] = prev_first
        bad = tg < prev
        if self.distinct:
            same = tg == prev
            if self.ignore_key is not None:
                same &= kg != self.ignore_key
            bad |= same
        if np.any(bad):
            i = int(np.argmin(np.where(bad, chunk.lines[g], np.iinfo(np.int64).max)))
            what = "at the same" if tg[i] == prev[i] else "before the"
            group = f" of {self.by} {kg[i]}" if self.by is not None else ""
            raise RowOrderError(
                f"{self.source}: line {chunk.lines[g][i]}: {self.time} {tg[i]:g}{group} is "
                f"{what} {self.time} of an earlier row; rows must be in {self.time} order "
                "to be read in chunks")
        last = np.flatnonzero(np.append(kg[1:] != kg[:-1], True))  # each group's last row
        keys_all = np.concatenate([self._keys, kg[last]])
        last_all = np.concatenate([self._last, tg[last]])
        order = np.argsort(keys_all, kind="stable")
        keys_all, last_all = keys_all[order], last_all[order]
        keep = np.append(keys_all[1:] != keys_all[:-1], True)  # the chunk's value wins
        self._keys, self._last = keys_all[keep], last_all[keep]


def _checked(
    chunks: Iterator[TableChunk], order: TimeOrderCheck, *, amplitude: bool = False,
    score: bool = False,
) -> Iterator[TableChunk]:
    for c in chunks:
        t = c.table
        if amplitude and np.any(t["amplitude"] < 0):
            raise ValueError(f"{t.source}: column 'amplitude' has negative values "
                             "(expected linear power)")
        if score and "score" in t and np.any((t["score"] < 0) | (t["score"] > 1)):
            raise ValueError(f"{t.source}: column 'score' must lie in [0, 1]")
        order.check(c)
        yield c


def iter_amplitudes(path: PathLike, *, rows_per_chunk: int = _ROWS_PER_CHUNK) -> Iterator[TableChunk]:
    """Tracker outputs ``track_id,time,amplitude,residual`` in chunks of rows.

    The checks of :func:`fusion.io.read_amplitudes`, chunk by chunk; each track's rows must
    come in strictly increasing time (tracks may interleave), else :class:`RowOrderError`.

    Yields
    ------
    TableChunk
        Columns ``track_id`` (int64), ``time``, ``amplitude``, ``residual``.
    """
    chunks = iter_table(path, required=("track_id", "time", "amplitude", "residual"),
                        integer=("track_id",), rows_per_chunk=rows_per_chunk)
    order = TimeOrderCheck(source=str(path), by="track_id")
    return _checked(chunks, order, amplitude=True)


def iter_bearings(path: PathLike, *, rows_per_chunk: int = _ROWS_PER_CHUNK) -> Iterator[TableChunk]:
    """Bearing tracks ``track_id,time,bearing_deg`` in chunks of rows.

    The checks of :func:`fusion.io.read_bearings`, chunk by chunk; each track's rows must come
    in strictly increasing time (rows of track -1 in non-decreasing time), else
    :class:`RowOrderError`.

    Yields
    ------
    TableChunk
        Columns ``track_id`` (int64), ``time`` (s), ``bearing_deg`` (deg).
    """
    chunks = iter_table(path, required=("track_id", "time", "bearing_deg"),
                        integer=("track_id",), rows_per_chunk=rows_per_chunk)
    order = TimeOrderCheck(source=str(path), by="track_id", ignore_key=-1)
    return _checked(chunks, order)


def iter_detections(path: PathLike, *, rows_per_chunk: int = _ROWS_PER_CHUNK) -> Iterator[TableChunk]:
    """Position detections ``event,time,x,y`` (plus optional clues) in chunks of rows.

    The checks of :func:`fusion.io.read_detections`, chunk by chunk (``score`` in [0, 1]);
    rows must come in non-decreasing ``event`` (many detections share an event), else
    :class:`RowOrderError`. An event may be split between two chunks.

    Yields
    ------
    TableChunk
        Columns ``event`` (int64), ``time``, ``x``, ``y`` and the clue columns present
        (:data:`fusion.io.DETECTION_CLUES`).
    """
    chunks = iter_table(path, required=("event", "time", "x", "y"), optional=DETECTION_CLUES,
                        integer=("event",), rows_per_chunk=rows_per_chunk)
    order = TimeOrderCheck(source=str(path), time="event", distinct=False)
    return _checked(chunks, order, score=True)

