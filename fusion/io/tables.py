"""CSV tables: read with validation (:func:`read_table`), write atomically (:func:`write_table`).

A table is a :class:`fusion.types.Table` (named columns of one length). Readers refuse anything
that is not a well-formed table of finite numbers (see :mod:`fusion.io` for the limits); the
named readers of each file kind are in :mod:`fusion.io.table_kinds`.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._output import atomic_output
from fusion.io._files import (
    _ROWS_PER_CHUNK,
    _WHOLE_LIMIT,
    MAX_ABS_VALUE,
    MAX_CSV_BYTES,
    MAX_LINE_CHARS,
    PathLike,
    _check_file,
    _show,
)
from fusion.types import Table

__all__ = ["Table", "TableChunk", "iter_table", "read_table", "write_table", "write_table_chunks"]


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


def _header(p: Path, row: list[str], line: int) -> list[str]:
    """The column names of a header row; a name given twice is refused (which one is meant?)."""
    header = [h.strip() for h in row]
    first: dict[str, int] = {}
    for k, name in enumerate(header, start=1):
        if name and name in first:
            raise ValueError(f"{p}: line {line}, column {k}: column name {_show(name)} repeats "
                             f"column {first[name]}; each column needs its own name")
        first.setdefault(name, k)
    return header


def _ragged(p: Path, line: int, n_fields: int, n_header: int) -> None:
    """Refuse a row whose field count differs from the header's (its values would shift)."""
    if n_fields > n_header:
        raise ValueError(f"{p}: line {line}, column {n_header + 1}: the row has {n_fields} fields, "
                         f"the header names {n_header}; a field past the last named column")
    raise ValueError(f"{p}: line {line} has {n_fields} fields, header has {n_header}")


@dataclass(frozen=True)
class TableChunk:
    """Consecutive data rows of a CSV file, as read by :func:`iter_table`.

    Attributes
    ----------
    table : Table
        The chunk's columns (as :func:`read_table` would return them for these rows).
    start_row : int
        Index of the chunk's first row among the file's data rows (0 for the first chunk).
    lines : ndarray of int64, shape (n_rows,)
        Line number in the file of each row (1-based, the header is a line), for messages.
    """

    table: Table
    start_row: int
    lines: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.lines)


def iter_table(
    path: PathLike,
    *,
    required: Sequence[str],
    optional: Sequence[str] = (),
    integer: Sequence[str] = (),
    text: Sequence[str] = (),
    max_abs: float | None = MAX_ABS_VALUE,
    rows_per_chunk: int = _ROWS_PER_CHUNK,
) -> Iterator[TableChunk]:
    """Read a CSV file with a header line in chunks of rows, validating as :func:`read_table`.

    Parameters
    ----------
    path : path-like
        CSV file (limits as in :func:`read_table`). A missing file, a folder or a file over
        the size limit is refused at the call; everything else while iterating.
    required, optional, integer, text, max_abs
        As in :func:`read_table`.
    rows_per_chunk : int, optional
        Rows per chunk (default 65,536: the chunks :func:`read_table` validates one at a time,
        so both report the same first bad cell of a file).

    Yields
    ------
    TableChunk
        Consecutive rows in file order; the last chunk may be shorter. Memory is bounded by
        one chunk (its cells as text and as numbers), whatever the file's length.

    Raises
    ------
    FileNotFoundError, ValueError
        As :func:`read_table`, with the same messages: header problems (empty file, missing
        column) at the first chunk, a bad cell or row with the chunk that holds it, ``no data
        rows`` when the file ends without one. A consumer that writes as it reads must
        therefore write atomically (:func:`fusion.io.atomic_output`) so that bad input late
        in the file leaves no partial output.

    Notes
    -----
    Only the rows' own content is checked here. Checks across rows (time order, repeated
    times) are the reader of each file kind's (:mod:`fusion.io.table_stream`); a chunked reader
    cannot sort, so it refuses rows out of order where the whole-file reader sorts them.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> f = pathlib.Path(tempfile.mkdtemp()) / "t.csv"
    >>> _ = f.write_text("time,x\\n0,1\\n1,2\\n2,3\\n")
    >>> [c.table["x"].tolist() for c in iter_table(f, required=("time", "x"), rows_per_chunk=2)]
    [[1.0, 2.0], [3.0]]
    """
    if int(rows_per_chunk) != rows_per_chunk or rows_per_chunk < 1:
        raise ValueError(f"rows_per_chunk must be a positive integer, got {rows_per_chunk!r}")
    p = _check_file(path, max_bytes=MAX_CSV_BYTES, what="CSV inputs")
    return _chunks(p, required=tuple(required), optional=tuple(optional),
                   integer=frozenset(integer), text=frozenset(text), max_abs=max_abs,
                   rows_per_chunk=int(rows_per_chunk))


