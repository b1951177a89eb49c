"""Tests of fusion.io: validation of every reader, round trips, atomic writes."""

import json
import logging

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from fusion.geometry import SensorArray
from fusion.io import (
    Cube,
    LocalizationResult,
    LocalizationWindow,
    SourceEstimate,
    TdoaRecord,
    atomic_output,
    iter_audio_blocks,
    read_alerts,
    read_amplitudes,
    read_array,
    read_audio,
    read_bearings,
    read_cube,
    read_detections,
    read_json,
    read_localization,
    read_ownship,
    read_smoothed,
    read_table,
    read_tma_bearings,
    read_tma_result,
    read_tqi,
    read_tracks,
    write_array,
    write_audio,
    write_cube,
    write_json,
    write_localization,
    write_table,
)

READERS = {
    "bearings": (read_bearings, "track_id,time,bearing_deg\n1,0,10\n1,10,11\n"),
    "amplitudes": (read_amplitudes, "track_id,time,amplitude,residual\n1,0,3.2,0.1\n1,1,2.5,-0.2\n"),
    "detections": (read_detections, "event,time,x,y\n0,0,10,20\n1,60,11,21\n"),
    "ownship": (read_ownship, "time,x,y\n0,0,0\n10,5,0\n"),
    "tma_bearings": (read_tma_bearings, "time,bearing_deg\n0,45\n10,46\n"),
}


