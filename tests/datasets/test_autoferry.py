"""Tests of the Autoferry reader on a trimmed copy of real recordings."""

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.datasets.autoferry import Sensor, load_autoferry


@pytest.fixture
def rec(data_dir):
    return load_autoferry(data_dir / "autoferry_raw" / "scenario2")


def test_scans_sorted_and_frames(rec, data_dir):
    """Scan times start at 0 and increase; positions are converted from north/east to x east/y north."""
    assert rec.scan_time[0] == 0.0 and np.all(np.diff(rec.scan_time) >= 0)
    raw = json.loads((data_dir / "autoferry_raw/scenario2/scenario2_detections.json").read_text())
    order = np.argsort([s["time"] for s in raw], kind="stable")
    first = raw[order[0]]
    assert_allclose(rec.ownship_xy[0], first["ownshipPosition"][::-1])


def test_radar_positions_are_absolute(rec, data_dir):
    """Radar detections = ownship position + relative [north; east] measurement, as (x, y)."""
    raw = json.loads((data_dir / "autoferry_raw/scenario2/scenario2_detections.json").read_text())
    scan = next(s for s in sorted(raw, key=lambda s: s["time"]) if s["sensorID"] == Sensor.RADAR
                and s["measurement"])
    n, e = np.asarray(scan["measurement"], dtype=float)
    p = rec.positions((Sensor.RADAR,))
    first = p.select(p["event"] == 0)
    assert_allclose(first["x"], e + scan["ownshipPosition"][1])
    assert_allclose(first["y"], n + scan["ownshipPosition"][0])


def test_camera_bearings_follow_gnss(rec):
    """Camera bearings cluster on the GNSS targets' bearings far above chance (real data check).

    EO scans of this stretch carry many false alarms; IR bearings are cleaner. Chance of a random
    bearing within 3 deg of one of two targets is 2 * 6 / 360 = 3.3 %.
    """
    b = rec.bearings()
    tb = rec.true_bearings()
    assert len(b) > 50
    best = np.full(len(b), np.inf)
    for tid in np.unique(tb["track_id"]):
        m = tb["track_id"] == tid
        tt, ti = np.unique(tb["time"][m], return_index=True)
        truth = np.interp(b["time"], tt, np.unwrap(np.radians(tb["bearing_deg"][m][ti])))
        err = np.abs(np.degrees(np.angle(np.exp(1j * (np.radians(b["bearing_deg"]) - truth)))))
        best = np.minimum(best, err)
    assert np.mean(best < 3.0) > 0.2
    ir = b["sensor_id"] == Sensor.IR
    assert np.median(best[ir]) < 3.0
    assert np.all((b["bearing_deg"] >= 0) & (b["bearing_deg"] < 360))


def test_ownship_times_strictly_increase(rec):
    """The own-ship table has strictly increasing times (usable by TMA)."""
    o = rec.ownship()
    assert np.all(np.diff(o["time"]) > 0)


def test_missing_folder(tmp_path):
    """A missing folder or missing files are reported."""
    with pytest.raises(FileNotFoundError, match="no such folder"):
        load_autoferry(tmp_path / "nope")
    with pytest.raises(FileNotFoundError, match="detections"):
        load_autoferry(tmp_path)
