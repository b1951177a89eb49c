"""Property tests of every reader in fusion.io: any file content gives a valid result or ValueError.

Hypothesis feeds each reader random bytes and structured near-misses (CSV-like text, JSON
documents, ``.npz`` archives of random dtypes, damaged WAV/FLAC files). A reader may accept the
file -- then its result must satisfy the format's invariants -- or raise ValueError; any other
exception (a csv/json/zip/soundfile error, TypeError, OverflowError, MemoryError, ...) is a bug.
"""

from __future__ import annotations

import contextlib
import io as _io
import json
import math
import tempfile
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusion import io
from fusion.io import MAX_ABS_VALUE, Table

SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@contextmanager
def file_with(content: bytes, name: str) -> Iterator[Path]:
    """A temporary file holding `content`."""
    with tempfile.TemporaryDirectory() as folder:
        p = Path(folder) / name
        p.write_bytes(content)
        yield p


def valid_or_value_error(reader: Callable[[Path], object], p: Path) -> object | None:
    """The reader's result, or None if it raised ValueError naming the file (anything else fails)."""
    try:
        return reader(p)
    except ValueError as e:
        assert p.name in str(e) or "window" in str(e), f"message does not name the file: {e}"
        return None


# --------------------------------------------------------------------------------------------
# CSV readers
# --------------------------------------------------------------------------------------------
TABLE_READERS: dict[str, tuple[Callable[[Path], Table], tuple[str, ...]]] = {
    "bearings": (io.read_bearings, ("track_id", "time", "bearing_deg")),
    "amplitudes": (io.read_amplitudes, ("track_id", "time", "amplitude", "residual")),
    "detections": (io.read_detections, ("event", "time", "x", "y", "score", "snr_db")),
    "ownship": (io.read_ownship, ("time", "x", "y")),
    "tma_bearings": (io.read_tma_bearings, ("time", "bearing_deg")),
    "tqi": (io.read_tqi, ("track_id", "time", "amplitude", "residual", "tqi")),
    "tracks": (io.read_tracks, ("track_id", "event", "time", "x", "y", "vx", "vy", "status")),
    "alerts": (io.read_alerts, ("time", "track_a", "track_b", "t_cross", "kind")),
    "smoothed": (io.read_smoothed, ("track_id", "time", "bearing_deg", "bearing_rate_deg_per_min",
                                    "sigma_bearing_deg")),
    "tma_result": (io.read_tma_result, ("time", "x", "y", "vx", "vy", "sigma_x", "sigma_y",
                                        "range")),
    "table": (lambda p: io.read_table(p, required=("a",), optional=("b",), integer=("a",),
                                      text=("c",)), ("a", "b", "c")),
}

bad_cells = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", " ", "nan", "inf", "-inf", "1e308", "-1e13", "1_000", "0x10", "strong",
                     "\"", "\"a,b\"", "\"1\n2\"", "\x00", "é", "-0", "  7  ", "\ufeff", "2.5"]),
    st.text(max_size=6),
)

#: good values of the category columns
CATEGORIES = {"tqi": io.TQI_STATES, "status": io.TRACK_STATUSES, "kind": io.ALERT_KINDS}


def good_cells(column: str) -> st.SearchStrategy[str]:
    """Values a reader accepts in `column` (small whole numbers, scores in [0, 1], categories)."""
    if column in CATEGORIES:
        return st.sampled_from(CATEGORIES[column])
    if column == "c":
        return st.text(alphabet="abc ", max_size=4)
    if column == "score":
        return st.sampled_from(["0", "0.25", "1"])
    return st.integers(-1, 6).map(str)


