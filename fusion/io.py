"""Readers and writers for the files the ``fusion`` command reads and writes.

Every reader validates what it reads and raises :class:`ValueError` (or :class:`FileNotFoundError`
for a missing file) whose message starts with the file's path and names the problem; the command
line turns these into one line on stderr and exit code 2. Readers never raise anything else for
bad file content (property-tested with random bytes and random CSV-like text).

Every writer is atomic (:func:`atomic_output`, from :mod:`fusion._output`): it writes a temporary
file beside the destination and renames it into place, so an interrupted or failed run never leaves
a half-written result; a symbolic link is written through; FIFOs and devices are refused; ``"-"``
(:data:`STDOUT`) writes to standard output.

Formats (``docs/formats.md``):

- sensor array ``array.json``: ``{"sound_speed": c, "sensors": [{"id", "x", "y", "z"}, ...]}``;
  sensors at distinct positions;
- audio, WAV or FLAC, channel ``i`` = ``sensors[i]``;
- CSV tables with a header line; extra columns are ignored, missing required columns are errors;
- beam/frequency/time cubes ``.npz`` with ``power``, ``freqs``, ``scan_period``, ``aperture``,
  ``sound_speed``, all real numbers;
- JSON results.

Limits: CSV inputs at most :data:`MAX_CSV_BYTES` (1 GiB), lines at most :data:`MAX_LINE_CHARS`
characters, fields at most 128 KiB (the csv module's limit), numbers in commands' inputs at most
:data:`MAX_ABS_VALUE` (1e12) in magnitude; JSON at most :data:`MAX_JSON_BYTES`; whole-file audio
reads at most :data:`MAX_AUDIO_SAMPLES` samples.

Row order: readers of time series put each track's rows in time order (a stable sort by time when
some track is out of order, announced by one warning; rows already in order keep the file's
order) and refuse two rows of one track at the same time -- the algorithms are defined on
time-ordered samples with distinct times. Detections are put in ``event`` order the same way.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import numbers
import os
import stat
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._output import STDOUT, atomic_output
from fusion.geometry import SensorArray

__all__ = [
    "MAX_ABS_VALUE",
    "MAX_AUDIO_SAMPLES",
    "MAX_CSV_BYTES",
    "MAX_JSON_BYTES",
    "MAX_LINE_CHARS",
    "STDOUT",
    "Cube",
    "LocalizationResult",
    "LocalizationWindow",
    "SourceEstimate",
    "TdoaRecord",
    "read_localization",
    "write_localization",
    "Table",
    "atomic_output",
    "iter_audio_blocks",
    "read_amplitudes",
    "read_array",
    "read_audio",
    "read_bearings",
    "read_cube",
    "read_detections",
    "read_alerts",
    "read_json",
    "read_smoothed",
    "read_tma_result",
    "read_tqi",
    "read_tracks",
    "read_ownship",
    "read_table",
    "read_tma_bearings",
    "write_array",
    "write_audio",
    "write_cube",
    "write_json",
    "write_table",
]

PathLike = str | os.PathLike[str]

logger = logging.getLogger(__name__)


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


def _show(cell: str, width: int = 40) -> str:
    """`cell` quoted for a message, shortened if long."""
    return repr(cell if len(cell) <= width else cell[:width] + "...")


# --------------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Table:
    """Columns of a CSV file, each a 1-D array of one length.

    Attributes
    ----------
    columns : dict of str to ndarray
        Column name to values (float64, int64 for integer columns, or str).
    source : str
        Where the table came from (a file path), for messages.
    """

    columns: Mapping[str, NDArray[Any]]
    source: str = "<table>"

    def __post_init__(self) -> None:
        lengths = {len(v) for v in self.columns.values()}
        if len(lengths) > 1:
            raise ValueError(f"{self.source}: columns have different lengths {sorted(lengths)}")
        object.__setattr__(self, "columns", dict(self.columns))

    def __getitem__(self, name: str) -> NDArray[Any]:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"{self.source}: no column {name!r}") from None

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    @property
    def n_rows(self) -> int:
        """Number of rows."""
        return len(self)

    def select(self, mask: ArrayLike) -> Table:
        """Rows where `mask` is true (or at the given indices), as a new table."""
        m = np.asarray(mask)
        return Table({k: v[m] for k, v in self.columns.items()}, self.source)


def _csv_lines(p: Path, fh: Any) -> Iterator[str]:
    """Lines of an open text file, refusing over-long lines, NUL bytes and non-UTF-8 text."""
    lineno = 0
    while True:
        try:
            line = fh.readline(MAX_LINE_CHARS + 1)
        except UnicodeDecodeError:
            raise ValueError(f"{p}: not a text CSV file (not UTF-8 after line {lineno})") from None
        if not line:
            return
        lineno += 1
        if len(line) > MAX_LINE_CHARS:
            raise ValueError(f"{p}: line {lineno} is longer than {MAX_LINE_CHARS:,} characters; "
                             "not a CSV table")
        if "\x00" in line:
            raise ValueError(f"{p}: not a text CSV file (NUL bytes in line {lineno})")
        yield line


def _csv_rows(p: Path, reader: Any) -> Iterator[list[str]]:
    """Non-blank rows of a csv reader; its errors become ValueErrors naming file and line."""
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as e:
            if "field larger than field limit" in str(e):
                raise ValueError(f"{p}: line {reader.line_num}: a field is longer than "
                                 f"{csv.field_size_limit():,} characters; not a CSV table") from None
            raise ValueError(f"{p}: line {reader.line_num}: malformed CSV ({e})") from None
        if row and (row[0].strip() or any(cell.strip() for cell in row)):
            yield row


def _number(cell: str, where: str, *, whole: bool, max_abs: float | None) -> float:
    """A CSV cell as a finite float (a whole number if `whole`), bounded by `max_abs`."""
    cell = cell.strip()
    try:
        x = float(cell)
    except ValueError:
        raise ValueError(f"{where}: {_show(cell)} is not a number") from None
    if not math.isfinite(x):
        raise ValueError(f"{where}: value is {cell}")
    if max_abs is not None and abs(x) > max_abs:
        raise ValueError(f"{where}: {_show(cell)} is beyond +-{max_abs:g}, implausible for this "
                         "column (check units)")
    if whole:
        if x != round(x):
            raise ValueError(f"{where}: {_show(cell)} is not a whole number")
        if abs(x) > _WHOLE_LIMIT:
            raise ValueError(f"{where}: {_show(cell)} is too large for a whole number")
    return x


def _numbers(
    cells: list[str], lines: list[int], where: str, *, whole: bool, max_abs: float | None
) -> NDArray[np.float64]:
    """Cells of one column as checked float64 (see :func:`_number`); vectorized checks.

    `where` is formatted with the line number of the first bad cell (``{line}``), whose message
    is that of :func:`_number`.
    """
    try:
        x = np.fromiter(map(float, cells), dtype=float, count=len(cells))
    except ValueError:  # some cell is not a number
        x = None
    if x is not None:
        bad = ~np.isfinite(x)
        if max_abs is not None:
            bad |= np.abs(x) > max_abs
        if whole:
            bad |= (x != np.round(x)) | (np.abs(x) > _WHOLE_LIMIT)
        if not np.any(bad):
            return x
    for cell, line in zip(cells, lines, strict=True):  # the first bad cell raises
        _number(cell, where.format(line=line), whole=whole, max_abs=max_abs)
    raise AssertionError("a bad cell was expected")  # pragma: no cover


def read_table(
    path: PathLike,
    *,
    required: Sequence[str],
    optional: Sequence[str] = (),
    integer: Sequence[str] = (),
    text: Sequence[str] = (),
    max_abs: float | None = MAX_ABS_VALUE,
) -> Table:
    """Read a CSV file with a header line, keeping and validating the named columns.

    Parameters
    ----------
    path : path-like
        CSV file, UTF-8 (a byte-order mark is allowed), at most :data:`MAX_CSV_BYTES` bytes, lines
        at most :data:`MAX_LINE_CHARS` characters, fields at most the csv module's limit (128 KiB).
    required : sequence of str
        Columns that must be present.
    optional : sequence of str, optional
        Columns read when present (absent ones are simply not in the result).
    integer : sequence of str, optional
        Columns that must hold whole numbers (returned as int64).
    text : sequence of str, optional
        Columns kept as strings (not checked as numbers).
    max_abs : float or None, optional
        Largest magnitude accepted in the numeric columns (default :data:`MAX_ABS_VALUE`);
        ``None``: no bound beyond finiteness.

    Returns
    -------
    Table
        The required columns and the optional ones present, in file order; extra columns are
        ignored; blank lines are skipped.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        A folder, a file over the size limit, not UTF-8 text, NUL bytes, an over-long line or
        field, empty file, no data rows, a missing required column, a ragged row, a non-numeric
        value, NaN, infinity or a value beyond `max_abs`. The message starts with the path and
        names line and column.
    """
    p = _check_file(path, max_bytes=MAX_CSV_BYTES, what="CSV inputs")
    with p.open(newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(_csv_lines(p, fh))
        rows = _csv_rows(p, reader)
        first = next(rows, None)
        if first is None:
            raise ValueError(f"{p}: file is empty")
        header = [h.strip() for h in first]
        missing = [c for c in required if c not in header]
        if missing:
            raise ValueError(f"{p}: missing required column(s) {', '.join(missing)}")
        wanted = list(required) + [c for c in optional if c in header and c not in required]
        index = [header.index(c) for c in wanted]
        need = max(index) + 1
        cells: list[list[str]] = [[] for _ in wanted]  # per column, the cells of this chunk
        lines: list[int] = []  # line number of each row of this chunk
        parsed: list[list[Any]] = [[] for _ in wanted]  # per column, float64 chunks or strings
        n_rows = 0

        def flush() -> None:
            for k, name in enumerate(wanted):
                if name in text:
                    parsed[k] += [c.strip() for c in cells[k]]
                else:
                    parsed[k].append(_numbers(
                        cells[k], lines, f"{p}: line {{line}}, column {name!r}",
                        whole=name in integer, max_abs=max_abs))
                cells[k] = []
            lines.clear()

        for row in rows:
            if len(row) < need:
                raise ValueError(f"{p}: line {reader.line_num} has {len(row)} fields, header has "
                                 f"{len(header)}")
            lines.append(reader.line_num)
            for k, j in enumerate(index):
                cells[k].append(row[j])
            n_rows += 1
            if len(lines) == _ROWS_PER_CHUNK:
                flush()
        flush()
    if n_rows == 0:
        raise ValueError(f"{p}: no data rows")
    columns: dict[str, NDArray[Any]] = {}
    for k, name in enumerate(wanted):
        if name in text:
            columns[name] = np.array(parsed[k], dtype=str)
        else:
            values = np.concatenate(parsed[k])
            columns[name] = values.astype(np.int64) if name in integer else values
    return Table(columns, str(p))


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


def read_bearings(path: PathLike) -> Table:
    """Bearing tracks ``track_id,time,bearing_deg`` (``track_id`` -1: unknown origin).

    Rows need not be sorted: each track's rows are put in time order (see
    :func:`_in_time_order`, one warning if a sort was needed). Two rows of one track
    (``track_id >= 0``) at the same time are an error; rows of track -1 may share times.
    """
    t = read_table(path, required=("track_id", "time", "bearing_deg"), integer=("track_id",))
    return _in_time_order(t, by="track_id", ignore_key=-1)


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


DETECTION_CLUES = ("snr_db", "score", "aspect_deg", "src_x", "src_y", "rcv_x", "rcv_y")


def read_detections(path: PathLike) -> Table:
    """Position detections ``event,time,x,y`` plus optional clue columns.

    Optional: ``snr_db, score, aspect_deg, src_x, src_y, rcv_x, rcv_y``. ``score`` must lie in
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


