"""Plausibility limits where an input value sizes memory or a grid (docs/bad-input.md).

Each is one stderr line naming the file (or the option), exit 2, nothing written -- instead of
a ZeroDivisionError, an OverflowError, terabytes of allocation or hours of empty pings.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from fusion.cli import EXIT_BAD_INPUT


def _one_line_exit_2(run_cli, *argv, words=()) -> str:
    code, _, err = run_cli(*argv)
    assert code == EXIT_BAD_INPUT, (code, err)
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err


def _array(path: Path, c: float) -> Path:
    sensors = [{"x": 0, "y": 0, "z": -1}, {"x": 10, "y": 0, "z": -1}, {"x": 0, "y": 10, "z": -1},
               {"x": 0, "y": 0, "z": -11}]
    path.write_text(json.dumps({"sound_speed": c, "sensors": sensors}))
    return path


@pytest.mark.parametrize("c", [1e308, 1e-12, 343.0, 999.0, 2001.0])
def test_implausible_sound_speed_in_array_is_refused(tmp_path, c):
    from fusion.io import read_array

    with pytest.raises(ValueError, match=r"a\.json: 'sound_speed' = .* outside the plausible "
                                         r"range 1000\.\.2000 m/s"):
        read_array(_array(tmp_path / "a.json", c))


@pytest.mark.parametrize("c", [1000.0, 1480.0, 2000.0])
def test_plausible_sound_speed_is_read(tmp_path, c):
    from fusion.io import read_array

    assert read_array(_array(tmp_path / "a.json", c)).sound_speed == c


@pytest.fixture(scope="module")
def cube(tmp_path_factory) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {"power": rng.exponential(size=(80, 16, 8)), "freqs": 100.0 + np.arange(8.0),
            "scan_period": np.array(1.0), "aperture": np.array(50.0),
            "sound_speed": np.array(1500.0)}


@pytest.mark.parametrize(("key", "value"), [("scan_period", 1e308), ("scan_period", 1e-9),
                                            ("aperture", 5e-324), ("aperture", 1e9),
                                            ("sound_speed", 1e308), ("sound_speed", 1e-12)])
@pytest.mark.parametrize("command", ["acquire", "passive"])
def test_implausible_cube_scalars_are_refused(run_cli, tmp_path, cube, key, value, command):
    """scan_period=1e308 was a ZeroDivisionError, aperture=5e-324 an OverflowError."""
    d = dict(cube)
    d[key] = np.array(value)
    p = tmp_path / "c.npz"
    np.savez(p, **d)
    argv = (["acquire", "--cube", p, "--beam", 3, "--freq-hz", 102] if command == "acquire" else
            ["passive", "--cube", p, "--auto", "--out", tmp_path / "o", "--quiet"])
    _one_line_exit_2(run_cli, *argv, words=("c.npz", key, "plausible range"))
    assert not (tmp_path / "o").exists()


def test_window_beyond_the_click_map_limit_is_refused():
    from fusion.clicks.scm import ScmConfig

    with pytest.raises(ValueError, match="longer than the 699 s a smoothed click map may span"):
        ScmConfig(window_s=1e9)
    assert ScmConfig(window_s=600.0).n_samples == 1_800_000


def test_localize_window_1e9_is_refused(run_cli, tmp_path):
    from fusion.io import write_audio

    audio = write_audio(tmp_path / "a.wav", np.zeros((96000, 4)), 96000.0)
    _one_line_exit_2(run_cli, "localize", "--audio", audio, "--array",
                     _array(tmp_path / "a.json", 1500.0), "--out", tmp_path / "l.json",
                     "--window-s", "1e9", "--hop-s", 1, "--quiet", words=("1e+09 s", "shorter window"))
    assert not (tmp_path / "l.json").exists()


def _bearings(path: Path, extra: list[tuple[int, float, float]]) -> Path:
    rows = [(k, 10.0 * i, b0 + r * i) for i in range(30)
            for k, (b0, r) in enumerate(((40.0, 1.0), (70.0, -1.0)))]
    rows = [*extra, *rows] if extra and extra[0][1] < 0 else [*rows, *extra]
    path.write_text("track_id,time,bearing_deg\n" + "".join(f"{k},{t!r},{b}\n" for k, t, b in rows))
    return path


@pytest.mark.parametrize(("command", "time"), [("crossings", -1e12),
                                               ("smooth", 9e11), ("smooth", -1e12)])
def test_time_far_from_the_data_is_refused(run_cli, tmp_path, command, time):
    src = _bearings(tmp_path / "b.csv", [(0, time, 50.0)])
    err = _one_line_exit_2(run_cli, command, "--bearings", src, "--out", tmp_path / "o.csv",
                           words=("b.csv", "more than 10,000,000", "implausible"))
    assert "track" in err
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("time", [-1e12, 9e11])
def test_time_far_from_the_data_out_of_time_order_is_refused_by_crossings(run_cli, tmp_path,
                                                                           time):
    """The far row out of time order (crossings then reads the whole file instead of streaming
    it): the same one line (was: a MemoryError traceback, 671-745 GiB; found by the property
    test)."""
    rows = _bearings(tmp_path / "b.csv", []).read_text().splitlines()
    rows.insert(5, f"0,{time!r},50.0")
    (tmp_path / "b.csv").write_text("\n".join(rows) + "\n")
    err = _one_line_exit_2(run_cli, "crossings", "--bearings", tmp_path / "b.csv", "--out",
                           tmp_path / "o.csv", words=("b.csv", "more than 10,000,000", "track 0"))
    assert "Traceback" not in err
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("event", [1_000_000_000_000, 100_000_000, 200_000])
def test_event_id_far_past_the_others_is_refused(run_cli, tmp_path, event):
    rows = [(e, 10.0 * e, 100.0 * k, 50.0 * e) for e in range(20) for k in range(3)]
    rows.append((event, 10.0 * 21, 0.0, 0.0))
    src = tmp_path / "d.csv"
    src.write_text("event,time,x,y\n" + "".join(f"{e},{t},{x},{y}\n" for e, t, x, y in rows))
    _one_line_exit_2(run_cli, "track", "--detections", src, "--out", tmp_path / "t.csv",
                     words=("d.csv", f"event {event} after event 19", "more than 100,000"))
    assert not (tmp_path / "t.csv").exists()


@pytest.mark.parametrize("event", [900_000_000_000, 200_000])
def test_event_id_far_past_the_others_out_of_order_is_refused(run_cli, tmp_path, event):
    """The far event out of event order (track then reads the whole file instead of streaming
    it): the same one line (was: a MemoryError traceback, 6.55 TiB; found by the property
    test)."""
    rows = [(e, 10.0 * e, 100.0 * k, 50.0 * e) for e in range(20) for k in range(3)]
    rows.insert(7, (event, 10.0 * 21, 0.0, 0.0))
    src = tmp_path / "d.csv"
    src.write_text("event,time,x,y\n" + "".join(f"{e},{t},{x},{y}\n" for e, t, x, y in rows))
    _one_line_exit_2(run_cli, "track", "--detections", src, "--out", tmp_path / "t.csv",
                     words=("d.csv", f"event {event} after event 19", "more than 100,000"))
    assert not (tmp_path / "t.csv").exists()


def test_failing_run_prints_only_its_error_line(run_cli, tmp_path):
    """The sort note of out-of-order rows is dropped when the run then fails."""
    b = tmp_path / "b.csv"
    b.write_text("time,bearing_deg\n10,30\n0,31\n20,32\n30,33\n40,34\n")
    own = tmp_path / "o.csv"
    own.write_text("time,x,y\n0,0,0\n5,1,1\n")
    err = _one_line_exit_2(run_cli, "tma", "--bearings", b, "--ownship", own, "--out",
                           tmp_path / "t.csv", words=("own-ship",))
    assert "sorted" not in err


def test_failing_track_prints_only_its_error_line_not_its_note(run_cli, tmp_path):
    """track's note on missing clue columns waits for the tracks to be written: a run that
    then fails prints its error line only (was: the note first; found by the property test)."""
    src = tmp_path / "d.csv"
    src.write_text("event,time,x,y\n2,0,0,0\n0,0,105,0\n1,30,10,50\n")
    err = _one_line_exit_2(run_cli, "track", "--detections", src, "--out", tmp_path / "t.csv",
                           words=("error:", "goes back"))
    assert "note:" not in err
    ok = tmp_path / "ok.csv"
    ok.write_text("event,time,x,y\n" + "".join(f"{e},{10 * e},{100 * k},{50 * e}\n"
                                                 for e in range(12) for k in range(2)))
    code, _, err = run_cli("track", "--detections", ok, "--out", tmp_path / "t.csv",
                           "--fit-pings", 5)
    assert code == 0, err
    assert err.count("note: ") == 1 and "left out of the rank" in err, err


def test_numpy_warning_of_a_successful_run_is_one_line(run_cli, tmp_path, monkeypatch):
    """A numpy overflow in a run that succeeds (options no longer overflow: --snr0-db 1e300 is
    refused, so the overflow is planted in the command)."""
    import numpy as np

    import fusion.commands.tqi as tqi

    real = tqi.run

    def overflowing(args):
        np.float64(1e300) * np.float64(1e300)
        return real(args)

    monkeypatch.setattr(tqi, "run", overflowing)
    src = tmp_path / "a.csv"
    src.write_text("track_id,time,amplitude,residual\n0,0,1,0.1\n0,1,2,0.2\n0,2,1,0.1\n")
    code, _, err = run_cli("tqi", "--amplitudes", src, "--out", tmp_path / "t.csv")
    assert code == 0, err
    lines = err.strip().splitlines()
    assert lines and all(ln.startswith("fusion tqi: warning: ") for ln in lines), err
    assert any("RuntimeWarning" in ln for ln in lines)


def test_huge_sensor_coordinate_is_refused_without_a_numpy_warning(tmp_path, recwarn):
    from fusion.io import read_array

    p = _array(tmp_path / "a.json", 1500.0)
    p.write_text(p.read_text().replace('"x": 0,', '"x": 1e308,', 1))
    with pytest.raises(ValueError, match=r"sensor 0: 'x' = 1e\+308 is beyond"):
        read_array(p)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


@pytest.mark.parametrize(("option", "value", "words"), [
    ("--workers", "0", ("--workers", ">= 1")),
    ("--workers", "99999999999999", ("--workers", "<=")),
    ("--workers", "max+1", ("--workers", "<=")),
    ("--candidates", "0", ("--candidates", ">= 1")),
    ("--candidates", "257", ("--candidates", "<= 256")),
    ("--candidates", "1000000000000", ("--candidates", "<= 256")),
])
def test_localize_workers_and_candidates_out_of_bounds_are_one_line(run_cli, tmp_path, option,
                                                                     value, words):
    """--workers above 4 per core (was: any number of Dask processes started) and --candidates
    above 256 (was: every local maximum of the volume competing, K^2 pairs an iteration) are
    usage errors, before any file is read."""
    from fusion.commands.localize import MAX_WORKERS_PER_CORE, max_workers

    assert max_workers() == MAX_WORKERS_PER_CORE * (os.cpu_count() or 1)
    value = str(max_workers() + 1) if value == "max+1" else value
    _one_line_exit_2(run_cli, "localize", "--audio", tmp_path / "a.wav", "--array",
                     tmp_path / "a.json", "--out", tmp_path / "r.json", option, value,
                     words=words)
    assert not list(tmp_path.iterdir())


def test_localize_workers_and_candidates_at_their_bounds_are_accepted():
    from fusion.cli import build_parser
    from fusion.commands.localize import MAX_CANDIDATES, max_workers

    args = build_parser("localize").parse_args(
        ["localize", "--audio", "a.wav", "--array", "a.json", "--out", "r.json", "--workers",
         str(max_workers()), "--candidates", str(MAX_CANDIDATES)])
    assert (args.workers, args.candidates) == (max_workers(), MAX_CANDIDATES)


@pytest.mark.parametrize("argv", [
    ("tma", "--bearings", "B", "--ownship", "O", "--bearing-sigma-deg", "4.374969934613653e-268"),
    ("tma", "--bearings", "B", "--ownship", "O", "--accel-psd-m2-per-s3", "5e-324"),
    ("smooth", "--bearings", "B", "--bearing-sigma-deg", "1e-300"),
    ("tqi", "--amplitudes", "A", "--residual-smoothing", "9e-13"),
])
def test_positive_option_below_1e_12_is_a_usage_error(run_cli, tmp_path, argv):
    """A positive float option below 1e-12 (``gt=0``): one line, exit 2 (was, for tma
    --bearing-sigma-deg 4e-268: a ZeroDivisionError traceback, its square 0; found by the
    property test)."""
    files = {"B": tmp_path / "b.csv", "O": tmp_path / "o.csv", "A": tmp_path / "a.csv"}
    for f in files.values():
        f.write_text("x\n1\n")
    argv = [str(files.get(a, a)) for a in argv]
    err = _one_line_exit_2(run_cli, *argv, "--out", tmp_path / "r.csv", words=(argv[-2],))
    assert ">= 1e-12" in err
    assert not (tmp_path / "r.csv").exists()


def test_positive_option_bound_is_inclusive():
    import argparse

    from fusion.cli import MIN_POSITIVE_OPTION, number

    assert number(float, gt=0)("1e-12") == MIN_POSITIVE_OPTION
    assert number(float, gt=0)("0.5") == 0.5
    assert number(float, ge=0)("5e-324") == 5e-324  # zero allowed: tiny too
    for text, words in (("-1", "> 0"), ("0", "> 0"), ("5e-324", ">= 1e-12")):
        with pytest.raises(argparse.ArgumentTypeError, match=words):
            number(float, gt=0)(text)


@pytest.mark.parametrize("command", ["localize", "train-validator"])
@pytest.mark.parametrize("hop", ["1e-6", "0.0009"])
def test_hop_below_the_click_map_resolution_is_a_usage_error(run_cli, tmp_path, command, hop):
    """--hop-s below 1 ms (3 samples of the click map): one line, before any work (was: a hop of
    1 us ran a 3-s recording's 3 million windows for hours)."""
    from fusion.clicks.scm import ScmConfig
    from fusion.commands.localize import MIN_HOP_S

    assert MIN_HOP_S * ScmConfig().fs_hz >= 3
    argv = (["localize", "--audio", tmp_path / "a.wav", "--array", tmp_path / "a.json"]
            if command == "localize" else ["train-validator", "--recording", tmp_path])
    _one_line_exit_2(run_cli, *argv, "--out", tmp_path / "r.out", "--hop-s", hop,
                     words=("--hop-s", ">= 0.001"))
    assert not (tmp_path / "r.out").exists()


@pytest.mark.parametrize("options", [("--period-s", "1.192092896e-07", "--window-s", "2"),
                                     ("--period-s", "1.192092896e-07", "--horizon-s", "2")])
def test_crossing_windows_beyond_a_million_samples_are_refused(run_cli, tmp_path, options):
    """A ladder of windows over 10^6 samples (a tiny --period-s): one line, before any
    allocation (was: a MemoryError traceback, 4-36 GiB; found by the property test)."""
    src = _bearings(tmp_path / "b.csv", [])
    _one_line_exit_2(run_cli, "crossings", "--bearings", src, "--out", tmp_path / "o.csv",
                     *options, words=("longest window", "more than 1,000,000"))
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("command", ["acquire", "passive"])
def test_cube_power_beyond_1e100_is_refused(run_cli, tmp_path, cube, command):
    """One cube cell of 1e308: one line naming the file and the cell (was, for passive: a
    GTSAM 'Indeterminate linear system' traceback; found by the property test)."""
    arrays = dict(cube)
    arrays["power"] = arrays["power"].copy()
    arrays["power"][0, 2, 3] = 1e308
    bad = tmp_path / "c.npz"
    np.savez(bad, **arrays)
    argv = (["acquire", "--cube", bad, "--beam", 1, "--freq-hz", 300] if command == "acquire"
            else ["passive", "--cube", bad, "--auto", "--out", tmp_path / "o", "--quiet"])
    _one_line_exit_2(run_cli, *argv, words=("c.npz", "1e+308", "(0, 2, 3)", "implausible"))
    assert not (tmp_path / "o").exists()


def test_simulate_clicks_duration_is_bounded(tmp_path, capsys):
    """`fusion simulate clicks --duration-s 1e12` is one usage line, nothing written (was: a
    MemoryError traceback allocating 1.3 EiB; found by the property test)."""
    from fusion.cli import main

    assert main(["simulate", "clicks", "--duration-s", "999999999999",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--duration-s" in err[0]
    assert not (tmp_path / "o").exists()