def _chunks(
    p: Path,
    *,
    required: tuple[str, ...],
    optional: tuple[str, ...],
    integer: frozenset[str],
    text: frozenset[str],
    max_abs: float | None,
    rows_per_chunk: int,
) -> Iterator[TableChunk]:
    """The chunks of :func:`iter_table` (a generator: nothing is read before the first)."""
    with p.open(newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(_csv_lines(p, fh))
        rows = _csv_rows(p, reader)
        first = next(rows, None)
        if first is None:
            raise ValueError(f"{p}: file is empty")
        header = _header(p, first, reader.line_num)
        missing = [c for c in required if c not in header]
        if missing:
            raise ValueError(f"{p}: missing required column(s) {', '.join(missing)}")
        wanted = list(required) + [c for c in optional if c in header and c not in required]
        index = [header.index(c) for c in wanted]
        cells: list[list[str]] = [[] for _ in wanted]  # per column, the cells of this chunk
        lines: list[int] = []  # line number of each row of this chunk
        n_rows = 0

        def chunk() -> TableChunk:
            columns: dict[str, NDArray[Any]] = {}
            for k, name in enumerate(wanted):
                if name in text:
                    columns[name] = np.array([c.strip() for c in cells[k]], dtype=str)
                else:
                    x = _numbers(cells[k], lines, f"{p}: line {{line}}, column {name!r}",
                                 whole=name in integer, max_abs=max_abs)
                    columns[name] = x.astype(np.int64) if name in integer else x
                cells[k] = []
            out = TableChunk(Table(columns, str(p)), n_rows - len(lines),
                             np.array(lines, dtype=np.int64))
            lines.clear()
            return out

        for row in rows:
            if len(row) != len(header):
                _ragged(p, reader.line_num, len(row), len(header))
            lines.append(reader.line_num)
            for k, j in enumerate(index):
                cells[k].append(row[j])
            n_rows += 1
            if len(lines) == rows_per_chunk:
                yield chunk()
        if lines:
            yield chunk()
    if n_rows == 0:
        raise ValueError(f"{p}: no data rows")


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

    See Also
    --------
    iter_table : the same, one chunk of rows at a time.
    """
    parts = [c.table for c in iter_table(path, required=required, optional=optional,
                                         integer=integer, text=text, max_abs=max_abs)]
    columns = {name: np.concatenate([t[name] for t in parts]) for name in parts[0].columns}
    return Table(columns, parts[0].source)


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


def _columns(path: PathLike, columns: Mapping[str, ArrayLike]) -> tuple[dict[str, NDArray[Any]], int]:
    """`columns` as arrays and their common length (a ValueError if they differ)."""
    cols = {k: np.asarray(v) for k, v in columns.items()}
    lengths = {len(v) for v in cols.values()}
    if len(lengths) > 1:
        raise ValueError(f"{path}: columns have different lengths {sorted(lengths)}")
    return cols, (lengths.pop() if lengths else 0)


def _format_column(v: NDArray[Any], float_format: str) -> list[str]:
    """The cells of one column as :func:`_format_cell` writes them, a column at a time."""
    if v.dtype.kind == "f":
        return [repr(x) if abs(x) >= _FIXED_LIMIT else float_format % x for x in v.tolist()]
    if v.dtype.kind in "iu":
        return [str(x) for x in v.tolist()]
    if v.dtype.kind == "b":
        return ["true" if x else "false" for x in v.tolist()]
    if v.dtype.kind == "U":
        return v.tolist()
    return [_format_cell(x, float_format) for x in v]


def _write_rows(w: Any, cols: dict[str, NDArray[Any]], n: int, float_format: str) -> None:
    if n:
        w.writerows(zip(*(_format_column(v, float_format) for v in cols.values()), strict=True))


def write_table(
    path: PathLike, columns: Mapping[str, ArrayLike], *, float_format: str = "%.6f",
    max_abs: float | None = None,
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
    max_abs : float, optional
        Refuse (ValueError naming file, row and column) NaN, infinity and numbers beyond
        +-`max_abs` -- what the readers refuse (:data:`MAX_ABS_VALUE`) -- before writing.

    Returns
    -------
    pathlib.Path
        The written path.
    """
    cols, n = _columns(path, columns)
    for name, v in cols.items() if max_abs is not None else ():
        bad = np.flatnonzero(~(np.abs(v) <= max_abs)) if v.dtype.kind in "fiu" else []
        if len(bad):
            raise ValueError(f"{path}: row {bad[0] + 1}, column {name!r}: {v[bad[0]]:g} is not "
                             f"a finite number within +-{max_abs:g}; not written")
    with atomic_output(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(list(cols))
        _write_rows(w, cols, n, float_format)
    return Path(path)


def write_table_chunks(
    path: PathLike,
    chunks: Iterable[Mapping[str, ArrayLike]],
    *,
    header: Sequence[str],
    float_format: str = "%.6f",
) -> Path:
    """Write a CSV file from chunks of rows as they come, atomically.

    Parameters
    ----------
    path : path-like
        Destination (``"-"``: standard output; see :func:`atomic_output`).
    chunks : iterable of mapping of str to array_like
        Consecutive rows: each chunk maps every name of `header` to 1-D values of one length.
        Typically a generator that computes each chunk from a chunk of the input
        (:func:`iter_table`); it is consumed once.
    header : sequence of str
        Column names, in order.
    float_format : str, optional
        As in :func:`write_table`.

    Returns
    -------
    pathlib.Path
        The written path.

    Notes
    -----
    The bytes equal those :func:`write_table` writes for the concatenated chunks. Rows go to a
    temporary file beside `path`; only when `chunks` is exhausted is it renamed onto `path`.
    An exception raised by `chunks` (bad input found late in the file) deletes it, so the
    destination is never partly written and an existing file there keeps its content.
    """
    names = list(header)
    with atomic_output(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(names)
        for chunk in chunks:
            if list(chunk) != names:
                raise ValueError(f"{path}: a chunk has columns {list(chunk)}, expected {names}")
            cols, n = _columns(path, chunk)
            _write_rows(w, cols, n, float_format)
    return Path(path)