@st.composite
def csv_like(draw, columns: tuple[str, ...]) -> bytes:
    """CSV-like bytes: a table of good cells under a header, then up to three mutations."""
    header = list(columns) + draw(st.lists(st.sampled_from(["junk", ""]), max_size=2))
    header = draw(st.permutations(header))
    rows = [[draw(good_cells(c)) for c in header] for _ in range(draw(st.integers(1, 8)))]
    table = [header, *rows]
    for _ in range(draw(st.integers(0, 3))):
        r = draw(st.integers(0, len(table) - 1))
        what = draw(st.sampled_from(["cell", "cell", "drop", "add", "row", "header"]))
        if what == "cell" and table[r]:
            table[r][draw(st.integers(0, len(table[r]) - 1))] = draw(bad_cells)
        elif what == "drop" and table[r]:
            del table[r][draw(st.integers(0, len(table[r]) - 1))]
        elif what == "add":
            table[r].append(draw(bad_cells))
        elif what == "row":
            table.insert(r, draw(st.lists(bad_cells, max_size=len(header) + 1)))
        else:
            table[0] = draw(st.lists(st.sampled_from([*columns, "junk", ""]), max_size=9))
    end = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    text = end.join(",".join(r) for r in table) + draw(st.sampled_from(["", end]))
    encoding = draw(st.sampled_from(["utf-8", "utf-8", "utf-8-sig", "utf-16", "latin-1"]))
    return text.encode(encoding, errors="replace")


def table_problems(t: Table) -> list[str]:
    """What is wrong with a table that was accepted: it needs at least one row, columns of
    equal length and finite numbers (empty when nothing is)."""
    n = len(t)
    problems = [] if n >= 1 else ["no rows"]
    for name, values in t.columns.items():
        if len(values) != n:
            problems.append(f"{name}: {len(values)} values for {n} rows")
        elif values.dtype.kind in "fi" and not np.all(np.isfinite(values)):
            problems.append(f"{name}: a value that is not finite")
    return problems


@pytest.mark.parametrize("kind", sorted(TABLE_READERS))
@SETTINGS
@given(data=st.data())
def test_csv_readers_random_text(kind, data):
    """CSV readers on random CSV-like text: a valid table or ValueError."""
    reader, columns = TABLE_READERS[kind]
    content = data.draw(csv_like(columns))
    with file_with(content, f"{kind}.csv") as p:
        t = valid_or_value_error(reader, p)
    assert t is None or table_problems(t) == []


@pytest.mark.parametrize("kind", sorted(TABLE_READERS))
@SETTINGS
@given(content=st.binary(max_size=600))
def test_csv_readers_random_bytes(kind, content):
    """CSV readers on random bytes: a valid table or ValueError."""
    reader, _ = TABLE_READERS[kind]
    with file_with(content, f"{kind}.csv") as p:
        t = valid_or_value_error(reader, p)
    assert t is None or table_problems(t) == []


@SETTINGS
@given(data=st.data())
def test_time_series_readers_order_and_bounds(data):
    """Accepted bearings: each track in time order, labelled times distinct, values bounded."""
    content = data.draw(csv_like(("track_id", "time", "bearing_deg")))
    with file_with(content, "b.csv") as p:
        t = valid_or_value_error(io.read_bearings, p)
    if t is None:
        return
    for k in np.unique(t["track_id"]):
        times = t["time"][t["track_id"] == k]
        assert np.all(np.diff(times) >= 0)
        if k >= 0:
            assert np.all(np.diff(times) > 0)
    assert np.all(np.abs(t["bearing_deg"]) <= MAX_ABS_VALUE)


# --------------------------------------------------------------------------------------------
# JSON readers
# --------------------------------------------------------------------------------------------
json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20),
              st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=5)),
    lambda children: st.one_of(st.lists(children, max_size=5),
                               st.dictionaries(st.sampled_from(
                                   ["sensors", "sound_speed", "x", "y", "z", "id", "windows",
                                    "tdoas", "sources", "pair", "tau", "valid", "llr", "cov",
                                    "tdoas_used", "t_start", "t_end", "tracks", "points", "t"]),
                                   children, max_size=6)),
    max_leaves=30,
)

