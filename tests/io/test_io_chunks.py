"""Tests of chunked CSV reading and writing: iter_table, the chunked kind readers, write_table_chunks."""

import logging

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from fusion.io import (
    RowOrderError,
    iter_amplitudes,
    iter_bearings,
    iter_detections,
    iter_table,
    read_amplitudes,
    read_bearings,
    read_table,
    write_table,
    write_table_chunks,
)

_SETTINGS = settings(max_examples=60, deadline=None,
                     suppress_health_check=[HealthCheck.function_scoped_fixture])


def _write(tmp_path, text, name="t.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _bearings_text(rows):
    return "track_id,time,bearing_deg\n" + "".join(f"{k},{t},{b}\n" for k, t, b in rows)


@pytest.mark.parametrize("rows_per_chunk", [1, 2, 3, 7, 100])
def test_chunks_concatenate_to_the_whole_file(tmp_path, rows_per_chunk):
    """Chunks of any size hold the rows of read_table in order, with their line numbers."""
    text = "time,x,label,id,extra\n" + "".join(
        f"{0.5 * i},{i * i - 3},{'ab'[i % 2] * (i % 4)},{i // 3},z\n" + ("\n" if i == 4 else "")
        for i in range(11))
    p = _write(tmp_path, text)
    opts = {"required": ("time", "x"), "optional": ("label", "id"), "text": ("label",),
            "integer": ("id",)}
    whole = read_table(p, **opts)
    chunks = list(iter_table(p, rows_per_chunk=rows_per_chunk, **opts))
    assert [len(c) for c in chunks[:-1]] == [rows_per_chunk] * (len(chunks) - 1)
    assert [c.start_row for c in chunks] == list(range(0, 11, rows_per_chunk))
    for name in ("time", "x", "label", "id"):
        got = np.concatenate([c.table[name] for c in chunks])
        assert_array_equal(got, whole[name])
        assert got.dtype.kind == whole[name].dtype.kind
    # line 1 is the header; a blank line follows the row of i == 4 (line 6)
    assert_array_equal(np.concatenate([c.lines for c in chunks]), [2, 3, 4, 5, 6] + list(range(8, 14)))


@pytest.mark.parametrize(("text", "match"), [
    ("", "file is empty"),
    ("time,x\n", "no data rows"),
    ("time\n1\n", "missing required column"),
    ("time,x\n1,2\n2,nan\n", "line 3, column 'x': value is nan"),
    ("time,x\n1,2\n2,1e308\n", "beyond"),
    ("time,x\n1,2\n2\n", "line 3 has 1 fields"),
    ("time,x\n1,\"" + "a" * 140_000 + "\"\n", "field is longer"),
])
def test_bad_input_same_message_as_the_whole_file_reader(tmp_path, text, match):
    """iter_table refuses bad input with read_table's message, whatever the chunk size."""
    p = _write(tmp_path, text)
    with pytest.raises(ValueError, match=match) as whole:
        read_table(p, required=("time", "x"))
    with pytest.raises(ValueError) as chunked:
        for _ in iter_table(p, required=("time", "x"), rows_per_chunk=1):
            pass
    assert str(chunked.value) == str(whole.value)


def test_bad_cell_late_in_the_file_is_found_after_earlier_chunks(tmp_path):
    """A bad cell in the last chunk raises only after the earlier chunks were handed out."""
    p = _write(tmp_path, "time,x\n" + "".join(f"{i},1\n" for i in range(10)) + "10,inf\n")
    seen = []
    with pytest.raises(ValueError, match="line 12, column 'x': value is inf"):
        for c in iter_table(p, required=("time", "x"), rows_per_chunk=4):
            seen.append(len(c))
    assert seen == [4, 4]


def test_missing_file_and_folder_refused_at_the_call(tmp_path):
    """A missing file or a folder is refused when iter_table is called, before iterating."""
    with pytest.raises(FileNotFoundError, match="no such file"):
        iter_table(tmp_path / "nope.csv", required=("time",))
    with pytest.raises(ValueError, match="is a directory"):
        iter_table(tmp_path, required=("time",))
    with pytest.raises(ValueError, match="rows_per_chunk"):
        iter_table(_write(tmp_path, "time\n1\n"), required=("time",), rows_per_chunk=0)


@pytest.mark.parametrize(("rows", "line"), [
    ([(0, 0, 1), (1, 0, 1), (0, 10, 1), (1, 10, 1), (0, 5, 1)], 6),  # 2nd chunk, track 0 back
    ([(0, 0, 1), (0, 10, 1), (0, 10, 2)], 4),  # repeat across the boundary after 2 rows
    ([(0, 0, 1), (1, 30, 1), (1, 20, 1)], 4),  # track 1 goes back on the next row
])
def test_order_checked_across_chunk_boundaries(tmp_path, rows, line):
    """A row out of order or repeated is caught at its line even across a chunk boundary."""
    p = _write(tmp_path, _bearings_text(rows))
    for n in (1, 2, 3, 100):
        with pytest.raises(RowOrderError, match=f"line {line}: time"):
            list(iter_bearings(p, rows_per_chunk=n))


def test_interleaved_tracks_and_unknown_origin_repeats_pass(tmp_path):
    """Interleaved tracks in time order, and track -1 rows sharing times, read in any chunks."""
    rows = [(0, 0, 1), (-1, 0, 5), (-1, 0, 6), (1, 0, 2), (1, 10, 2), (-1, 10, 7), (0, 10, 1),
            (-1, 10, 8)]
    p = _write(tmp_path, _bearings_text(rows))
    for n in (1, 2, 5):
        got = np.concatenate([c.table["time"] for c in iter_bearings(p, rows_per_chunk=n)])
        assert_array_equal(got, [r[1] for r in rows])


def test_detections_share_events_but_not_go_back(tmp_path):
    """Detections may share an event across chunks; an earlier event after a later one is refused."""
    ok = _write(tmp_path, "event,time,x,y,score\n0,0,1,1,0.5\n0,0,2,2,0.9\n1,60,1,1,0.1\n")
    assert sum(len(c) for c in iter_detections(ok, rows_per_chunk=1)) == 3
    back = _write(tmp_path, "event,time,x,y\n0,0,1,1\n2,60,1,1\n1,60,2,2\n", "b.csv")
    with pytest.raises(RowOrderError, match="line 4: event 1 is before"):
        list(iter_detections(back, rows_per_chunk=2))
    bad = _write(tmp_path, "event,time,x,y,score\n0,0,1,1,0.5\n1,0,1,1,1.5\n", "s.csv")
    with pytest.raises(ValueError, match="'score' must lie in"):
        list(iter_detections(bad, rows_per_chunk=1))


def test_negative_amplitude_has_the_whole_file_message(tmp_path):
    """A negative amplitude is refused by the chunked reader with read_amplitudes' message."""
    p = _write(tmp_path, "track_id,time,amplitude,residual\n0,0,1,0\n0,1,-2,0\n")
    with pytest.raises(ValueError) as whole:
        read_amplitudes(p)
    with pytest.raises(ValueError) as chunked:
        list(iter_amplitudes(p, rows_per_chunk=1))
    assert str(chunked.value) == str(whole.value)


@_SETTINGS
@given(rows=st.lists(st.tuples(st.integers(-1, 2), st.integers(0, 6)), min_size=1, max_size=14),
       n=st.integers(1, 5))
def test_row_order_error_iff_whole_file_reader_sorts_or_refuses(tmp_path, caplog, rows, n):
    """Cross-check: chunked bearings fail on order exactly when read_bearings sorts or refuses."""
    p = _write(tmp_path, _bearings_text([(k, t, 1.0) for k, t in rows]))
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="fusion.io"):
        try:
            read_bearings(p)
            whole_ok = not any("not in time order" in r.getMessage() for r in caplog.records)
        except ValueError:
            whole_ok = False
    try:
        got = [c.table for c in iter_bearings(p, rows_per_chunk=n)]
        chunked_ok = True
    except RowOrderError:
        chunked_ok = False
    assert chunked_ok == whole_ok
    if chunked_ok:
        assert_array_equal(np.concatenate([t["track_id"] for t in got]), [k for k, _ in rows])