def _write(tmp_path, text, name="t.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("kind", sorted(READERS))
def test_reader_accepts_valid_file(tmp_path, kind):
    """Each reader reads its minimal valid file with the right row count."""
    reader, text = READERS[kind]
    t = reader(_write(tmp_path, text))
    assert len(t) == 2


@pytest.mark.parametrize("kind", sorted(READERS))
def test_reader_missing_file(tmp_path, kind):
    """A missing file names the path."""
    with pytest.raises(FileNotFoundError, match="nope.csv: no such file"):
        READERS[kind][0](tmp_path / "nope.csv")


@pytest.mark.parametrize("kind", sorted(READERS))
def test_reader_empty_file(tmp_path, kind):
    """An empty file is an error naming the file."""
    p = _write(tmp_path, "")
    with pytest.raises(ValueError, match=r"t\.csv: file is empty"):
        READERS[kind][0](p)


@pytest.mark.parametrize("kind", sorted(READERS))
def test_reader_header_only(tmp_path, kind):
    """A header with no rows is an error."""
    header = READERS[kind][1].splitlines()[0]
    with pytest.raises(ValueError, match="no data rows"):
        READERS[kind][0](_write(tmp_path, header + "\n"))


@pytest.mark.parametrize("kind", sorted(READERS))
def test_reader_missing_column(tmp_path, kind):
    """Dropping the last required column is reported by name."""
    reader, text = READERS[kind]
    lines = [",".join(line.split(",")[:-1]) for line in text.splitlines()]
    missing = text.splitlines()[0].split(",")[-1]
    with pytest.raises(ValueError, match=f"missing required column.*{missing}"):
        reader(_write(tmp_path, "\n".join(lines) + "\n"))


@pytest.mark.parametrize("kind", sorted(READERS))
@pytest.mark.parametrize("bad", ["abc", "nan", "inf", ""])
def test_reader_bad_value(tmp_path, kind, bad):
    """Non-numeric values, NaN and infinities are rejected with line and column."""
    reader, text = READERS[kind]
    lines = text.splitlines()
    cells = lines[2].split(",")
    cells[-1] = bad
    lines[2] = ",".join(cells)
    with pytest.raises(ValueError, match="line 3, column"):
        reader(_write(tmp_path, "\n".join(lines) + "\n"))


def test_read_table_extra_columns_and_optional(tmp_path):
    """Extra columns are ignored; optional columns are kept only when present."""
    p = _write(tmp_path, "event,time,x,y,junk,score\n0,0,1,2,zz,0.5\n")
    t = read_detections(p)
    assert "junk" not in t and "score" in t and "snr_db" not in t
    assert_allclose(t["score"], [0.5])
    assert t["event"].dtype == np.int64


def test_read_table_ragged_and_integer(tmp_path):
    """Short rows and fractional integers are errors."""
    with pytest.raises(ValueError, match="line 2 has 2 fields"):
        read_bearings(_write(tmp_path, "track_id,time,bearing_deg\n1,0\n"))
    with pytest.raises(ValueError, match="not a whole number"):
        read_bearings(_write(tmp_path, "track_id,time,bearing_deg\n1.5,0,3\n"))


def test_semantic_checks(tmp_path):
    """Scores outside [0, 1], negative amplitudes and repeated own-ship times are errors."""
    with pytest.raises(ValueError, match="score"):
        read_detections(_write(tmp_path, "event,time,x,y,score\n0,0,1,2,1.5\n"))
    with pytest.raises(ValueError, match="negative"):
        read_amplitudes(_write(tmp_path, "track_id,time,amplitude,residual\n1,0,-1,0\n"))
    with pytest.raises(ValueError, match="two rows at time 1; times must be distinct"):
        read_ownship(_write(tmp_path, "time,x,y\n1,0,0\n1,5,0\n"))


def test_out_of_order_rows_are_sorted_once(tmp_path, caplog):
    """Rows out of time order are stably sorted, with one warning naming the file."""
    with caplog.at_level(logging.WARNING, logger="fusion.io"):
        o = read_ownship(_write(tmp_path, "time,x,y\n1,10,0\n0,0,0\n2,20,0\n"))
        d = read_detections(_write(tmp_path, "event,time,x,y\n2,0,1,2\n1,0,3,4\n1,0,5,6\n",
                                   "d.csv"))
    assert_array_equal(o["time"], [0, 1, 2])
    assert_array_equal(o["x"], [0, 10, 20])
    assert_array_equal(d["event"], [1, 1, 2])
    assert_array_equal(d["x"], [3, 5, 1])  # stable: the two event-1 rows keep their order
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 2 and "t.csv" in messages[0] and "d.csv" in messages[1]


def test_binary_file_is_not_csv(tmp_path):
    """A binary file is reported, not decoded into garbage."""
    p = tmp_path / "b.csv"
    p.write_bytes(b"\xff\xfe\x00\x81\x82")
    with pytest.raises(ValueError, match="b.csv"):
        read_bearings(p)


def test_table_round_trip(tmp_path):
    """write_table then read_table returns the same numbers and strings."""
    rng = np.random.default_rng(0)
    cols = {"track_id": np.arange(5), "time": rng.uniform(0, 100, 5), "bearing_deg": rng.uniform(0, 360, 5),
            "kind": np.array(["a", "b", "a", "c", "b"])}
    p = write_table(tmp_path / "o.csv", cols, float_format="%.10f")
    t = read_table(p, required=("track_id", "time", "bearing_deg", "kind"), integer=("track_id",),
                   text=("kind",))
    assert_array_equal(t["track_id"], cols["track_id"])
    assert_allclose(t["time"], cols["time"], atol=1e-9)
    assert_array_equal(t["kind"], cols["kind"])


def test_atomic_output_leaves_nothing_on_failure(tmp_path):
    """An exception inside atomic_output leaves neither the file nor a temporary behind."""
    dest = tmp_path / "out.csv"
    with pytest.raises(RuntimeError), atomic_output(dest) as tmp:
        tmp.write_text("half")
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="different lengths"):
        write_table(dest, {"a": [1, 2], "b": [1]})
    assert not dest.exists()


def _array_doc(**over):
    doc = {"sound_speed": 1500.0, "sensors": [
        {"id": "H1", "x": 0.0, "y": 0.0, "z": -1500.0},
        {"id": "H2", "x": 3200.0, "y": 150.0, "z": -1610.0},
        {"id": "H3", "x": 900.0, "y": 2800.0, "z": -1550.0}]}
    doc.update(over)
    return doc


