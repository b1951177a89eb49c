"""What a ``fusion`` result is: its kind, told from its columns, keys or folder contents.

:func:`detect_result` looks at a file's header line (CSV) or top-level keys (JSON), or at the
files of a folder, and names the command that wrote it. Only the header or the keys are read here;
the readers of :mod:`fusion.io` validate the whole file when a figure is drawn.

========================  ===================================================================
kind                      recognised by
========================  ===================================================================
``acquisition``           JSON with ``bearing_deg``, ``bearing_rate_deg_per_min``, ``snr_db``
                          (``fusion acquire``, saved from stdout)
``localization``          JSON with ``windows`` (``fusion localize``)
``events``                JSON with ``events`` (``fusion localize --events``)
``localization_folder``   a folder of localization JSONs (``fusion localize --audio DIR``)
``passive``               a folder with ``tracks.csv`` and ``alerts.csv`` (``fusion passive``)
``passive_tracks``        smoothed-track columns plus ``tqi`` (``tracks.csv`` of ``passive``)
``smoothed``              ``track_id,time,bearing_deg,bearing_rate_deg_per_min,
                          sigma_bearing_deg`` (``fusion smooth``)
``tqi``                   ``track_id,time,amplitude,residual,tqi`` (``fusion tqi``)
``alerts``                ``time,track_a,track_b,t_cross,kind`` (``fusion crossings``)
``tracks``                ``track_id,event,time,x,y,vx,vy,status`` (``fusion track``)
``tma``                   ``time,x,y,vx,vy,sigma_x,sigma_y,range`` (``fusion tma``)
========================  ===================================================================
"""

from __future__ import annotations

import csv
import json
import os
import stat
from dataclasses import dataclass
from pathlib import Path

from fusion._output import special_file_kind

__all__ = ["KINDS", "DetectedResult", "detect_result", "file_kind"]

#: Bytes read to find a CSV header line or to tell a JSON file's keys (larger JSON is parsed whole).
SNIFF_BYTES = 1 << 16

#: CSV kinds: name -> required columns (the most specific first).
CSV_KINDS: tuple[tuple[str, frozenset[str]], ...] = (
    ("passive_tracks", frozenset({"track_id", "time", "bearing_deg", "bearing_rate_deg_per_min",
                                  "sigma_bearing_deg", "tqi"})),
    ("smoothed", frozenset({"track_id", "time", "bearing_deg", "bearing_rate_deg_per_min",
                            "sigma_bearing_deg"})),
    ("tqi", frozenset({"track_id", "time", "amplitude", "residual", "tqi"})),
    ("alerts", frozenset({"time", "track_a", "track_b", "t_cross", "kind"})),
    ("tracks", frozenset({"track_id", "event", "time", "x", "y", "vx", "vy", "status"})),
    ("tma", frozenset({"time", "x", "y", "vx", "vy", "sigma_x", "sigma_y", "range"})),
)

#: Every kind :func:`detect_result` can name, with the command that writes it.
KINDS: dict[str, str] = {
    "acquisition": "fusion acquire",
    "localization": "fusion localize",
    "events": "fusion localize --events",
    "localization_folder": "fusion localize --audio DIR",
    "passive": "fusion passive",
    "passive_tracks": "fusion passive (tracks.csv)",
    "smoothed": "fusion smooth",
    "tqi": "fusion tqi",
    "alerts": "fusion crossings",
    "tracks": "fusion track",
    "tma": "fusion tma",
}

_ACQUISITION_KEYS = frozenset({"bearing_deg", "bearing_rate_deg_per_min", "snr_db"})


@dataclass(frozen=True)
class DetectedResult:
    """A result and its kind.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    path : pathlib.Path
        The result as given (file or folder).
    files : tuple of pathlib.Path
        The files to read: the file itself, or the folder's result files (passive: tracks,
        alerts; localization folder: every localization JSON, sorted by name).
    """

    kind: str
    path: Path
    files: tuple[Path, ...]


def _known() -> str:
    return ("expected the output of " + ", ".join(sorted(set(KINDS.values()) - {
        "fusion passive (tracks.csv)", "fusion localize --audio DIR"})))


def _head(path: Path) -> bytes:
    with path.open("rb") as fh:
        return fh.read(SNIFF_BYTES)


def _csv_kind(path: Path, head: bytes) -> str | None:
    """The CSV kind of a file whose first bytes are `head` (None: not a known table)."""
    text = head.decode("utf-8-sig", errors="replace")
    line = text.splitlines()[0] if text.strip() else ""
    if not line:
        return None
    try:
        columns = {c.strip() for c in next(csv.reader([line]))}
    except csv.Error:
        return None
    for kind, required in CSV_KINDS:
        if required <= columns:
            return kind
    return None


def _json_kind(path: Path, head: bytes) -> str | None:
    """The JSON kind of a file (None: not a known JSON result)."""
    if not head.lstrip().startswith(b"{"):
        return None
    if len(head) >= SNIFF_BYTES:
        from fusion.io import read_json

        doc = read_json(path)
    else:
        try:
            doc = json.loads(head.decode("utf-8-sig"))
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):
            return None
    if not isinstance(doc, dict):
        return None
    if "windows" in doc:
        return "localization"
    if "events" in doc:
        return "events"
    if _ACQUISITION_KEYS <= set(doc):
        return "acquisition"
    return None


def file_kind(path: Path) -> str | None:
    """The kind of a regular result file from its first bytes (None: not a known result)."""
    head = _head(path)
    if b"\0" in head:
        return None  # binary: neither a CSV table nor JSON
    if path.suffix.lower() == ".json" or head.lstrip().startswith(b"{"):
        return _json_kind(path, head)
    return _csv_kind(path, head)


def _folder(path: Path) -> DetectedResult:
    tracks, alerts = path / "tracks.csv", path / "alerts.csv"
    if tracks.is_file() and alerts.is_file() and file_kind(tracks) == "passive_tracks":
        return DetectedResult("passive", path, (tracks, alerts))
    jsons = sorted(p for p in path.iterdir() if p.suffix.lower() == ".json" and p.is_file())
    found = tuple(p for p in jsons if file_kind(p) in ("localization", "events"))
    if found:
        return DetectedResult("localization_folder", path, found)
    raise ValueError(f"{path}: a folder without a fusion result (no tracks.csv + alerts.csv of "
                     "fusion passive, no localization JSON of fusion localize); " + _known())


def detect_result(path: str | os.PathLike[str]) -> DetectedResult:
    """Tell what kind of ``fusion`` result `path` is.

    Parameters
    ----------
    path : path-like
        A result file (CSV table or JSON) or a command's output folder.

    Returns
    -------
    DetectedResult

    Raises
    ------
    ValueError
        One line naming the path: missing, a special file (FIFO, device, socket), unreadable as
        text, or not any known result (the message lists what is expected).
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise ValueError(f"{p}: no such file or folder") from None
    except OSError as e:
        raise ValueError(f"{p}: cannot be read ({e.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        return _folder(p)
    kind = special_file_kind(st.st_mode)
    if kind is not None:
        raise ValueError(f"{p}: is {kind}, not a result file")
    try:
        found = file_kind(p)
    except PermissionError:
        raise ValueError(f"{p}: permission denied") from None
    if found is None:
        raise ValueError(f"{p}: not a result the report knows (unknown columns or keys); "
                         + _known())
    return DetectedResult(found, p, (p,))