_FIXED_LIMIT = 1e15  # floats this large are written as repr (e.g. 1e+20), not fixed-point


def _format_cell(v: Any, float_format: str) -> str:
    if isinstance(v, str | np.str_):
        return str(v)
    if isinstance(v, bool | np.bool_):
        return "true" if v else "false"
    if isinstance(v, int | np.integer):
        return str(int(v))
    x = float(v)
    if abs(x) >= _FIXED_LIMIT:  # no 300-digit fixed-point numbers: shortest exact form instead
        return repr(x)
    return float_format % x


def write_table(
    path: PathLike, columns: Mapping[str, ArrayLike], *, float_format: str = "%.6f"
) -> Path:
    """Write columns as a CSV file with a header line, atomically.

    Parameters
    ----------
    path : path-like
        Destination (``"-"``: standard output; see :func:`atomic_output`).
    columns : mapping of str to array_like
        Column name to 1-D values, all the same length; integer, float, bool or str values.
    float_format : str, optional
        printf-style format of float values below 1e15 in magnitude; larger ones are written in
        their shortest exact form (``1e+20``), never as hundreds of fixed-point digits.

    Returns
    -------
    pathlib.Path
        The written path.
    """
    cols = {k: np.asarray(v) for k, v in columns.items()}
    lengths = {len(v) for v in cols.values()}
    if len(lengths) > 1:
        raise ValueError(f"{path}: columns have different lengths {sorted(lengths)}")
    n = lengths.pop() if lengths else 0
    with atomic_output(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(list(cols))
        values = list(cols.values())
        for i in range(n):
            w.writerow([_format_cell(v[i], float_format) for v in values])
    return Path(path)


# --------------------------------------------------------------------------------------------
# JSON
# --------------------------------------------------------------------------------------------
def _json_default(o: Any) -> Any:
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def read_json(path: PathLike) -> Any:
    """Read a JSON file (UTF-8, at most :data:`MAX_JSON_BYTES`).

    A folder, an over-large file, non-UTF-8 bytes, malformed or too deeply nested JSON raise
    ValueError naming the file (and the position of a syntax error).
    """
    p = _check_file(path, max_bytes=MAX_JSON_BYTES, what="JSON inputs")
    try:
        text = p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise ValueError(f"{p}: not a UTF-8 text JSON file") from None
    if not text.strip():
        raise ValueError(f"{p}: file is empty")
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"{p}: malformed JSON ({e.msg} at line {e.lineno}, column {e.colno})") from None
    except RecursionError:
        raise ValueError(f"{p}: JSON nested too deeply") from None


