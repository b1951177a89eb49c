"""Tests of ``fusion passive``: files in, tracks and alerts out, bad input refused."""

from __future__ import annotations

import numpy as np
import pytest

from fusion.io import Cube, read_alerts, read_table, write_cube, write_table
from fusion.simulate.passive import LineTarget, simulate_passive

TARGETS = (LineTarget(70.0, 8.0, 300.1, 10.0), LineTarget(110.0, -8.0, 300.1, 9.0))


@pytest.fixture(scope="module")
def cubes(tmp_path_factory):
    """A 200-scan crossing scenario written as two consecutive cubes, and its clicks."""
    sc = simulate_passive(seed=1, targets=TARGETS, n_scans=200, n_bins=16)
    d = tmp_path_factory.mktemp("passive")
    c = sc.cube
    paths = []
    for i, part in enumerate((slice(0, 120), slice(120, 200))):
        paths.append(write_cube(d / f"cube{i}.npz", Cube(
            power=c.power[part], freqs=c.freqs, scan_period=c.scan_period, aperture=c.aperture,
            sound_speed=c.sound_speed)))
    clicks = write_table(d / "clicks.csv", {
        "beam": np.array([b for b, _, _ in sc.clicks], np.int64),
        "freq": np.array([f for _, f, _ in sc.clicks]),
        "time": np.array([t for _, _, t in sc.clicks])})
    return sc, paths, clicks


def test_two_cubes_and_a_clicks_file(run_cli, cubes, tmp_path):
    """Consecutive cubes are one recording: tracks run to the end of the second cube, on truth."""
    sc, paths, clicks = cubes
    code, out, err = run_cli("passive", "--cube", paths[0], "--cube", paths[1], "--clicks", clicks,
                             "--out", tmp_path)
    assert code == 0, err
    assert "2 track(s)" in out
    tracks = read_table(tmp_path / "tracks.csv",
                        required=("track_id", "time", "bearing_deg", "bearing_rate_deg_per_min",
                                  "sigma_bearing_deg"), optional=("tqi",),
                        integer=("track_id",), text=("tqi",))
    for i in (0, 1):
        rows = tracks["track_id"] == i
        t = tracks["time"][rows]
        assert t[0] == 59.0 and t[-1] == 199.0
        err_deg = tracks["bearing_deg"][rows] - sc.bearing_deg[t.astype(int), i]
        assert np.sqrt(np.mean(err_deg**2)) < 1.0
    alerts = read_alerts(tmp_path / "alerts.csv")
    assert "predicted" in set(alerts["kind"])


def test_click_option_equals_clicks_file(run_cli, cubes, tmp_path):
    """--click BEAM,FREQ,TIME gives the same tracks as the clicks file."""
    sc, paths, clicks = cubes
    argv = []
    for b, f, t in sc.clicks:
        argv += ["--click", f"{b},{f},{t}"]
    assert run_cli("passive", "--cube", paths[0], *argv, "--out", tmp_path / "a")[0] == 0
    assert run_cli("passive", "--cube", paths[0], "--clicks", clicks, "--out", tmp_path / "b")[0] == 0
    a = (tmp_path / "a" / "tracks.csv").read_text()
    assert a == (tmp_path / "b" / "tracks.csv").read_text() and a.count("\n") > 100


@pytest.mark.parametrize(("extra", "mention"), [
    (["--click", "3"], "BEAM,FREQ"),
    (["--click", "999,300"], "outside the beams"),
    (["--click", "3,300", "--auto"], "not allowed with"),
    (["--click", "3,300", "--snr0-db", "12"], "--snr1-db"),
])
def test_bad_options(run_cli, cubes, tmp_path, extra, mention):
    """Bad clicks and options: exit 2, one line naming the problem, no output written."""
    _, paths, _ = cubes
    code, _, err = run_cli("passive", "--cube", paths[0], *extra, "--out", tmp_path / "o")
    assert code == 2
    assert mention in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o" / "tracks.csv").exists()
