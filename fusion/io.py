"""Readers and writers for the files the ``fusion`` command reads and writes.

Every reader validates what it reads and raises :class:`ValueError` (or :class:`FileNotFoundError`
for a missing file) whose message starts with the file's path and names the problem; the command
line turns these into one line on stderr and exit code 2. Every writer is atomic: it writes a
temporary file in the destination folder and renames it into place, so an interrupted or failed
run never leaves a half-written result.

Formats (see the project's format notes):

- sensor array ``array.json``: ``{"sound_speed": c, "sensors": [{"id", "x", "y", "z"}, ...]}``;
- audio, WAV or FLAC, channel ``i`` = ``sensors[i]``;
- CSV tables with a header line; extra columns are ignored, missing required columns are errors;
- beam/frequency/time cubes ``.npz`` with ``power``, ``freqs``, ``scan_period``, ``aperture``,
  ``sound_speed``;
- JSON results.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import SensorArray

__all__ = [
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


# --------------------------------------------------------------------------------------------
# atomic output
# --------------------------------------------------------------------------------------------
@contextlib.contextmanager
def atomic_output(path: PathLike, *, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside `path`; on success rename it onto `path`, else delete it.

    Parameters
    ----------
    path : path-like
        Final destination. Its folder is created if missing.
    suffix : str, optional
        Suffix of the temporary file (defaults to that of `path`, so that writers that pick a
        format by suffix, like soundfile, see the right one).

    Yields
    ------
    pathlib.Path
        Where to write.
    """
    dest = Path(path)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(
        prefix=f".{dest.name}.", suffix=dest.suffix if suffix is None else suffix, dir=dest.parent
    )
    os.close(fd)
    tmp = Path(tmp_name)
    # mkstemp makes the file private (0600); give it the usual permissions of a new file.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        yield tmp
        os.replace(tmp, dest)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def _check_file(path: PathLike) -> Path:
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    if p.is_dir():
        raise ValueError(f"{p}: is a directory, expected a file")
    return p


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


def read_table(
    path: PathLike,
    *,
    required: Sequence[str],
    optional: Sequence[str] = (),
    integer: Sequence[str] = (),
    text: Sequence[str] = (),
) -> Table:
    """Read a CSV file with a header line, keeping and validating the named columns.

    Parameters
    ----------
    path : path-like
        CSV file.
    required : sequence of str
        Columns that must be present.
    optional : sequence of str, optional
        Columns read when present (absent ones are simply not in the result).
    integer : sequence of str, optional
        Columns that must hold whole numbers (returned as int64).
    text : sequence of str, optional
        Columns kept as strings (not checked as numbers).

    Returns
    -------
    Table
        The required columns and the optional ones present; extra columns are ignored.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        Empty file, no data rows, a missing required column, a ragged row, a non-numeric
        value, NaN or infinity. The message starts with the path and names row and column.
    """
    p = _check_file(path)
    try:
        with p.open(newline="", encoding="utf-8-sig") as fh:
            rows = [r for r in csv.reader(fh) if any(cell.strip() for cell in r)]
    except UnicodeDecodeError:
        raise ValueError(f"{p}: not a text CSV file") from None
    if not rows:
        raise ValueError(f"{p}: file is empty")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in required if c not in header]
    if missing:
        raise ValueError(f"{p}: missing required column(s) {', '.join(missing)}")
    if len(rows) < 2:
        raise ValueError(f"{p}: no data rows")
    wanted = list(required) + [c for c in optional if c in header and c not in required]
    index = {c: header.index(c) for c in wanted}
    columns: dict[str, NDArray[Any]] = {}
    for name, j in index.items():
        values: list[Any] = []
        for lineno, row in enumerate(rows[1:], start=2):
            if j >= len(row):
                raise ValueError(f"{p}: line {lineno} has {len(row)} fields, header has {len(header)}")
            cell = row[j].strip()
            if name in text:
                values.append(cell)
                continue
            try:
                x = float(cell)
            except ValueError:
                raise ValueError(
                    f"{p}: line {lineno}, column {name!r}: {cell!r} is not a number"
                ) from None
            if not math.isfinite(x):
                raise ValueError(f"{p}: line {lineno}, column {name!r}: value is {cell}")
            if name in integer and x != round(x):
                raise ValueError(
                    f"{p}: line {lineno}, column {name!r}: {cell!r} is not a whole number"
                )
            values.append(x)
        if name in text:
            columns[name] = np.array(values, dtype=str)
        elif name in integer:
            columns[name] = np.array(values, dtype=float).astype(np.int64)
        else:
            columns[name] = np.array(values, dtype=float)
    return Table(columns, str(p))


