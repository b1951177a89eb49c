"""Checks of the upstream Autoferry JSON files: shapes, finite and plausible numbers.

:func:`parse_scans` and :func:`parse_ground_truth` turn the decoded JSON of
``scenarioN_detections.json`` and ``scenarioN_groundTruth.json`` into arrays, or raise one
ValueError naming the file, the scan or entry, and what is wrong. Nothing that is not finite
or plausible (:data:`UNIX_TIME_RANGE`, :data:`MAX_SPAN_S`, :data:`MAX_POSITION_M`,
:data:`MAX_BEARING_RAD`) gets through to the CSV files the import writes.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["MAX_BEARING_RAD", "MAX_POSITION_M", "MAX_SPAN_S", "UNIX_TIME_RANGE", "SENSOR_NAMES",
           "parse_ground_truth", "parse_scans"]

#: Scan and GNSS times are Unix seconds: 1970 to 2286.
UNIX_TIME_RANGE = (0.0, 1e10)
#: Longest plausible scenario, s (a week): times beyond are an export or unit error.
MAX_SPAN_S = 7 * 86400.0
#: Largest plausible north/east coordinate in the local frame, or offset of a detection, m
#: (10,000 km: beyond it is not a position near the frame origin).
MAX_POSITION_M = 1e7
#: Largest plausible camera bearing, rad (upstream bearings lie in [-pi, pi]; degrees given
#: by mistake are mostly beyond it).
MAX_BEARING_RAD = 4 * math.pi
#: Upstream sensor ids.
SENSOR_NAMES = {1: "lidar", 2: "radar", 3: "IR", 4: "EO"}


def _num(value: Any, where: str, what: str, limit: float | None = None) -> float:
    """`value` as a finite float (not a bool, not text) within +-`limit`."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{where}: {what} is {_show(value)}, not a number")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{where}: {what} is {v}, not a finite number")
    if limit is not None and abs(v) > limit:
        raise ValueError(f"{where}: {what} = {v:g} is beyond +-{limit:g}, implausible "
                         "(check units)")
    return v


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:40] + "..."


def _unix_time(value: Any, where: str) -> float:
    t = _num(value, where, "'time'")
    lo, hi = UNIX_TIME_RANGE
    if not lo <= t <= hi:
        raise ValueError(f"{where}: 'time' = {t:g} is not a Unix time in s ({lo:g}..{hi:g})")
    return t


def _numbers(values: Any, where: str, what: str, limit: float) -> list[float]:
    if not isinstance(values, list):
        raise ValueError(f"{where}: {what} is {_show(values)}, expected a list of numbers")
    return [_num(v, where, f"{what} value", limit) for v in values]


def _positions(meas: Any, where: str) -> NDArray[np.float64]:
    """A radar/lidar measurement as (M, 2) north, east offsets, m."""
    shape_help = "expected [north, east] or [[north, ...], [east, ...]]"
    if not isinstance(meas, list):
        raise ValueError(f"{where}: 'measurement' is {_show(meas)}; {shape_help}")
    if not meas:
        return np.zeros((0, 2))
    if all(isinstance(m, list) for m in meas):
        if len(meas) != 2 or len(meas[0]) != len(meas[1]):
            sizes = [len(m) for m in meas]
            raise ValueError(f"{where}: 'measurement' has rows of {sizes} values; {shape_help}")
        north = _numbers(meas[0], where, "'measurement'", MAX_POSITION_M)
        east = _numbers(meas[1], where, "'measurement'", MAX_POSITION_M)
        return np.column_stack([north, east]).reshape(-1, 2)
    flat = _numbers(meas, where, "'measurement'", MAX_POSITION_M)
    if len(flat) != 2:
        raise ValueError(f"{where}: 'measurement' has {len(flat)} values; {shape_help}")
    return np.array([flat])


def _bearings(meas: Any, where: str) -> NDArray[np.float64]:
    """An EO/IR measurement (one bearing or a list), rad."""
    values = meas if isinstance(meas, list) else [meas]
    return np.array([_num(b, where, "bearing", MAX_BEARING_RAD) for b in values], dtype=float)