def test_array_round_trip(tmp_path):
    """write_array then read_array gives the same array."""
    a = SensorArray(np.array([[0, 0, -1500], [3200, 150, -1610], [900, 2800, -1550.0]]), 1490.0,
                    ("A", "B", "C"))
    b = read_array(write_array(tmp_path / "array.json", a))
    assert b.ids == a.ids and b.sound_speed == a.sound_speed
    assert_allclose(b.positions, a.positions)


@pytest.mark.parametrize(
    ("doc", "match"),
    [
        ({"sensors": []}, "non-empty"),
        ({"sensors": _array_doc()["sensors"][:2]}, "at least 3"),
        ({"sensors": [{"x": 0, "y": 0, "z": 0}, {"x": 1, "y": 1, "z": 1}, {"x": 2, "y": 2, "z": 2}]},
         "collinear"),
        ({"sensors": [{"x": 0, "y": 0}] * 3}, "no 'z'"),
        ({"sensors": [{"x": "a", "y": 0, "z": 0}] * 3}, "not a finite number"),
        ({"sound_speed": -3}, "sound_speed"),
    ],
)
def test_array_bad_input(tmp_path, doc, match):
    """Every malformed array file gives a message naming the file and the problem."""
    p = tmp_path / "array.json"
    p.write_text(json.dumps(_array_doc(**doc)))
    with pytest.raises(ValueError, match=match):
        read_array(p)


def test_array_nan_and_malformed_json(tmp_path):
    """NaN coordinates and broken JSON are errors."""
    p = tmp_path / "array.json"
    p.write_text(json.dumps(_array_doc()).replace("3200.0", "NaN"))
    with pytest.raises(ValueError, match="not a finite number"):
        read_array(p)
    p.write_text("{\"sensors\": [")
    with pytest.raises(ValueError, match="malformed JSON"):
        read_array(p)
    p.write_text("")
    with pytest.raises(ValueError, match="empty"):
        read_json(p)


@pytest.mark.parametrize("suffix", [".wav", ".flac"])
def test_audio_round_trip_and_channels(tmp_path, suffix):
    """Audio round-trips within 24-bit quantisation; a channel mismatch is an error."""
    rng = np.random.default_rng(1)
    x = rng.uniform(-0.5, 0.5, (4000, 3))
    p = write_audio(tmp_path / f"a{suffix}", x, 96000)
    y, fs = read_audio(p, n_channels=3)
    assert fs == 96000 and y.shape == x.shape
    assert_allclose(y, x, atol=2 ** -22)
    with pytest.raises(ValueError, match="3 channel.*array has 4 sensors"):
        read_audio(p, n_channels=4)


def test_audio_bad_input(tmp_path):
    """Not-audio files, wrong suffixes and NaN samples are errors."""
    p = tmp_path / "x.wav"
    p.write_text("not audio")
    with pytest.raises(ValueError, match="not a readable"):
        read_audio(p)
    with pytest.raises(ValueError, match=".wav or .flac"):
        write_audio(tmp_path / "x.mp3", np.zeros((10, 1)), 1000)
    with pytest.raises(ValueError, match="NaN"):
        write_audio(tmp_path / "y.wav", np.full((10, 1), np.nan), 1000)
    assert not (tmp_path / "y.wav").exists()


def test_audio_blocks_cover_recording(tmp_path):
    """Windowed reading yields windows at the hop whose samples match the whole file."""
    rng = np.random.default_rng(2)
    x = rng.uniform(-0.5, 0.5, (10000, 3))
    p = write_audio(tmp_path / "a.wav", x, 1000)
    whole, _ = read_audio(p)
    starts = []
    for t0, block, fs in iter_audio_blocks(p, block_s=3.0, hop_s=2.0, n_channels=3):
        i0 = int(round(t0 * fs))
        assert_allclose(block, whole[i0 : i0 + len(block)])
        starts.append(t0)
    assert starts[:3] == [0.0, 2.0, 4.0]


