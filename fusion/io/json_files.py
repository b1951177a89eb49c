"""JSON files: read with validation, write atomically (numpy scalars and arrays converted)."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from fusion._output import atomic_output
from fusion.io._files import MAX_JSON_BYTES, PathLike, _check_file

__all__ = ["read_json", "settings_path", "write_json", "write_settings"]


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


def settings_path(out: PathLike) -> Path:
    """Where a command writes the settings it chose: ``T.csv`` -> ``T.settings.json`` beside it."""
    out = Path(out)
    return out.with_name(out.stem + ".settings.json")


def write_settings(out: PathLike, document: Any, *,
                   inputs: Iterable[PathLike | None] = ()) -> Path | None:
    """Write `document` to :func:`settings_path` of `out`, atomically.

    Nothing is written (None) when `out` is standard output (``-``) or when that path is one
    of `inputs` (by any link or path): a side file never replaces an input.
    """
    if str(out) == "-":
        return None
    side = settings_path(out)
    for p in inputs:
        try:
            if p is not None and os.path.samefile(side, p):
                return None
        except OSError:
            continue
    return write_json(side, document)