def parse_scans(path: Path, doc: Any) -> tuple[NDArray[np.float64], NDArray[np.int64],
                                               NDArray[np.float64], list[NDArray[np.float64]]]:
    """Times (Unix s), sensor ids, own-ship (n, e) and measurements of the scans, file order.

    Measurements: (M, 2) north/east offsets, m, for radar and lidar; (M,) bearings, rad, for
    the cameras.
    """
    if not isinstance(doc, list) or not doc:
        raise ValueError(f"{path}: expected a non-empty list of scans")
    times, sensors, own, meas = [], [], [], []
    for k, scan in enumerate(doc):
        where = f"{path}: scan {k}"
        if not isinstance(scan, dict):
            raise ValueError(f"{where}: is {_show(scan)}, expected an object")
        missing = [key for key in ("time", "sensorID", "ownshipPosition", "measurement")
                   if key not in scan]
        if missing:
            raise ValueError(f"{where}: malformed Autoferry scan (no {', '.join(missing)})")
        times.append(_unix_time(scan["time"], where))
        sid = scan["sensorID"]
        if isinstance(sid, bool) or not isinstance(sid, int | float) or sid not in SENSOR_NAMES:
            raise ValueError(f"{where}: unknown 'sensorID' {_show(sid)} (expected 1 lidar, "
                             "2 radar, 3 IR or 4 EO)")
        sensors.append(int(sid))
        pos = _numbers(scan["ownshipPosition"], where, "'ownshipPosition'", MAX_POSITION_M)
        if len(pos) < 2:
            raise ValueError(f"{where}: 'ownshipPosition' has {len(pos)} values, expected "
                             "north, east[, down]")
        own.append(pos[:2])
        where = f"{where} ({SENSOR_NAMES[int(sid)]})"
        meas.append(_bearings(scan["measurement"], where) if sid in (3, 4)
                    else _positions(scan["measurement"], where))
    t = np.array(times)
    if t.max() - t.min() > MAX_SPAN_S:
        k = int(np.argmax(np.abs(t - np.median(t))))
        raise ValueError(f"{path}: scan {k}: 'time' {t[k]:.9g} is {abs(t[k] - np.median(t)):.3g} "
                         f"s from the other scans; a scenario spans at most {MAX_SPAN_S:g} s "
                         "(check the times)")
    return t, np.array(sensors, dtype=np.int64), np.array(own, dtype=float), meas


def parse_ground_truth(path: Path, doc: Any, *, n_scans: int, t0: float,
                       detections: Path) -> tuple[list[int], list[float], list[float], list[float]]:
    """Target ids, times (s from `t0`), east and north (m) of the GNSS fixes.

    The upstream file is a list with one entry per scan of `detections` (the entry at index k
    pairs with scan k): a list of targets ``{"targetID", "position": [n, e, d], "time"}``.
    """
    if not isinstance(doc, list):
        raise ValueError(f"{path}: is {type(doc).__name__}, expected a list with one entry of "
                         "targets per scan")
    if doc and len(doc) != n_scans:
        raise ValueError(f"{path}: has {len(doc)} entries, {detections.name} has {n_scans} "
                         "scans; expected one entry per scan (the ground truth of another "
                         "scenario?)")
    tid, tt, te, tn = [], [], [], []
    for k, entry in enumerate(doc):
        for target in entry if isinstance(entry, list) else [entry]:
            where = f"{path}: entry {k}"
            if not isinstance(target, dict) or not {"targetID", "position", "time"} <= set(target):
                raise ValueError(f"{where}: {_show(target)} is not a target "
                                 "{'targetID', 'position': [north, east, down], 'time'}")
            ident = _num(target["targetID"], where, "'targetID'", 2.0**31)
            if ident != int(ident):
                raise ValueError(f"{where}: 'targetID' {ident:g} is not a whole number")
            pos = _numbers(target["position"], where, "'position'", MAX_POSITION_M)
            if len(pos) not in (2, 3):
                raise ValueError(f"{where}: 'position' has {len(pos)} values, expected north, "
                                 "east[, down]")
            t = _unix_time(target["time"], where) - t0
            if abs(t) > MAX_SPAN_S:
                raise ValueError(f"{where}: 'time' is {t:.3g} s from the first scan; a scenario "
                                 f"spans at most {MAX_SPAN_S:g} s (the ground truth of another "
                                 "recording?)")
            tid.append(int(ident))
            tt.append(t)
            tn.append(pos[0])
            te.append(pos[1])
    return tid, tt, te, tn