@_SETTINGS
@given(text=st.text(alphabet="0123456789.,-e\nnax ", max_size=60), n=st.integers(1, 4))
def test_iter_table_agrees_with_read_table_on_any_text(tmp_path, text, n):
    """On arbitrary CSV-like text, iter_table gives read_table's rows or raises ValueError."""
    p = _write(tmp_path, "a,b\n" + text)
    try:
        whole = read_table(p, required=("a", "b"))
    except ValueError:
        whole = None
    try:
        chunks = list(iter_table(p, required=("a", "b"), rows_per_chunk=n))
    except ValueError:
        chunks = None
    assert (whole is None) == (chunks is None)
    if whole is not None:
        assert_array_equal(np.concatenate([c.table["b"] for c in chunks]), whole["b"])


def test_chunked_writer_writes_the_bytes_of_write_table(tmp_path):
    """write_table_chunks gives the same bytes as write_table on the concatenated columns."""
    rng = np.random.default_rng(3)
    cols = {"track_id": np.arange(9) // 4, "time": rng.normal(size=9) * 1e3,
            "big": np.array([1e20, -1e300, 0.5] * 3), "tqi": np.array(["lost", "strong", ""] * 3),
            "flag": np.arange(9) % 2 == 0}
    write_table(tmp_path / "a.csv", cols)
    parts = [{k: v[i:i + 4] for k, v in cols.items()} for i in (0, 4, 8)]
    write_table_chunks(tmp_path / "b.csv", iter(parts), header=list(cols))
    assert (tmp_path / "b.csv").read_bytes() == (tmp_path / "a.csv").read_bytes()


