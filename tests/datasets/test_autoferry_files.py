"""Tests of ``fusion import autoferry`` on the trimmed copy of scenario 2 (120 scans)."""

import csv
import json
import shutil

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.datasets.autoferry_files import FILES, import_autoferry

RAW = "autoferry_raw/scenario2"


def read_table(path):
    """Every column of a written CSV as a float array (independent of fusion.io's readers)."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    names = rows[0].keys() if rows else []
    return {k: np.array([float(r[k]) for r in rows]) for k in names} | {"_n": len(rows)}


@pytest.fixture
def raw(data_dir):
    return json.loads((data_dir / RAW / "scenario2_detections.json").read_text())


@pytest.fixture
def imported(data_dir, tmp_path):
    out = tmp_path / "out"
    (imp,) = import_autoferry(data_dir / RAW, out)
    return imp, out


def test_row_counts_match_the_raw_scans(imported, raw):
    """Each file has one row per raw detection of its sensor (counted from the JSON directly)."""
    imp, out = imported
    count = {1: 0, 2: 0, 3: 0, 4: 0}
    for s in raw:
        n = np.asarray(s["measurement"], float).size
        count[s["sensorID"]] += n // 2 if s["sensorID"] in (1, 2) else n
    assert count == {1: 14, 2: 15, 3: 27, 4: 137}  # the trimmed copy's known content
    expect = {"lidar.csv": 14, "radar.csv": 15, "ir_bearings.csv": 27, "eo_bearings.csv": 137}
    for name, n in expect.items():
        assert imp.rows[name] == n
        assert read_table(out / name)["_n"] == n
    assert set(imp.rows) == set(FILES)
    # own-ship: one row per distinct scan time (120 scans)
    assert imp.rows["ownship.csv"] == len({s["time"] for s in raw})


def test_time_origin_is_the_earliest_scan(imported, raw):
    """t0 is the earliest scan time; every file is on that clock (first EO scan at its offset)."""
    imp, out = imported
    t0 = min(s["time"] for s in raw)
    assert imp.t0_unix == t0
    assert json.loads((out / "import.json").read_text())["t0_unix"] == t0
    own = read_table(out / "ownship.csv")
    assert own["time"][0] == 0.0
    first_eo = min(s["time"] for s in raw if s["sensorID"] == 4 and s["measurement"])
    eo = read_table(out / "eo_bearings.csv")
    assert_allclose(eo["time"].min(), first_eo - t0, atol=1e-6)
    truth = read_table(out / "truth.csv")
    assert abs(truth["time"].min()) < 1.0  # GNSS fixes on the same clock, within a second


def test_radar_coordinates_east_north(imported, raw):
    """First radar detection: x = ferry east + east offset, y = ferry north + north offset."""
    _, out = imported
    scan = next(s for s in sorted(raw, key=lambda s: s["time"]) if s["sensorID"] == 2
                and s["measurement"])
    n, e = np.asarray(scan["measurement"], float)
    own_n, own_e = scan["ownshipPosition"][:2]
    r = read_table(out / "radar.csv")
    first = r["event"] == r["event"].min()
    assert_allclose(r["x"][first], e + own_e, atol=1e-6)
    assert_allclose(r["y"][first], n + own_n, atol=1e-6)
    assert_allclose(r["own_x"][first], own_e, atol=1e-6)


def test_bearings_are_true_degrees(imported, raw):
    """EO bearings are the raw radians in degrees, wrapped to [0, 360), track_id -1."""
    _, out = imported
    scan = next(s for s in sorted(raw, key=lambda s: s["time"]) if s["sensorID"] == 4
                and s["measurement"])
    eo = read_table(out / "eo_bearings.csv")
    first = eo["time"] == eo["time"].min()
    expect = np.mod(np.degrees(np.atleast_1d(scan["measurement"])), 360.0)
    assert_allclose(eo["bearing_deg"][first], expect, atol=1e-6)
    assert np.all(eo["track_id"] == -1)
    assert np.all((eo["bearing_deg"] >= 0) & (eo["bearing_deg"] < 360))


def test_truth_bearings_agree_with_truth_positions(imported):
    """truth_bearings = atan2(dx, dy) from the own-ship to the GNSS position at the same time."""
    _, out = imported
    tb = read_table(out / "truth_bearings.csv")
    tr = read_table(out / "truth.csv")
    own = read_table(out / "ownship.csv")
    m = tb["track_id"] == 1
    t = tb["time"][m][5]
    sel = tr["track_id"] == 1
    x = np.interp(t, tr["time"][sel], tr["x"][sel])
    y = np.interp(t, tr["time"][sel], tr["y"][sel])
    ox, oy = np.interp(t, own["time"], own["x"]), np.interp(t, own["time"], own["y"])
    assert_allclose(tb["bearing_deg"][m][5], np.degrees(np.arctan2(x - ox, y - oy)) % 360,
                    atol=1e-4)
    assert_allclose(tb["range_m"][m][5], np.hypot(x - ox, y - oy), atol=1e-4)
    # each GNSS fix once
    pairs = np.column_stack([tr["track_id"], tr["time"]])
    assert np.unique(pairs, axis=0).shape[0] == tr["_n"]


def test_cli_import_and_errors(run_cli, data_dir, tmp_path):
    """The command writes the files; bad input is one line with exit code 2."""
    code, out, err = run_cli("import", "autoferry", data_dir / RAW, "--out", tmp_path / "o")
    assert code == 0, err
    assert "scenario2: t0" in out and "radar 15" in out
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == sorted([*FILES, "import.json"])
    code, _, err = run_cli("import", "autoferry", tmp_path / "missing", "--out", tmp_path / "p")
    assert code == 2 and len(err.strip().splitlines()) == 1
    bad = tmp_path / "bad"
    shutil.copytree(data_dir / RAW, bad)
    det = json.loads((bad / "scenario2_detections.json").read_text())
    del det[3]["measurement"]
    (bad / "scenario2_detections.json").write_text(json.dumps(det))
    code, _, err = run_cli("import", "autoferry", bad, "--out", tmp_path / "q")
    assert code == 2 and "malformed" in err and len(err.strip().splitlines()) == 1
    code, _, err = run_cli("import", "autoferry", bad, "--out", bad / "inside")
    assert code == 2 and "inside the input folder" in err
