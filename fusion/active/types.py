"""Data of the multistatic tracker: a ping's detections, the tracks after a ping, a whole run.

Frozen dataclasses (the tracker never mutates them) and the grouping of detection rows
(``event,time,x,y`` plus optional clue columns, the detections format of ``fusion track``) into
pings. Rows come as columns: a mapping of column name to array, e.g. a
:class:`fusion.io.Table` read by :func:`fusion.io.read_detections`.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._validation import MAX_EMPTY_PINGS, check_grid

__all__ = [
    "CLUE_COLUMNS",
    "POSITION_CLUES",
    "SENSOR_CLUES",
    "Columns",
    "Ping",
    "PingResult",
    "TrackingResult",
    "check_tracker_options",
    "iter_pings",
    "pings_from_columns",
    "receiver_groups",
]

#: Source and receiver position columns of a bistatic detection, m.
POSITION_CLUES: tuple[str, ...] = ("src_x", "src_y", "rcv_x", "rcv_y")
#: Position of a monostatic sensor's platform (own ship) at the detection, m.
SENSOR_CLUES: tuple[str, ...] = ("own_x", "own_y")
#: Optional per-detection columns the tracker reads.
CLUE_COLUMNS: tuple[str, ...] = ("snr_db", "score", "aspect_deg", *POSITION_CLUES, *SENSOR_CLUES)


class Columns(Protocol):
    """Named columns of equal length (a dict of arrays, or a :class:`fusion.io.Table`)."""

    def __getitem__(self, name: str) -> ArrayLike: ...

    def __contains__(self, name: object) -> bool: ...

    def __len__(self) -> int: ...


@dataclass(frozen=True)
class Ping:
    """The detections of one event (ping or scan).

    Attributes
    ----------
    event : int
        Event index.
    time : float
        Event time, s.
    xy : ndarray, shape (n, 2)
        Detection positions (x east, y north), m.
    clues : dict of str to ndarray, shape (n,)
        Optional per-detection clues among ``snr_db``, ``score``, ``aspect_deg`` and positions
        ``src_x, src_y, rcv_x, rcv_y``, ``own_x, own_y`` (m).
    """

    event: int
    time: float
    xy: NDArray[np.float64]
    clues: Mapping[str, NDArray[np.float64]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        xy = np.asarray(self.xy, dtype=float).reshape(-1, 2) if np.size(self.xy) else np.zeros((0, 2))
        if not np.all(np.isfinite(xy)) or not np.isfinite(self.time):
            raise ValueError(f"event {self.event}: positions and time must be finite")
        clues = {}
        for k, v in self.clues.items():
            a = np.asarray(v, dtype=float).reshape(-1)
            if a.shape != (xy.shape[0],):
                raise ValueError(f"event {self.event}: clue {k!r} has {a.size} values for "
                                 f"{xy.shape[0]} detections")
            clues[k] = a
        object.__setattr__(self, "xy", xy)
        object.__setattr__(self, "clues", clues)

    @property
    def n(self) -> int:
        """Number of detections."""
        return int(self.xy.shape[0])

    def subset(self, index: ArrayLike) -> Ping:
        """The ping with only the detections `index` (ints or a boolean mask), clues included."""
        idx = np.asarray(index)
        return Ping(self.event, self.time, self.xy[idx], {k: v[idx] for k, v in self.clues.items()})



def pings_from_columns(columns: Columns | Mapping[str, ArrayLike]) -> list[Ping]:
    """Group detection rows (``event,time,x,y`` + optional clue columns) into pings.

    Event numbers missing between the first and the last become empty pings at times
    interpolated linearly between their neighbours.

    Parameters
    ----------
    columns : mapping of str to array_like, each shape (n,)
        ``event`` (int), ``time`` (s), ``x``, ``y`` (m) and any of :data:`CLUE_COLUMNS`; other
        columns are ignored. A :class:`fusion.io.Table` will do.

    Returns
    -------
    list of Ping
        One per event from the smallest to the largest event number.

    Examples
    --------
    >>> pings = pings_from_columns({"event": [0, 2], "time": [0.0, 100.0], "x": [1.0, 2.0],
    ...                             "y": [0.0, 0.0]})
    >>> [(p.event, p.time, p.n) for p in pings]
    [(0, 0.0, 1), (1, 50.0, 0), (2, 100.0, 1)]
    """
    if len(columns["event"]) == 0:
        return []
    ev = np.asarray(columns["event"]).astype(np.int64)
    order = np.argsort(ev, kind="stable")
    ev = ev[order]
    t = np.asarray(columns["time"], dtype=float)[order]
    xy = np.column_stack([columns["x"], columns["y"]]).astype(float)[order]
    clues = {c: np.asarray(columns[c], dtype=float)[order] for c in CLUE_COLUMNS if c in columns}
    uniq, start = np.unique(ev, return_index=True)
    stop = np.append(start[1:], ev.size)
    t_event = t[start]
    gaps = np.diff(uniq) - 1
    if gaps.size and gaps.max() > 0:  # as iter_pings: the longest run of pings without detections
        k = int(np.argmax(gaps))
        check_grid(int(gaps[k]), f"event {uniq[k + 1]} after event {uniq[k]}: pings without "
                   "detections", limit=MAX_EMPTY_PINGS)
    all_events = np.arange(uniq[0], uniq[-1] + 1)
    all_times = np.interp(all_events, uniq, t_event)
    by_event = {int(e): (a, b) for e, a, b in zip(uniq, start, stop, strict=True)}
    pings = []
    for e, te in zip(all_events, all_times, strict=True):
        a, b = by_event.get(int(e), (0, 0))
        pings.append(Ping(int(e), float(te), xy[a:b], {k: v[a:b] for k, v in clues.items()}))
    return pings


def iter_pings(chunks: Iterable[Columns | Mapping[str, ArrayLike]]) -> Iterator[Ping]:
    """Pings from consecutive chunks of detection rows, one ping at a time.

    The streaming form of :func:`pings_from_columns` for rows already in event order (as
    :func:`fusion.io.iter_detections` yields them): an event may be split between two chunks;
    memory holds one chunk and one event.

    Parameters
    ----------
    chunks : iterable of mapping of str to array_like
        Consecutive rows with columns ``event, time, x, y`` and any of :data:`CLUE_COLUMNS`
        (the same in every chunk), ``event`` non-decreasing over all chunks.

    Yields
    ------
    Ping
        One per event from the first to the last event number; missing event numbers become
        empty pings at times interpolated between their neighbours, as in
        :func:`pings_from_columns`.

    Examples
    --------
    >>> rows = [{"event": [0, 0], "time": [0.0, 0.0], "x": [1.0, 2.0], "y": [0.0, 0.0]},
    ...         {"event": [0, 3], "time": [0.0, 90.0], "x": [3.0, 4.0], "y": [0.0, 0.0]}]
    >>> [(p.event, p.time, p.n) for p in iter_pings(rows)]
    [(0, 0.0, 3), (1, 30.0, 0), (2, 60.0, 0), (3, 90.0, 1)]
    """
    held: dict[str, NDArray[np.float64]] | None = None   # rows of the last event so far
    last: tuple[int, float] | None = None                # last event yielded and its time

    def emit(rows: dict[str, NDArray[np.float64]]) -> Iterator[Ping]:
        nonlocal last
        e, t = int(rows["event"][0]), float(rows["time"][0])
        if last is not None and e > last[0] + 1:
            check_grid(e - last[0] - 1, f"event {e} after event {last[0]}: pings without "
                       "detections", limit=MAX_EMPTY_PINGS)
            gap = np.arange(last[0] + 1, e)
            for g, tg in zip(gap, np.interp(gap, [last[0], e], [last[1], t]), strict=True):
                yield Ping(int(g), float(tg), np.zeros((0, 2)),
                           {k: np.zeros(0) for k in rows if k in CLUE_COLUMNS})
        last = (e, t)
        yield Ping(e, t, np.column_stack([rows["x"], rows["y"]]),
                   {k: v for k, v in rows.items() if k in CLUE_COLUMNS})

    for chunk in chunks:
        if len(chunk["event"]) == 0:
            continue
        rows = {"event": np.asarray(chunk["event"]).astype(np.int64)}
        for k in ("time", "x", "y", *CLUE_COLUMNS):
            if k in chunk:
                rows[k] = np.asarray(chunk[k], dtype=float)
        if held is not None:
            rows = {k: np.concatenate([held[k], v]) for k, v in rows.items()}
        ev = rows["event"]
        if np.any(np.diff(ev) < 0) or (last is not None and ev[0] <= last[0]):
            raise ValueError("detections must come in non-decreasing event order")
        cut = np.flatnonzero(np.diff(ev)) + 1
        bounds = np.concatenate([[0], cut, [ev.size]])
        for a, b in zip(bounds[:-2], bounds[1:-1], strict=True):
            yield from emit({k: v[a:b] for k, v in rows.items()})
        held = {k: v[bounds[-2]:] for k, v in rows.items()}
    if held is not None:
        yield from emit(held)


def receiver_groups(ping: Ping) -> list[tuple[tuple[float, ...] | None, NDArray[np.int64]]]:
    """Split a ping's detections by receiver (source-receiver geometry).

    Parameters
    ----------
    ping : Ping

    Returns
    -------
    list of (key, ndarray of int)
        One entry per geometry, in the order of first appearance: the key (``src_x, src_y,
        rcv_x, rcv_y`` rounded to 1 m) and the indices of its detections. A ping without (or
        with non-finite) source/receiver positions is one group with key None.

    Examples
    --------
    >>> ping = Ping(0, 0.0, [[0, 0], [1, 1], [2, 2]],
    ...             {"src_x": [0, 0, 0], "src_y": [0, 0, 0], "rcv_x": [5, 9, 5], "rcv_y": [0, 0, 0]})
    >>> [(k, i.tolist()) for k, i in receiver_groups(ping)]
    [((0.0, 0.0, 5.0, 0.0), [0, 2]), ((0.0, 0.0, 9.0, 0.0), [1])]
    """
    cached = ping.__dict__.get("_receiver_groups")
    if cached is not None:
        return cached
    if ping.n == 0:
        out = []
    elif not all(k in ping.clues for k in POSITION_CLUES):
        out = [(None, np.arange(ping.n))]
    else:
        geo = np.column_stack([ping.clues[k] for k in POSITION_CLUES])
        if not np.all(np.isfinite(geo)):
            out = [(None, np.arange(ping.n))]
        else:
            # Rounded rows (+ 0.0: -0.0 and 0.0 are one key, as in a dict), grouped in the
            # order of each geometry's first detection.
            r = np.round(geo) + 0.0
            _, first, inv = np.unique(r, axis=0, return_index=True, return_inverse=True)
            inv = inv.reshape(-1)
            out = [(tuple(r[first[g]].tolist()), np.flatnonzero(inv == g).astype(np.int64))
                   for g in np.argsort(first).tolist()]
    object.__setattr__(ping, "_receiver_groups", out)   # a ping's grouping never changes
    return out


@dataclass(frozen=True)
class PingResult:
    """Tracks after one ping.

    Attributes
    ----------
    event : int
    time : float
        s.
    track_id : ndarray of int, shape (k,)
        Tracks alive before or born on this ping (deleted ones included once, with their last
        state).
    state : ndarray, shape (k, 4)
        ``x, y, vx, vy`` (m, m/s): posterior, or prediction for a track without a detection.
    status : ndarray of str, shape (k,)
        ``tentative``, ``confirmed`` or ``deleted``.
    detection : ndarray of int, shape (k,)
        Index of the associated detection in the ping, -1 when none (the birth detection for
        new tracks).
    rank : ndarray, shape (k,)
        Rank (fuzzy) or likelihood ratio (kalman) of the associated pair; NaN when none.
    hotspots : ndarray, shape (h, 2)
        Clutter-map hotspots after this ping, m (empty in kalman mode).
    covariance : ndarray, shape (k, 4, 4)
        Covariance of ``state`` (m^2, m^2/s, m^2/s^2).
    measurement : ndarray, shape (k, 2)
        Position of the associated (or birth) detection, m; NaN when none.
    measurement_cov : ndarray, shape (k, 2, 2)
        Position covariance of that detection as the tracker used it, m^2; NaN when none.
    detections : tuple of ndarray of int
        Per track, every detection of the ping it took (one per receiver at most; the first is
        `detection`); empty when none. When a track took several, `measurement` and
        `measurement_cov` are their information-weighted fusion
        ``C = (sum R_i^-1)^-1``, ``z = C sum R_i^-1 z_i`` (one equivalent measurement).
    """

    event: int
    time: float
    track_id: NDArray[np.int64]
    state: NDArray[np.float64]
    status: NDArray[np.str_]
    detection: NDArray[np.int64]
    rank: NDArray[np.float64]
    hotspots: NDArray[np.float64]
    covariance: NDArray[np.float64]
    measurement: NDArray[np.float64]
    measurement_cov: NDArray[np.float64]
    detections: tuple[NDArray[np.int64], ...] = ()


@dataclass(frozen=True)
class TrackingResult:
    """All pings of a run.

    Attributes
    ----------
    pings : tuple of PingResult
    """

    pings: tuple[PingResult, ...]

    def columns(self) -> dict[str, NDArray]:
        """Output rows ``track_id,event,time,x,y,vx,vy,status``, one per track per event."""
        if not self.pings:
            empty = np.zeros(0)
            return {"track_id": empty.astype(np.int64), "event": empty.astype(np.int64),
                    "time": empty, "x": empty, "y": empty, "vx": empty, "vy": empty,
                    "status": np.zeros(0, dtype=str)}
        k = [p.track_id.size for p in self.pings]
        state = np.concatenate([p.state for p in self.pings]).reshape(-1, 4)
        return {
            "track_id": np.concatenate([p.track_id for p in self.pings]).astype(np.int64),
            "event": np.repeat([p.event for p in self.pings], k).astype(np.int64),
            "time": np.repeat([p.time for p in self.pings], k).astype(float),
            "x": state[:, 0], "y": state[:, 1], "vx": state[:, 2], "vy": state[:, 3],
            "status": np.concatenate([p.status for p in self.pings]).astype(str),
        }

    def confirmed_ids(self) -> NDArray[np.int64]:
        """Ids of the tracks that were confirmed at some ping."""
        ids = [p.track_id[p.status == "confirmed"] for p in self.pings]
        return np.unique(np.concatenate(ids)) if ids else np.zeros(0, np.int64)



def check_tracker_options(*, mode: str, speed_sigma_mps: float, accel_psd: float,
                          confirm: tuple[int, int], max_misses: int,
                          coast_probability: float | None, noise: str,
                          score_threshold: float | None) -> None:
    """Raise ValueError for a bad option of :class:`fusion.active.tracker.Tracker`."""
    confirm_hits, confirm_window = confirm
    if mode not in ("fuzzy", "kalman"):
        raise ValueError(f"mode must be 'fuzzy' or 'kalman', got {mode!r}")
    if not np.isfinite(speed_sigma_mps) or speed_sigma_mps <= 0:
        raise ValueError(f"speed_sigma_mps must be positive, got {speed_sigma_mps!r}")
    if not np.isfinite(accel_psd) or accel_psd < 0:
        raise ValueError(f"accel_psd must be >= 0, got {accel_psd!r}")
    if not 1 <= confirm_hits <= confirm_window:
        raise ValueError("need 1 <= confirm_hits <= confirm_window, got "
                         f"{confirm_hits} and {confirm_window}")
    if max_misses < 1 or not (coast_probability is None or 0.0 < coast_probability < 1.0):
        raise ValueError(f"need max_misses >= 1 and coast_probability in (0, 1), got "
                         f"{max_misses!r}, {coast_probability!r}")
    if noise not in ("estimate", "fixed"):
        raise ValueError(f"noise must be 'estimate' or 'fixed', got {noise!r}")
    if score_threshold is not None and not 0.0 <= score_threshold <= 1.0:
        raise ValueError(f"score_threshold must lie in [0, 1], got {score_threshold!r}")