def _require_nondecreasing(table: Table, col: str, *, by: str | None = None) -> None:
    t = table[col]
    if by is None:
        if np.any(np.diff(t) < 0):
            raise ValueError(f"{table.source}: column {col!r} must be non-decreasing")
        return
    keys = table[by]
    for k in np.unique(keys):
        if np.any(np.diff(t[keys == k]) < 0):
            raise ValueError(f"{table.source}: column {col!r} must be non-decreasing for {by} {k}")


def read_bearings(path: PathLike) -> Table:
    """Bearing tracks ``track_id,time,bearing_deg`` (``track_id`` -1: unknown origin).

    Rows need not be sorted; callers sort by time.
    """
    return read_table(path, required=("track_id", "time", "bearing_deg"), integer=("track_id",))


def read_amplitudes(path: PathLike) -> Table:
    """Tracker outputs ``track_id,time,amplitude,residual`` (amplitude linear, >= 0)."""
    t = read_table(
        path, required=("track_id", "time", "amplitude", "residual"), integer=("track_id",)
    )
    if np.any(t["amplitude"] < 0):
        raise ValueError(f"{t.source}: column 'amplitude' has negative values (expected linear power)")
    _require_nondecreasing(t, "time", by="track_id")
    return t


DETECTION_CLUES = ("snr_db", "score", "aspect_deg", "src_x", "src_y", "rcv_x", "rcv_y")


def read_detections(path: PathLike) -> Table:
    """Position detections ``event,time,x,y`` plus optional clue columns.

    Optional: ``snr_db, score, aspect_deg, src_x, src_y, rcv_x, rcv_y``. ``score`` must lie in
    [0, 1]; ``event`` must be non-decreasing.
    """
    t = read_table(
        path, required=("event", "time", "x", "y"), optional=DETECTION_CLUES, integer=("event",)
    )
    if "score" in t and np.any((t["score"] < 0) | (t["score"] > 1)):
        raise ValueError(f"{t.source}: column 'score' must lie in [0, 1]")
    _require_nondecreasing(t, "event")
    return t


def read_ownship(path: PathLike) -> Table:
    """Own-ship positions ``time,x,y``, strictly increasing in time."""
    t = read_table(path, required=("time", "x", "y"))
    if np.any(np.diff(t["time"]) <= 0):
        raise ValueError(f"{t.source}: column 'time' must be strictly increasing")
    return t


def read_tma_bearings(path: PathLike) -> Table:
    """True bearings ``time,bearing_deg`` (clockwise from north), strictly increasing in time."""
    t = read_table(path, required=("time", "bearing_deg"))
    if np.any(np.diff(t["time"]) <= 0):
        raise ValueError(f"{t.source}: column 'time' must be strictly increasing")
    return t


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
    )


def read_tma_result(path: PathLike) -> Table:
    """Output of ``fusion tma``: ``time,x,y,vx,vy,sigma_x,sigma_y,range``."""
    return read_table(path, required=("time", "x", "y", "vx", "vy", "sigma_x", "sigma_y", "range"))


def _format_cell(v: Any, float_format: str) -> str:
    if isinstance(v, str | np.str_):
        return str(v)
    if isinstance(v, bool | np.bool_):
        return "true" if v else "false"
    if isinstance(v, int | np.integer):
        return str(int(v))
    return float_format % float(v)


def write_table(
    path: PathLike, columns: Mapping[str, ArrayLike], *, float_format: str = "%.6f"
) -> Path:
    """Write columns as a CSV file with a header line, atomically.

    Parameters
    ----------
    path : path-like
        Destination.
    columns : mapping of str to array_like
        Column name to 1-D values, all the same length; integer, float, bool or str values.
    float_format : str, optional
        printf-style format of float values.

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
    """Read a JSON file; a malformed one raises ValueError naming the file and position."""
    p = _check_file(path)
    text = p.read_text(encoding="utf-8")
    if not text.strip():
        raise ValueError(f"{p}: file is empty")
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"{p}: malformed JSON ({e.msg} at line {e.lineno}, column {e.colno})") from None


def write_json(path: PathLike, obj: Any, *, indent: int | None = 1) -> Path:
    """Write `obj` as JSON atomically (numpy scalars and arrays are converted)."""
    text = json.dumps(obj, indent=indent, default=_json_default, allow_nan=False)
    with atomic_output(path) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    return Path(path)


# --------------------------------------------------------------------------------------------
# sensor arrays
# --------------------------------------------------------------------------------------------
def read_array(path: PathLike) -> SensorArray:
    """Read a sensor array file (``array.json``).

    Raises
    ------
    ValueError
        Malformed JSON, missing keys, non-numeric or non-finite coordinates, fewer than 3 sensors,
        all sensors collinear, non-positive sound speed.
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


