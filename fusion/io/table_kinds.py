"""Readers of each CSV file kind of the file-format notes: bearings, amplitudes, detections, ...

Each reader names its required columns (:func:`fusion.io.tables.read_table`) and checks what the
kind demands: allowed labels, non-negative amplitudes, scores in [0, 1]. Time series are put in
time order within each track (a stable sort, announced by one warning, when some track is out
of order) and two rows of one track at the same time are refused.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from fusion.io._files import PathLike
from fusion.io.tables import read_table
from fusion.types import Table

__all__ = [
    "ALERT_KINDS",
    "DETECTION_CLUES",
    "TQI_STATES",
    "TRACK_STATUSES",
    "read_alerts",
    "read_amplitudes",
    "read_bearings",
    "read_detections",
    "read_ownship",
    "read_smoothed",
    "read_tma_bearings",
    "read_tma_result",
    "read_tqi",
    "read_tracks",
]

logger = logging.getLogger("fusion.io")  # the package's logger: one name for every reader


def _in_time_order(
    table: Table,
    *,
    time: str = "time",
    by: str | None = None,
    distinct: bool = True,
    ignore_key: int | None = None,
) -> Table:
    """`table` with each `by` group's rows in `time` order; repeated times refused.

    Rows already in order within every group are returned unchanged (interleaved groups stay
    interleaved). Otherwise all rows are stably sorted by `time` -- which puts each group in
    time order and keeps the file order of equal times -- and one warning says so. With
    `distinct`, two rows of one group at the same time are a ValueError (rows of the group
    `ignore_key`, e.g. track -1 of unknown-origin detections, may share times).
    """
    t = table[time]
    keys = table[by] if by is not None else np.zeros(len(t), dtype=np.int64)
    if distinct:
        s = np.lexsort((t, keys))
        dup = (keys[s][1:] == keys[s][:-1]) & (t[s][1:] == t[s][:-1])
        if ignore_key is not None:
            dup &= keys[s][1:] != ignore_key
        if np.any(dup):
            i = int(np.flatnonzero(dup)[0]) + 1
            group = f"{by} {keys[s][i]} has" if by is not None else "there are"
            within = f" within a {by.removesuffix('_id')}" if by is not None else ""
            raise ValueError(f"{table.source}: {group} two rows at {time} {t[s][i]:g}; "
                             f"{time}s must be distinct{within} "
                             "(merge or drop the repeats)")
    g = np.argsort(keys, kind="stable")
    if np.any((keys[g][1:] == keys[g][:-1]) & (np.diff(t[g]) < 0)):
        logger.warning("%s: rows were not in %s order%s; sorted by %s (stable)", table.source,
                       time, f" within each {by.removesuffix('_id')}" if by else "", time)
        return table.select(np.argsort(t, kind="stable"))
    return table


def read_bearings(path: PathLike, *, distinct: bool = True, sigma: bool = False) -> Table:
    """Bearing tracks ``track_id,time,bearing_deg`` (``track_id`` -1: unknown origin).

    Rows need not be sorted: each track's rows are put in time order (see
    :func:`_in_time_order`, one warning if a sort was needed). Two rows of one track
    (``track_id >= 0``) at the same time are an error unless `distinct` is False; rows of
    track -1 may share times. With `sigma` the optional column ``sigma_bearing_deg`` is read
    too.
    """
    t = read_table(path, required=("track_id", "time", "bearing_deg"),
                   optional=("sigma_bearing_deg",) if sigma else (), integer=("track_id",))
    return _in_time_order(t, by="track_id", ignore_key=-1, distinct=distinct)


def read_amplitudes(path: PathLike) -> Table:
    """Tracker outputs ``track_id,time,amplitude,residual`` (amplitude linear, >= 0).

    Each track's rows are put in time order (one warning if a sort was needed); two rows of one
    track at the same time are an error.
    """
    t = read_table(
        path, required=("track_id", "time", "amplitude", "residual"), integer=("track_id",)
    )
    if np.any(t["amplitude"] < 0):
        raise ValueError(f"{t.source}: column 'amplitude' has negative values (expected linear power)")
    return _in_time_order(t, by="track_id")


DETECTION_CLUES = ("snr_db", "score", "aspect_deg", "src_x", "src_y", "rcv_x", "rcv_y", "own_x",
                   "own_y")


def read_detections(path: PathLike) -> Table:
    """Position detections ``event,time,x,y`` plus optional clue columns.

    Optional: ``snr_db, score, aspect_deg, src_x, src_y, rcv_x, rcv_y, own_x, own_y``. ``score`` must lie in
    [0, 1]. Rows are put in ``event`` order (stable; one warning if a sort was needed); many
    detections share an event.
    """
    t = read_table(
        path, required=("event", "time", "x", "y"), optional=DETECTION_CLUES, integer=("event",)
    )
    if "score" in t and np.any((t["score"] < 0) | (t["score"] > 1)):
        raise ValueError(f"{t.source}: column 'score' must lie in [0, 1]")
    return _in_time_order(t, time="event", distinct=False)


def read_ownship(path: PathLike) -> Table:
    """Own-ship positions ``time,x,y``, put in time order; repeated times are an error."""
    return _in_time_order(read_table(path, required=("time", "x", "y")))


def read_tma_bearings(path: PathLike) -> Table:
    """True bearings ``time,bearing_deg`` (clockwise from north), put in time order.

    Repeated times are an error.
    """
    return _in_time_order(read_table(path, required=("time", "bearing_deg")))


TQI_STATES = ("lost", "uncertain", "low_snr", "strong")
TRACK_STATUSES = ("tentative", "confirmed", "deleted")
ALERT_KINDS = ("predicted", "detected")


def _require_values(table: Table, col: str, allowed: Sequence[str]) -> None:
    bad = sorted(set(table[col].tolist()) - set(allowed))
    if bad:
        raise ValueError(
            f"{table.source}: column {col!r} has value(s) {', '.join(bad)} (allowed: {', '.join(allowed)})"
        )


def read_tqi(path: PathLike) -> Table:
    """Output of ``fusion tqi``: the amplitude columns plus ``tqi`` (lost/uncertain/low_snr/strong)."""
    t = read_table(
        path,
        required=("track_id", "time", "amplitude", "residual", "tqi"),
        integer=("track_id",),
        text=("tqi",),
        max_abs=None,
    )
    _require_values(t, "tqi", TQI_STATES)
    return t


def read_tracks(path: PathLike) -> Table:
    """Output of ``fusion track``: ``track_id,event,time,x,y,vx,vy,status``."""
    t = read_table(
        path,
        required=("track_id", "event", "time", "x", "y", "vx", "vy", "status"),
        integer=("track_id", "event"),
        text=("status",),
        max_abs=None,
    )
    _require_values(t, "status", TRACK_STATUSES)
    return t


def read_alerts(path: PathLike) -> Table:
    """Output of ``fusion crossings``: ``time,track_a,track_b,t_cross,kind``."""
    t = read_table(
        path,
        required=("time", "track_a", "track_b", "t_cross", "kind"),
        integer=("track_a", "track_b"),
        text=("kind",),
        max_abs=None,
    )
    _require_values(t, "kind", ALERT_KINDS)
    return t


def read_smoothed(path: PathLike) -> Table:
    """Output of ``fusion smooth``.

    Columns ``track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg``.
    """
    return read_table(
        path,
        required=("track_id", "time", "bearing_deg", "bearing_rate_deg_per_min", "sigma_bearing_deg"),
        integer=("track_id",),
        max_abs=None,
    )


def read_tma_result(path: PathLike) -> Table:
    """Output of ``fusion tma``: ``time,x,y,vx,vy,sigma_x,sigma_y,range``."""
    return read_table(path, required=("time", "x", "y", "vx", "vy", "sigma_x", "sigma_y", "range"),
                      max_abs=None)