def _cube(**over):
    rng = np.random.default_rng(0)
    kw = {"power": rng.exponential(1.0, (6, 8, 4)), "freqs": np.array([100.0, 101, 102, 103]),
          "scan_period": 10.0, "aperture": 30.0, "sound_speed": 1500.0}
    kw.update(over)
    return kw


def test_cube_round_trip(tmp_path):
    """write_cube then read_cube gives the same arrays and scalars."""
    c = Cube(**_cube())
    d = read_cube(write_cube(tmp_path / "c.npz", c))
    assert_allclose(d.power, c.power)
    assert (d.n_scans, d.n_beams, d.n_bins) == (6, 8, 4)
    assert d.scan_period == 10.0 and d.aperture == 30.0


@pytest.mark.parametrize(
    ("over", "match"),
    [
        ({"power": np.ones((6, 8))}, "shape"),
        ({"freqs": np.array([1.0, 2.0])}, "frequencies"),
        ({"power": np.full((6, 8, 4), np.nan)}, "NaN"),
        ({"scan_period": 0.0}, "scan_period"),
        ({"freqs": np.array([4.0, 3, 2, 1])}, "increasing"),
    ],
)
def test_cube_bad_input(tmp_path, over, match):
    """Malformed cubes are rejected with a message naming the file."""
    p = tmp_path / "c.npz"
    np.savez(p, **_cube(**over))
    with pytest.raises(ValueError, match=match):
        read_cube(p)


def test_cube_missing_array_and_not_npz(tmp_path):
    """A cube without 'power', or not an npz at all, is an error."""
    p = tmp_path / "c.npz"
    kw = _cube()
    del kw["power"]
    np.savez(p, **kw)
    with pytest.raises(ValueError, match="missing array.*power"):
        read_cube(p)
    p.write_text("nope")
    with pytest.raises(ValueError, match="c.npz: not a valid .npz file"):
        read_cube(p)


def test_json_round_trip_numpy(tmp_path):
    """numpy scalars and arrays serialise; NaN is refused rather than written as invalid JSON."""
    p = write_json(tmp_path / "r.json", {"a": np.float64(1.5), "b": np.arange(3), "c": np.int64(2)})
    assert read_json(p) == {"a": 1.5, "b": [0, 1, 2], "c": 2}
    with pytest.raises(ValueError):
        write_json(tmp_path / "n.json", {"a": float("nan")})
    assert not (tmp_path / "n.json").exists()


OUTPUT_READERS = {
    "tqi": (read_tqi, "track_id,time,amplitude,residual,tqi\n1,0,3,0.1,strong\n", "tqi", "great"),
    "tracks": (read_tracks, "track_id,event,time,x,y,vx,vy,status\n0,1,60,1,2,0.1,0.2,confirmed\n",
               "status", "maybe"),
    "alerts": (read_alerts, "time,track_a,track_b,t_cross,kind\n100,1,2,130,predicted\n", "kind", "soon"),
}


@pytest.mark.parametrize("kind", sorted(OUTPUT_READERS))
def test_output_readers_check_categories(tmp_path, kind):
    """Output CSVs read back; an unknown category value is named in the error."""
    reader, text, col, bad = OUTPUT_READERS[kind]
    assert len(reader(_write(tmp_path, text))) == 1
    good = text.splitlines()[1].split(",")[-1]
    with pytest.raises(ValueError, match=f"column '{col}' has value.*{bad}"):
        reader(_write(tmp_path, text.replace(good, bad)))


def test_smoothed_and_tma_outputs(tmp_path):
    """The smooth and tma outputs read back with their required columns."""
    s = read_smoothed(_write(tmp_path, "track_id,time,bearing_deg,bearing_rate_deg_per_min,"
                                       "sigma_bearing_deg\n1,0,10,0.5,0.2\n"))
    assert s["bearing_rate_deg_per_min"][0] == 0.5
    with pytest.raises(ValueError, match="range"):
        read_tma_result(_write(tmp_path, "time,x,y,vx,vy,sigma_x,sigma_y\n0,1,2,3,4,5,6\n"))