def _audio_info(p: Path):
    sf = _sf()
    try:
        return sf.info(str(p))
    except (RuntimeError, sf.LibsndfileError) as e:
        raise ValueError(f"{p}: not a readable WAV/FLAC audio file ({e})") from None


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
        Unreadable file, no samples, wrong channel count, NaN/inf samples.
    """
    p = _check_file(path)
    info = _audio_info(p)
    if n_channels is not None and info.channels != n_channels:
        raise ValueError(
            f"{p}: audio has {info.channels} channel(s) but the array has {n_channels} sensors"
        )
    if info.frames == 0:
        raise ValueError(f"{p}: audio file has no samples")
    data, fs = _sf().read(str(p), dtype="float64", always_2d=True)
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
    """
    p = _check_file(path)
    info = _audio_info(p)
    if n_channels is not None and info.channels != n_channels:
        raise ValueError(
            f"{p}: audio has {info.channels} channel(s) but the array has {n_channels} sensors"
        )
    if block_s <= 0 or hop_s <= 0:
        raise ValueError("window length and hop must be positive")
    fs = float(info.samplerate)
    block, hop = int(round(block_s * fs)), int(round(hop_s * fs))
    for start, data in enumerate(
        _sf().blocks(str(p), blocksize=block, overlap=max(block - hop, 0), dtype="float64",
                     always_2d=True)
    ):
        if not np.all(np.isfinite(data)):
            raise ValueError(f"{p}: audio contains NaN or infinite samples")
        yield start * hop / fs, data, fs


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


def read_cube(path: PathLike) -> Cube:
    """Read a beam/frequency/time cube from ``.npz``."""
    p = _check_file(path)
    try:
        with np.load(p, allow_pickle=False) as z:
            files = list(z.files)
            d = {k: z[k] for k in _CUBE_KEYS if k in files}
    except Exception as e:  # zipfile.BadZipFile, OSError, refused pickles: all mean "not a cube"
        raise ValueError(f"{p}: not a readable .npz cube ({e})") from None
    missing = [k for k in _CUBE_KEYS if k not in d]
    if missing:
        raise ValueError(f"{p}: missing array(s) {', '.join(missing)}")
    try:
        return Cube(
            power=d["power"],
            freqs=d["freqs"],
            scan_period=float(np.asarray(d["scan_period"]).reshape(())),
            aperture=float(np.asarray(d["aperture"]).reshape(())),
            sound_speed=float(np.asarray(d["sound_speed"]).reshape(())),
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
            tdoas = tuple(
                TdoaRecord((int(d["pair"][0]), int(d["pair"][1])), _num(d["tau"], where),
                           bool(d["valid"]), _num(d["llr"], where))
                for d in w["tdoas"]
            )
            sources = []
            for s in w["sources"]:
                cov = np.asarray(s["cov"], dtype=float)
                if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
                    raise ValueError(f"{where}: 'cov' must be a finite 3x3 matrix")
                sources.append(SourceEstimate(
                    _num(s["x"], where), _num(s["y"], where), _num(s["z"], where),
                    tuple(tuple(float(v) for v in r) for r in cov), int(s["tdoas_used"])))
            windows.append(LocalizationWindow(_num(w["t_start"], where), _num(w["t_end"], where),
                                              tdoas, tuple(sources)))
        tracks = tuple(
            (int(t["id"]), tuple((_num(q["t"], str(p)), _num(q["x"], str(p)), _num(q["y"], str(p)),
                                  _num(q["z"], str(p))) for q in t["points"]))
            for t in doc.get("tracks", [])
        )
    except (KeyError, TypeError, IndexError) as e:
        raise ValueError(f"{p}: malformed localization result (missing or bad {e})") from None
    return LocalizationResult(tuple(windows), tracks)
