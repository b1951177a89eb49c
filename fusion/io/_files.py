"""Limits and file checks shared by the readers of :mod:`fusion.io`."""

from __future__ import annotations

import os
import stat
from pathlib import Path

PathLike = str | os.PathLike[str]

#: Largest CSV input, bytes (1 GiB): a larger file is refused before anything is read.
MAX_CSV_BYTES = 1 << 30
#: Longest line of a CSV input, characters (1 Mi): a longer "line" is not a table.
MAX_LINE_CHARS = 1 << 20
#: Largest magnitude of a number in a command's CSV input. Times (s), positions (m), bearings
#: (deg), amplitudes (linear, noise mean 1) beyond it are a unit or export error, not data.
MAX_ABS_VALUE = 1e12
#: Largest JSON input, bytes (256 MiB).
MAX_JSON_BYTES = 256 << 20
#: Most samples (all channels) :func:`read_audio` reads at once: 2**29, 4 GiB as float64.
MAX_AUDIO_SAMPLES = 1 << 29

#: Plausible sound speed in water, m/s (``array.json``, cubes): beyond it is a unit error, and
#: a value like 1e-12 or 1e308 would size delay grids of the localizers beyond any memory.
SOUND_SPEED_RANGE = (1000.0, 2000.0)
#: Plausible time between the scans of a cube, s (1 ms to 1 h).
SCAN_PERIOD_RANGE = (1e-3, 3600.0)
#: Plausible acoustic aperture of a cube's array, m (10 cm to 10 km).
APERTURE_RANGE = (0.1, 1e4)

_ROWS_PER_CHUNK = 1 << 16
_WHOLE_LIMIT = 2.0**53  # integers beyond are not exact in float64


def _size(n: int) -> str:
    for unit, scale in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n} bytes"


def _check_file(path: PathLike, *, max_bytes: int | None = None, what: str = "inputs") -> Path:
    """`path` as a Path if it names an existing file (not a folder) no larger than `max_bytes`."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise FileNotFoundError(f"{p}: no such file") from None
    except OSError as e:
        raise ValueError(f"{p}: cannot be read ({e.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{p}: is a directory, expected a file")
    if max_bytes is not None and stat.S_ISREG(st.st_mode) and st.st_size > max_bytes:
        raise ValueError(f"{p}: is {_size(st.st_size)}, larger than the {_size(max_bytes)} limit of "
                         f"{what}")
    return p


def _check_range(p: Path, name: str, value: float, bounds: tuple[float, float], unit: str) -> None:
    """Refuse `value` outside `bounds` (inclusive) with one line naming file, key and limits."""
    lo, hi = bounds
    if not lo <= value <= hi:
        raise ValueError(f"{p}: {name!r} = {value:g} {unit} is outside the plausible range "
                         f"{lo:g}..{hi:g} {unit} (check units)")


def _show(cell: str, width: int = 40) -> str:
    """`cell` quoted for a message, shortened if long."""
    return repr(cell if len(cell) <= width else cell[:width] + "...")