@st.composite
def array_docs(draw) -> bytes:
    """array.json near-misses: 3-5 sensors on a small grid (repeats and lines happen), mutated."""
    n = draw(st.integers(3, 5))
    sensors: list[dict] = [{"id": f"H{k}", "x": draw(st.integers(-2, 2)),
                            "y": draw(st.integers(-2, 2)), "z": draw(st.floats(-2, 2))}
                           for k in range(n)]
    doc: dict = {"sound_speed": 1500.0, "sensors": sensors}
    for _ in range(draw(st.integers(0, 2))):
        bad = draw(st.sampled_from(["1", None, True, math.nan, 1e-4, [], 0, -1, 7]))
        where = draw(st.sampled_from(["x", "y", "z", "id", "sound_speed", "drop", "sensors"]))
        if where == "sound_speed":
            doc["sound_speed"] = bad
        elif where == "sensors":
            doc["sensors"] = bad
        elif where == "drop":
            del sensors[draw(st.integers(0, len(sensors) - 1))]
        elif sensors:
            sensors[draw(st.integers(0, len(sensors) - 1))][where] = bad
    return json.dumps(doc).encode()


@st.composite
def localization_docs(draw) -> bytes:
    """Localization results with randomly damaged fields."""
    good = {"windows": [{"t_start": 0.0, "t_end": 12.0,
                         "tdoas": [{"pair": [0, 1], "tau": 0.4, "valid": True, "llr": 5.2}],
                         "sources": [{"x": 0.0, "y": 0.0, "z": -900.0,
                                      "cov": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "tdoas_used": 7}]}],
            "tracks": [{"id": 0, "points": [{"t": 6.0, "x": 0.0, "y": 0.0, "z": -900.0}]}]}
    text = json.dumps(good)
    for _ in range(draw(st.integers(0, 2))):
        value = draw(st.sampled_from(['"a"', "null", "[]", "{}", "1e400", "Infinity", "NaN",
                                      "true", "[1]", "-1", "1.5"]))
        target = draw(st.sampled_from(["0.4", "5.2", "[0, 1]", "true", "7", "6.0", "-900.0",
                                       "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]", "0"]))
        text = text.replace(target, value, 1)
    return text.encode()


JSON_READERS = {"json": io.read_json, "array": io.read_array, "localization": io.read_localization}


@pytest.mark.parametrize("kind", sorted(JSON_READERS))
@SETTINGS
@given(data=st.data())
def test_json_readers(kind, data):
    """JSON readers on random bytes, random JSON and near-miss documents: result or ValueError."""
    content = data.draw(st.one_of(
        st.binary(max_size=300),
        json_values.map(lambda v: json.dumps(v).encode()),
        array_docs(), localization_docs(),
        st.integers(1, 5000).map(lambda n: b"[" * n),
    ))
    with file_with(content, f"{kind}.json") as p:
        result = valid_or_value_error(JSON_READERS[kind], p)
    if kind == "array" and result is not None:
        pos = result.positions
        gaps = np.linalg.norm(pos[:, None] - pos[None, :], axis=-1) + np.eye(len(pos))
        assert np.all(gaps >= io.MIN_SENSOR_SEPARATION_M)


# --------------------------------------------------------------------------------------------
# cubes
# --------------------------------------------------------------------------------------------
dtypes = st.sampled_from([np.float32, np.int16, np.uint8, np.complex128, np.bool_, "U3", "S2",
                          object])