def write_json(path: PathLike, obj: Any, *, indent: int | None = 1) -> Path:
    """Write `obj` as JSON atomically (numpy scalars and arrays are converted)."""
    text = json.dumps(obj, indent=indent, default=_json_default, allow_nan=False)
    with atomic_output(path) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    return Path(path)


# --------------------------------------------------------------------------------------------
# sensor arrays
# --------------------------------------------------------------------------------------------
#: Sensors of an array closer than this (m) count as one position: the geometry is degenerate.
MIN_SENSOR_SEPARATION_M = 1e-3


def read_array(path: PathLike) -> SensorArray:
    """Read a sensor array file (``array.json``).

    Raises
    ------
    ValueError
        Malformed JSON, missing keys, non-numeric or non-finite coordinates, fewer than 3 sensors,
        two sensors at the same position (closer than :data:`MIN_SENSOR_SEPARATION_M`), all
        sensors collinear, duplicate ids, non-positive sound speed.
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
            row.append(float(v))
        pos.append(row)
        ids.append(str(s.get("id", f"H{k + 1}")))
    c = doc.get("sound_speed", 1500.0)
    if isinstance(c, bool) or not isinstance(c, int | float) or not math.isfinite(c) or c <= 0:
        raise ValueError(f"{p}: 'sound_speed' = {c!r} is not a positive number")
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


# --------------------------------------------------------------------------------------------
# audio
# --------------------------------------------------------------------------------------------
def _sf():
    import soundfile

    return soundfile


def _sf_message(e: Exception) -> str:
    return " ".join(str(e).replace("Error :", "").split()).rstrip(".")


def _audio_info(p: Path):
    sf = _sf()
    try:
        return sf.info(str(p))
    except (RuntimeError, sf.LibsndfileError) as e:  # LibsndfileError is a RuntimeError
        raise ValueError(f"{p}: not a readable WAV/FLAC audio file ({_sf_message(e)})") from None


def read_audio(
    path: PathLike, *, n_channels: int | None = None
) -> tuple[NDArray[np.float64], float]:
    """Read a whole WAV/FLAC file.

    Parameters
    ----------
    path : path-like
        Audio file.
    n_channels : int, optional
        Expected channel count (e.g. the array's sensor count); a mismatch is an error.

    Returns
    -------
    samples : ndarray, shape (n_samples, n_channels)
        float64 samples in [-1, 1].
    fs : float
        Sample rate, Hz.

    Raises
    ------
    ValueError
        Unreadable, truncated or corrupt file (also when the damage is found while decoding),
        no samples, wrong channel count, more than :data:`MAX_AUDIO_SAMPLES` samples (read such
        a file with :func:`iter_audio_blocks`), NaN/inf samples.
    """
    p = _check_file(path)
    info = _audio_info(p)
    if n_channels is not None and info.channels != n_channels:
        raise ValueError(
            f"{p}: audio has {info.channels} channel(s) but the array has {n_channels} sensors"
        )
    if info.frames == 0:
        raise ValueError(f"{p}: audio file has no samples")
    if info.frames * info.channels > MAX_AUDIO_SAMPLES:
        raise ValueError(f"{p}: {info.frames} frames x {info.channels} channels is more than "
                         f"{MAX_AUDIO_SAMPLES} samples; read it in blocks")
    sf = _sf()
    try:
        data, fs = sf.read(str(p), dtype="float64", always_2d=True)
    except (RuntimeError, sf.LibsndfileError) as e:
        raise ValueError(f"{p}: audio is truncated or corrupt ({_sf_message(e)})") from None
    if data.shape[0] == 0:
        raise ValueError(f"{p}: audio file has no samples")
    if not np.all(np.isfinite(data)):
        raise ValueError(f"{p}: audio contains NaN or infinite samples")
    return data, float(fs)


def iter_audio_blocks(
    path: PathLike, *, block_s: float, hop_s: float, n_channels: int | None = None
) -> Iterator[tuple[float, NDArray[np.float64], float]]:
    """Read a long recording in overlapping windows, never loading it whole.

    Parameters
    ----------
    path : path-like
        Audio file.
    block_s, hop_s : float
        Window length and hop, s.
    n_channels : int, optional
        Expected channel count.

    Yields
    ------
    t_start : float
        Start of the window, s from the start of the file.
    samples : ndarray, shape (n, n_channels)
        The window (the last one may be shorter).
    fs : float
        Sample rate, Hz.

    Raises
    ------
    ValueError
        As :func:`read_audio` (damage found while decoding a block included); a window or hop
        shorter than one sample, or a hop longer than the window (samples would be skipped).
    """
    if not (math.isfinite(block_s) and math.isfinite(hop_s)) or block_s <= 0 or hop_s <= 0:
        raise ValueError("window length and hop must be positive")
    p = _check_file(path)
    info = _audio_info(p)
    if n_channels is not None and info.channels != n_channels:
        raise ValueError(
            f"{p}: audio has {info.channels} channel(s) but the array has {n_channels} sensors"
        )
    fs = float(info.samplerate)
    block, hop = int(round(block_s * fs)), int(round(hop_s * fs))
    if block < 1 or hop < 1:
        raise ValueError(f"window {block_s:g} s and hop {hop_s:g} s must each span at least one "
                         f"sample at {fs:g} Hz")
    if hop > block:
        raise ValueError(f"hop {hop_s:g} s is longer than the window {block_s:g} s; samples "
                         "would be skipped")
    sf = _sf()
    blocks = sf.blocks(str(p), blocksize=block, overlap=block - hop, dtype="float64",
                       always_2d=True)
    start = 0
    while True:
        try:
            data = next(blocks)
        except StopIteration:
            return
        except (RuntimeError, sf.LibsndfileError) as e:
            raise ValueError(f"{p}: audio is truncated or corrupt near {start * hop / fs:g} s "
                             f"({_sf_message(e)})") from None
        if not np.all(np.isfinite(data)):
            raise ValueError(f"{p}: audio contains NaN or infinite samples")
        yield start * hop / fs, data, fs
        start += 1


def write_audio(path: PathLike, samples: ArrayLike, fs: float, *, subtype: str | None = None) -> Path:
    """Write audio atomically; WAV or FLAC by the path's suffix.

    Parameters
    ----------
    path : path-like
        ``.wav`` or ``.flac`` destination.
    samples : array_like, shape (n_samples,) or (n_samples, n_channels)
        Samples in [-1, 1] (values outside are clipped by the encoder).
    fs : float
        Sample rate, Hz.
    subtype : str, optional
        soundfile subtype; defaults to 24-bit PCM.
    """
    p = Path(path)
    fmt = {".wav": "WAV", ".flac": "FLAC"}.get(p.suffix.lower())
    if fmt is None:
        raise ValueError(f"{p}: audio must be .wav or .flac")
    x = np.asarray(samples)
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{p}: refusing to write NaN or infinite samples")
    with atomic_output(p) as tmp:
        _sf().write(str(tmp), x, int(round(fs)), format=fmt, subtype=subtype or "PCM_24")
    return p


# --------------------------------------------------------------------------------------------
# beam / frequency / time cubes
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Cube:
    """Beam/frequency/time power of a line array, beams equally spaced in cosine.

    Attributes
    ----------
    power : ndarray, shape (n_scans, n_beams, n_bins)
        Power, linear, >= 0 (normalised spectra have noise mean 1).
    freqs : ndarray, shape (n_bins,)
        Bin centre frequencies, Hz, increasing.
    scan_period : float
        Time between scans, s.
    aperture : float
        Array aperture, m.
    sound_speed : float
        Sound speed, m/s.
    """

    power: NDArray[np.float64]
    freqs: NDArray[np.float64]
    scan_period: float
    aperture: float
    sound_speed: float = 1500.0

    def __post_init__(self) -> None:
        for name in ("power", "freqs"):
            dtype = np.asarray(getattr(self, name)).dtype
            if dtype.kind not in _REAL_KINDS:
                raise ValueError(f"{name} must hold real numbers, got {dtype} values")
        for name in ("scan_period", "aperture", "sound_speed"):
            v = getattr(self, name)
            if isinstance(v, bool | np.bool_) or not isinstance(v, numbers.Real):
                raise ValueError(f"{name} must be a real number, got {v!r}")
        power = np.asarray(self.power, dtype=float)
        freqs = np.asarray(self.freqs, dtype=float).reshape(-1)
        if power.ndim != 3:
            raise ValueError(f"power must have shape (scans, beams, bins), got {power.shape}")
        if power.shape[0] < 2 or power.shape[1] < 2 or power.shape[2] < 1:
            raise ValueError(f"cube too small: {power.shape} (need >= 2 scans, >= 2 beams, >= 1 bin)")
        if freqs.shape[0] != power.shape[2]:
            raise ValueError(f"{freqs.shape[0]} frequencies for {power.shape[2]} bins")
        if not (np.all(np.isfinite(power)) and np.all(np.isfinite(freqs))):
            raise ValueError("cube contains NaN or infinite values")
        if np.any(power < 0):
            raise ValueError("power has negative values")
        if freqs.size > 1 and np.any(np.diff(freqs) <= 0):
            raise ValueError("freqs must be strictly increasing")
        for name in ("scan_period", "aperture", "sound_speed"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive, got {v!r}")
            object.__setattr__(self, name, float(v))
        object.__setattr__(self, "power", power)
        object.__setattr__(self, "freqs", freqs)

    @property
    def n_scans(self) -> int:
        """Number of scans."""
        return int(self.power.shape[0])

    @property
    def n_beams(self) -> int:
        """Number of beams."""
        return int(self.power.shape[1])

    @property
    def n_bins(self) -> int:
        """Number of frequency bins."""
        return int(self.power.shape[2])


_CUBE_KEYS = ("power", "freqs", "scan_period", "aperture", "sound_speed")
_REAL_KINDS = "fiu"  # numpy dtype kinds of real numbers (no bool, complex, text or objects)
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


# --------------------------------------------------------------------------------------------
# localization results (``fusion localize``)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TdoaRecord:
    """One measured TDOA of a processing window.

    Attributes
    ----------
    pair : tuple of int
        0-based sensor indices ``(i, j)``.
    tau : float
        Arrival time at sensor i minus at sensor j, s.
    valid : bool
        Whether validation accepted it.
    llr : float
        Validation log-likelihood ratio.
    """

    pair: tuple[int, int]
    tau: float
    valid: bool
    llr: float


@dataclass(frozen=True)
class SourceEstimate:
    """One localized source of a processing window (position in m, covariance in m^2)."""

    x: float
    y: float
    z: float
    cov: tuple[tuple[float, float, float], ...]
    tdoas_used: int


@dataclass(frozen=True)
class LocalizationWindow:
    """TDOAs and sources of one processing window (``t_start``/``t_end`` in s from the audio start)."""

    t_start: float
    t_end: float
    tdoas: tuple[TdoaRecord, ...]
    sources: tuple[SourceEstimate, ...]


@dataclass(frozen=True)
class LocalizationResult:
    """Result of ``fusion localize``: windows and tracks (``tracks``: id -> points (t, x, y, z))."""

    windows: tuple[LocalizationWindow, ...]
    tracks: tuple[tuple[int, tuple[tuple[float, float, float, float], ...]], ...] = ()


def write_localization(path: PathLike, result: LocalizationResult) -> Path:
    """Write a localization result as JSON (atomic)."""
    doc = {
        "windows": [
            {
                "t_start": w.t_start,
                "t_end": w.t_end,
                "tdoas": [
                    {"pair": list(d.pair), "tau": d.tau, "valid": d.valid, "llr": d.llr}
                    for d in w.tdoas
                ],
                "sources": [
                    {"x": s.x, "y": s.y, "z": s.z, "cov": [list(r) for r in s.cov],
                     "tdoas_used": s.tdoas_used}
                    for s in w.sources
                ],
            }
            for w in result.windows
        ],
        "tracks": [
            {"id": tid, "points": [{"t": t, "x": x, "y": y, "z": z} for t, x, y, z in pts]}
            for tid, pts in result.tracks
        ],
    }
    return write_json(path, doc)


def _num(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ValueError(f"{where}: {v!r} is not a finite number")
    return float(v)


def _int(v: Any, where: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise ValueError(f"{where}: {v!r} is not a whole number")
    return v


def _cov3(v: Any, where: str) -> tuple[tuple[float, float, float], ...]:
    try:
        cov = np.asarray(v, dtype=float)
    except (ValueError, TypeError):
        cov = np.zeros(0)
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise ValueError(f"{where}: 'cov' must be a finite 3x3 matrix")
    return tuple(tuple(float(x) for x in r) for r in cov)


def read_localization(path: PathLike) -> LocalizationResult:
    """Read and validate a localization result JSON."""
    p = Path(path)
    doc = read_json(p)
    if not isinstance(doc, dict) or not isinstance(doc.get("windows"), list):
        raise ValueError(f"{p}: expected an object with a 'windows' list")
    try:
        windows = []
        for k, w in enumerate(doc["windows"]):
            where = f"{p}: window {k}"
            tdoas = []
            for d in w["tdoas"]:
                if not isinstance(d["valid"], bool) or len(d["pair"]) != 2:
                    raise ValueError(f"{where}: a TDOA needs a 2-element 'pair' and a true/false "
                                     "'valid'")
                tdoas.append(TdoaRecord((_int(d["pair"][0], where), _int(d["pair"][1], where)),
                                        _num(d["tau"], where), d["valid"], _num(d["llr"], where)))
            sources = tuple(
                SourceEstimate(_num(s["x"], where), _num(s["y"], where), _num(s["z"], where),
                               _cov3(s["cov"], where), _int(s["tdoas_used"], where))
                for s in w["sources"]
            )
            windows.append(LocalizationWindow(_num(w["t_start"], where), _num(w["t_end"], where),
                                              tuple(tdoas), sources))
        tracks = tuple(
            (_int(t["id"], str(p)),
             tuple((_num(q["t"], str(p)), _num(q["x"], str(p)), _num(q["y"], str(p)),
                    _num(q["z"], str(p))) for q in t["points"]))
            for t in doc.get("tracks", [])
        )
    except (KeyError, TypeError, IndexError) as e:
        raise ValueError(f"{p}: malformed localization result (missing or bad {e})") from None
    return LocalizationResult(tuple(windows), tracks)