def _localization():
    w = LocalizationWindow(
        0.0, 12.0,
        (TdoaRecord((0, 1), 0.4012, True, 5.2, 6.31, 1.2e-4), TdoaRecord((1, 2), -0.1, False, -3.0)),
        (SourceEstimate(10.0, -20.0, -900.0, ((1.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 0.0, 3.0)), 7),),
    )
    return LocalizationResult((w,), ((0, ((6.0, 10.0, -20.0, -900.0),)),))


def test_localization_round_trip(tmp_path):
    """A localization result survives write and read unchanged."""
    r = _localization()
    back = read_localization(write_localization(tmp_path / "r.json", r))
    assert back == r
    d = back.windows[0].tdoas[0]
    assert (d.t, d.rate) == (6.31, 1.2e-4)
    assert d.tau_at(8.31) == pytest.approx(0.4012 + 2.4e-4)
    assert np.isnan(back.windows[0].tdoas[1].t)  # a file without the fields (older results)


def test_localization_bad_input(tmp_path):
    """Missing keys, bad covariances and NaN positions are errors naming the file."""
    p = write_localization(tmp_path / "r.json", _localization())
    doc = json.loads(p.read_text())
    del doc["windows"][0]["tdoas"][0]["tau"]
    p.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="r.json: malformed localization result"):
        read_localization(p)
    doc = json.loads(write_localization(tmp_path / "r.json", _localization()).read_text())
    doc["windows"][0]["sources"][0]["cov"] = [[1, 0], [0, 1]]
    p.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="3x3"):
        read_localization(p)
    p.write_text(json.dumps({"windows": [{"t_start": None, "t_end": 1.0, "tdoas": [], "sources": []}]}))
    with pytest.raises(ValueError, match="not a finite number"):
        read_localization(p)


def test_written_files_have_usual_permissions(tmp_path):
    """Atomic writes give new files the permissions the umask allows, not mkstemp's private 0600."""
    import os

    umask = os.umask(0)
    os.umask(umask)
    p = write_json(tmp_path / "r.json", {"a": 1})
    assert (p.stat().st_mode & 0o777) == (0o666 & ~umask)


# --------------------------------------------------------------------------------------------
# bad input found while decoding, degenerate arrays, folders, huge numbers
# --------------------------------------------------------------------------------------------
def _flac(tmp_path, damage):
    """A 3-channel FLAC of 2 s, damaged by `damage(bytes) -> bytes`."""
    rng = np.random.default_rng(4)
    p = write_audio(tmp_path / "a.flac", rng.uniform(-0.5, 0.5, (16000, 3)), 8000)
    p.write_bytes(damage(p.read_bytes()))
    return p