def test_chunked_writer_leaves_no_partial_output(tmp_path):
    """An error raised by a later chunk leaves an existing output untouched and no temporary."""
    out = tmp_path / "out.csv"
    out.write_text("old\n")

    def chunks():
        yield {"x": np.arange(3)}
        raise ValueError("bad row late in the input")

    with pytest.raises(ValueError, match="bad row late"):
        write_table_chunks(out, chunks(), header=["x"])
    assert out.read_text() == "old\n"
    assert sorted(q.name for q in tmp_path.iterdir()) == ["out.csv"]
    with pytest.raises(ValueError, match="expected"):
        write_table_chunks(out, iter([{"y": np.arange(2)}]), header=["x"])
    assert out.read_text() == "old\n"


@_SETTINGS
@given(values=st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=1, max_size=20),
       ints=st.lists(st.integers(-(2**62), 2**62), min_size=1, max_size=20))
def test_columns_written_as_cell_by_cell(tmp_path, values, ints):
    """Column-wise formatting writes each cell exactly as the cell formatter does."""
    from fusion.io.tables import _format_cell

    n = min(len(values), len(ints))
    cols = {"f": np.array(values[:n]), "f32": np.clip(values[:n], -3e38, 3e38).astype(np.float32),
            "i": np.array(ints[:n], dtype=np.int64), "b": np.arange(n) % 3 == 0,
            "s": np.array([f"x{i}" for i in range(n)]), "o": np.array(values[:n], dtype=object)}
    write_table(tmp_path / "t.csv", cols, float_format="%.4f")
    expected = ",".join(cols) + "\n" + "".join(
        ",".join(_format_cell(v[i], "%.4f") for v in cols.values()) + "\n" for i in range(n))
    assert (tmp_path / "t.csv").read_text() == expected


@_SETTINGS
@given(content=st.binary(max_size=400), n=st.integers(1, 4),
       kind=st.sampled_from(["bearings", "amplitudes", "detections"]))
def test_chunked_readers_random_bytes(tmp_path, content, n, kind):
    """Chunked readers on random bytes (after a valid header): rows or ValueError, nothing else."""
    header = {"bearings": b"track_id,time,bearing_deg\n",
              "amplitudes": b"track_id,time,amplitude,residual\n",
              "detections": b"event,time,x,y,score\n"}[kind]
    reader = {"bearings": iter_bearings, "amplitudes": iter_amplitudes,
              "detections": iter_detections}[kind]
    p = tmp_path / "r.csv"
    p.write_bytes(header + content)
    try:
        rows = sum(len(c) for c in reader(p, rows_per_chunk=n))
    except ValueError:
        return
    assert rows >= 1
