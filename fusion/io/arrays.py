"""Sensor array files (``array.json``): positions of the hydrophones and the sound speed."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fusion.geometry import SensorArray
from fusion.io._files import MAX_ABS_VALUE, SOUND_SPEED_RANGE, PathLike, _check_range
from fusion.io.json_files import read_json, write_json

__all__ = ["MIN_SENSOR_SEPARATION_M", "read_array", "write_array"]

#: Sensors of an array closer than this (m) count as one position: the geometry is degenerate.
MIN_SENSOR_SEPARATION_M = 1e-3


def read_array(path: PathLike) -> SensorArray:
    """Read a sensor array file (``array.json``).

    Raises
    ------
    ValueError
        Malformed JSON, missing keys, non-numeric or non-finite coordinates, fewer than 3 sensors,
        two sensors at the same position (closer than :data:`MIN_SENSOR_SEPARATION_M`), all
        sensors collinear, duplicate ids, a sound speed outside :data:`~fusion.io._files.SOUND_SPEED_RANGE`.
    """
    p = Path(path)
    doc = read_json(p)
    if not isinstance(doc, dict) or "sensors" not in doc:
        raise ValueError(f"{p}: expected an object with a 'sensors' list")
    sensors = doc["sensors"]
    if not isinstance(sensors, list) or not sensors:
        raise ValueError(f"{p}: 'sensors' must be a non-empty list")
    pos, ids = [], []
    for k, s in enumerate(sensors):
        if not isinstance(s, dict):
            raise ValueError(f"{p}: sensor {k} is not an object")
        row = []
        for axis in ("x", "y", "z"):
            if axis not in s:
                raise ValueError(f"{p}: sensor {k} has no {axis!r}")
            v = s[axis]
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ValueError(f"{p}: sensor {k}: {axis!r} = {v!r} is not a finite number")
            if abs(v) > MAX_ABS_VALUE:
                raise ValueError(f"{p}: sensor {k}: {axis!r} = {v!r} is beyond "
                                 f"+-{MAX_ABS_VALUE:g} m, implausible (check units)")
            row.append(float(v))
        pos.append(row)
        ids.append(str(s.get("id", f"H{k + 1}")))
    c = doc.get("sound_speed", 1500.0)
    if isinstance(c, bool) or not isinstance(c, int | float) or not math.isfinite(c) or c <= 0:
        raise ValueError(f"{p}: 'sound_speed' = {c!r} is not a positive number")
    _check_range(p, "sound_speed", float(c), SOUND_SPEED_RANGE, "m/s")
    xyz = np.array(pos)
    gap = np.linalg.norm(xyz[:, None, :] - xyz[None, :, :], axis=-1)
    gap[np.diag_indices(len(pos))] = np.inf
    if np.min(gap) < MIN_SENSOR_SEPARATION_M:
        i, j = sorted(np.unravel_index(int(np.argmin(gap)), gap.shape))
        raise ValueError(f"{p}: sensors {i} ({ids[i]}) and {j} ({ids[j]}) are at the same "
                         "position (degenerate geometry)")
    try:
        return SensorArray(np.array(pos), float(c), tuple(ids))
    except ValueError as e:
        raise ValueError(f"{p}: {e}") from None


def write_array(path: PathLike, array: SensorArray) -> Path:
    """Write a sensor array as ``array.json`` (atomic)."""
    doc = {
        "sound_speed": array.sound_speed,
        "sensors": [
            {"id": i, "x": float(x), "y": float(y), "z": float(z)}
            for i, (x, y, z) in zip(array.ids, array.positions, strict=True)
        ],
    }
    return write_json(path, doc)