def _truncate(b: bytes) -> bytes:
    return b[: len(b) // 2]


def _scramble(b: bytes) -> bytes:
    c = bytearray(b)
    i = len(c) // 3
    c[i : i + 4000] = bytes((x * 7 + 13) % 256 for x in c[i : i + 4000])
    return bytes(c)


@pytest.mark.parametrize("damage", [_truncate, _scramble], ids=["truncated", "corrupt"])
def test_damaged_flac_found_while_decoding(tmp_path, damage):
    """A FLAC whose header reads but whose frames do not: ValueError naming the file, both readers."""
    p = _flac(tmp_path, damage)
    import soundfile

    assert soundfile.info(str(p)).frames == 16000  # the header alone looks fine
    with pytest.raises(ValueError, match=r"a\.flac: audio is truncated or corrupt"):
        read_audio(p)
    with pytest.raises(ValueError, match=r"a\.flac: audio is truncated or corrupt near"):
        list(iter_audio_blocks(p, block_s=0.5, hop_s=0.25))


def test_audio_blocks_refuse_hops_that_skip_samples(tmp_path):
    """A hop longer than the window, or a window under one sample, is refused."""
    p = write_audio(tmp_path / "a.wav", np.zeros((1000, 1)), 1000)
    with pytest.raises(ValueError, match="would be skipped"):
        list(iter_audio_blocks(p, block_s=0.1, hop_s=0.2))
    with pytest.raises(ValueError, match="at least one sample"):
        list(iter_audio_blocks(p, block_s=1e-6, hop_s=1e-6))


def test_array_duplicate_positions(tmp_path):
    """Two sensors at one position: degenerate geometry, named by index and id."""
    sensors = _array_doc()["sensors"] + [{"id": "H4", "x": 3200.0, "y": 150.0, "z": -1610.0}]
    p = tmp_path / "array.json"
    p.write_text(json.dumps(_array_doc(sensors=sensors)))
    with pytest.raises(ValueError, match=r"array\.json: sensors 1 \(H2\) and 3 \(H4\) are at the "
                                         "same position"):
        read_array(p)


@pytest.mark.parametrize("reader", [read_json, read_array, read_audio, read_cube, read_bearings,
                                    read_localization])
def test_folder_given_as_a_file(tmp_path, reader):
    """Every reader given a folder says so in one message naming it."""
    d = tmp_path / "folder.json"
    d.mkdir()
    with pytest.raises(ValueError, match=r"folder\.json: is a directory, expected a file"):
        reader(d)


def test_json_not_utf8_and_too_deep(tmp_path):
    """Non-UTF-8 bytes and pathological nesting are ValueErrors naming the file."""
    p = tmp_path / "r.json"
    p.write_bytes(b'{"a": "\xff"}')
    with pytest.raises(ValueError, match="r.json: not a UTF-8"):
        read_json(p)
    p.write_text("[" * 100_000)
    with pytest.raises(ValueError, match="r.json: JSON nested too deeply"):
        read_json(p)


def test_huge_floats_written_exactly_not_as_300_digits(tmp_path):
    """write_table writes 1e308 as '1e+308' (exact, short), ordinary values in the given format."""
    p = write_table(tmp_path / "o.csv", {"v": [1e308, -2.5e20, 1.25, 123456789012.5]})
    assert p.read_text().splitlines() == ["v", "1e+308", "-2.5e+20", "1.250000",
                                          "123456789012.500000"]
    t = read_table(p, required=("v",), max_abs=None)
    assert_array_equal(t["v"], [1e308, -2.5e20, 1.25, 123456789012.5])
    with pytest.raises(ValueError, match=r"line 2, column 'v': '1e\+308' is beyond \+-1e\+12"):
        read_table(p, required=("v",))


def test_bom_crlf_and_blank_lines(tmp_path):
    """A byte-order mark, CRLF line ends and blank lines are fine; line numbers are physical."""
    p = tmp_path / "b.csv"
    p.write_bytes(b"\xef\xbb\xbftrack_id,time,bearing_deg\r\n\r\n1,0,10\r\n1,10,x\r\n")
    with pytest.raises(ValueError, match="line 4, column 'bearing_deg'"):
        read_bearings(p)
    p.write_bytes(b"\xef\xbb\xbftrack_id,time,bearing_deg\r\n\r\n1,0,10\r\n1,10,11\r\n")
    assert_allclose(read_bearings(p)["bearing_deg"], [10, 11])


def test_large_table_in_chunks(tmp_path):
    """A table longer than one parsing chunk reads back whole and in order."""
    n = 70_000
    p = tmp_path / "o.csv"
    p.write_text("time,x,y\n" + "".join(f"{i},{2 * i},0\n" for i in range(n)))
    t = read_ownship(p)
    assert len(t) == n and t["x"][-1] == 2 * (n - 1) and np.all(np.diff(t["time"]) == 1)
