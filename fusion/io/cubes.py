"""Beam/frequency/time cubes (``.npz``): read with validation, write atomically.

A cube is a :class:`fusion.types.Cube`; the file holds the arrays ``power``, ``freqs``,
``scan_period``, ``aperture`` and ``sound_speed``, all real numbers.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fusion._output import atomic_output
from fusion.io._files import (
    APERTURE_RANGE,
    SCAN_PERIOD_RANGE,
    SOUND_SPEED_RANGE,
    PathLike,
    _check_file,
    _check_range,
)
from fusion.types import _REAL_KINDS, Cube

__all__ = ["Cube", "read_cube", "write_cube"]

_CUBE_KEYS = ("power", "freqs", "scan_period", "aperture", "sound_speed")
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
_NPY_MAGIC = b"\x93NUMPY"


def read_cube(path: PathLike) -> Cube:
    """Read a beam/frequency/time cube from ``.npz``.

    Raises
    ------
    ValueError
        Not an ``.npz`` (zip) file -- text, an ``.npy`` array, anything else --, a missing array,
        arrays that are not real numbers (text, complex, objects), scalars that are not one real
        number, or any check of :class:`Cube` (shape, NaN/inf, negative power, ...).
    """
    p = _check_file(path)
    with p.open("rb") as fh:
        magic = fh.read(len(_NPY_MAGIC))
    if not magic:
        raise ValueError(f"{p}: file is empty")
    if magic.startswith(_NPY_MAGIC):
        raise ValueError(f"{p}: is a single .npy array, not a valid .npz file "
                         f"(expected arrays {', '.join(_CUBE_KEYS)})")
    if not magic.startswith(_ZIP_MAGIC):
        raise ValueError(f"{p}: not a valid .npz file")
    try:
        with np.load(p, allow_pickle=False) as z:
            files = list(z.files)
            d = {k: z[k] for k in _CUBE_KEYS if k in files}
    except Exception as e:  # zipfile.BadZipFile, OSError, refused pickles: all mean "not a cube"
        raise ValueError(f"{p}: not a valid .npz file ({' '.join(str(e).split())})") from None
    missing = [k for k in _CUBE_KEYS if k not in d]
    if missing:
        raise ValueError(f"{p}: missing array(s) {', '.join(missing)}")
    for k, v in d.items():
        if v.dtype.kind not in _REAL_KINDS:
            raise ValueError(f"{p}: {k!r} must hold real numbers, got {v.dtype} values")
    for k in ("scan_period", "aperture", "sound_speed"):
        if d[k].size != 1:
            raise ValueError(f"{p}: {k!r} must be one number, got shape {d[k].shape}")
    for k, bounds, unit in (("scan_period", SCAN_PERIOD_RANGE, "s"),
                            ("aperture", APERTURE_RANGE, "m"),
                            ("sound_speed", SOUND_SPEED_RANGE, "m/s")):
        v = float(d[k].reshape(()))
        if math.isfinite(v) and v > 0:  # NaN, inf and <= 0 are refused by Cube, as before
            _check_range(p, k, v, bounds, unit)
    try:
        return Cube(
            power=d["power"],
            freqs=d["freqs"],
            scan_period=float(d["scan_period"].reshape(())),
            aperture=float(d["aperture"].reshape(())),
            sound_speed=float(d["sound_speed"].reshape(())),
        )
    except (ValueError, TypeError) as e:
        raise ValueError(f"{p}: {e}") from None


def write_cube(path: PathLike, cube: Cube) -> Path:
    """Write a cube as ``.npz`` (atomic)."""
    with atomic_output(path, suffix=".npz") as tmp:
        np.savez_compressed(
            tmp,
            power=cube.power,
            freqs=cube.freqs,
            scan_period=cube.scan_period,
            aperture=cube.aperture,
            sound_speed=cube.sound_speed,
        )
    return Path(path)