@st.composite
def npz_archives(draw) -> bytes:
    """A valid cube's ``.npz``, then up to three mutations of its arrays, maybe truncated."""
    n_scans, n_beams, n_bins = (draw(st.integers(1, 4)) for _ in range(3))
    arrays: dict[str, object] = {
        "power": np.abs(np.sin(np.arange(n_scans * n_beams * n_bins))).reshape(
            n_scans, n_beams, n_bins),
        "freqs": 100.0 + np.arange(n_bins), "scan_period": 1.0, "aperture": 20.0,
        "sound_speed": 1500.0}
    for _ in range(draw(st.integers(0, 3))):
        key = draw(st.sampled_from(sorted(arrays)))
        value = np.asarray(arrays[key])
        what = draw(st.sampled_from(["dtype", "value", "shape", "delete"]))
        if what in ("dtype", "value"):
            dtype = draw(dtypes)
            bad = draw(st.sampled_from([math.nan, math.inf, -1.0, 0.0, 1e300]))
            # a mutation numpy cannot make (text to int, ...) leaves the array as it was
            with warnings.catch_warnings(), np.errstate(all="ignore"), \
                    contextlib.suppress(ValueError, TypeError, OverflowError):
                warnings.simplefilter("ignore")
                arrays[key] = value.astype(dtype) if what == "dtype" else np.where(
                    np.arange(value.size).reshape(value.shape) == 0, bad, value)
        elif what == "shape":
            arrays[key] = value.reshape(-1) if value.ndim else np.full(2, value)
        else:
            del arrays[key]
    buf = _io.BytesIO()
    np.savez(buf, **arrays)
    data = buf.getvalue()
    if draw(st.integers(0, 4)) == 0:  # damage: truncate
        data = data[: draw(st.integers(0, len(data)))]
    return data


@SETTINGS
@given(content=st.one_of(st.binary(max_size=400), npz_archives(),
                         st.binary(max_size=50).map(lambda b: b"PK\x03\x04" + b),
                         st.binary(max_size=50).map(lambda b: b"\x93NUMPY" + b)))
def test_read_cube(content):
    """read_cube on random bytes and random archives: a valid cube or ValueError."""
    with file_with(content, "cube.npz") as p:
        cube = valid_or_value_error(io.read_cube, p)
    if cube is not None:
        assert cube.power.dtype == np.float64 and np.all(cube.power >= 0)
        assert np.all(np.isfinite(cube.power)) and cube.scan_period > 0


# --------------------------------------------------------------------------------------------
# audio
# --------------------------------------------------------------------------------------------
def _audio_bytes(fmt: str, n: int, channels: int) -> bytes:
    rng = np.random.default_rng(n + channels)
    buf = _io.BytesIO()
    sf.write(buf, rng.uniform(-0.5, 0.5, (n, channels)), 8000, format=fmt, subtype="PCM_16")
    return buf.getvalue()


@st.composite
def damaged_audio(draw) -> bytes:
    """A valid WAV/FLAC, then truncated, overwritten in places, or both."""
    fmt = draw(st.sampled_from(["WAV", "FLAC"]))
    data = bytearray(_audio_bytes(fmt, draw(st.integers(1, 3000)), draw(st.integers(1, 3))))
    for _ in range(draw(st.integers(0, 4))):
        at = draw(st.integers(0, len(data) - 1))
        chunk = draw(st.binary(min_size=1, max_size=64))
        data[at: at + len(chunk)] = chunk
    if draw(st.booleans()):
        data = data[: draw(st.integers(0, len(data)))]
    return bytes(data)


def _read_blocks(p: Path) -> list:
    return list(io.iter_audio_blocks(p, block_s=0.05, hop_s=0.025))


AUDIO_READERS = {"read_audio": io.read_audio, "iter_audio_blocks": _read_blocks}


@pytest.mark.parametrize("kind", sorted(AUDIO_READERS))
@SETTINGS
@given(content=st.one_of(st.binary(max_size=300), damaged_audio()),
       suffix=st.sampled_from([".wav", ".flac"]))
def test_audio_readers(kind, content, suffix):
    """Audio readers on random and damaged files: finite samples or ValueError."""
    with file_with(content, f"audio{suffix}") as p:
        result = valid_or_value_error(AUDIO_READERS[kind], p)
    if kind == "read_audio" and result is not None:
        samples, fs = result
        assert samples.ndim == 2 and samples.shape[0] > 0 and np.all(np.isfinite(samples))
        assert fs > 0
