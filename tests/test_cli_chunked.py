"""Commands that read their CSV in chunks give the bytes of the whole-file path.

``fusion tqi`` and ``fusion crossings`` stream their input (``fusion.io.iter_amplitudes``,
``iter_bearings``); these tests compare their outputs with the whole-table computations, kept in
the commands for inputs out of order, on simulated inputs (``fusion simulate amplitudes`` and
``fusion simulate bearings``, plain and ``--vary``, and variants with fractional times, gaps and
dense sampling), with small chunks so that tracks and grid cells straddle chunk boundaries, and
check bad input found late in a file.
"""

from __future__ import annotations

import argparse
import functools
import logging

import numpy as np
import pytest

import fusion.commands.crossings as crossings_command
import fusion.commands.tqi as tqi_command
from fusion.cli import EXIT_BAD_INPUT, main
from fusion.io import iter_amplitudes, iter_bearings, read_table, write_table
from fusion.simulate.amplitudes import write_scenario as write_amplitudes
from fusion.simulate.bearings import simulate_bearings
from fusion.simulate.bearings import write_scenario as write_bearings


def _tqi_args(amplitudes, out, *extra):
    parser = argparse.ArgumentParser()
    tqi_command.register(parser.add_subparsers())
    return parser.parse_args(["tqi", "--amplitudes", str(amplitudes), "--out", str(out), *extra])


@pytest.fixture(scope="module")
def amplitude_files(tmp_path_factory):
    """Simulated tracker outputs: two plain and two varied scenarios, and one interleaved."""
    root = tmp_path_factory.mktemp("amp")
    files = []
    for seed, vary in ((0, False), (1, False), (0, True), (2, True)):
        out = root / f"s{seed}{'v' if vary else ''}"
        write_amplitudes(out, seed=seed, vary=vary)
        files.append(out / "amplitudes.csv")
    # the same rows interleaved by time (each track still in time order)
    t = read_table(files[0], required=("track_id", "time", "amplitude", "residual"),
                   integer=("track_id",))
    order = np.lexsort((t["track_id"], t["time"]))
    inter = root / "interleaved.csv"
    write_table(inter, {k: v[order] for k, v in t.columns.items()})
    return [*files, inter]


@pytest.mark.parametrize(("rows_per_chunk", "diagnostics"),
                         [(97, False), (97, True), (1000, True), (1 << 16, False)])
def test_tqi_streamed_equals_whole_file(tmp_path, monkeypatch, amplitude_files, rows_per_chunk,
                                        diagnostics):
    """fusion tqi read in chunks writes the bytes of the whole-table TQI on simulated inputs."""
    monkeypatch.setattr(tqi_command, "iter_amplitudes",
                        functools.partial(iter_amplitudes, rows_per_chunk=rows_per_chunk))
    extra = ["--diagnostics"] if diagnostics else []
    for i, f in enumerate(amplitude_files):
        streamed, whole = tmp_path / f"s{i}.csv", tmp_path / f"w{i}.csv"
        assert main(["tqi", "--amplitudes", str(f), "--out", str(streamed), *extra]) == 0
        args = _tqi_args(f, whole, *extra)
        tqi_command._whole_file(args, tqi_command._indicator(args))
        assert streamed.read_bytes() == whole.read_bytes(), f.name
        labels = read_table(streamed, required=("tqi",), text=("tqi",))["tqi"]
        assert len(set(labels.tolist())) >= 2  # the scenarios exercise several states


def test_tqi_out_of_order_falls_back_to_the_sorted_whole_file(tmp_path, monkeypatch, caplog,
                                                             amplitude_files):
    """A row out of order in a late chunk: one sort warning, the output of the sorted file."""
    monkeypatch.setattr(tqi_command, "iter_amplitudes",
                        functools.partial(iter_amplitudes, rows_per_chunk=50))
    text = amplitude_files[0].read_text().splitlines(keepends=True)
    text[300], text[301] = text[301], text[300]  # same track: times swapped, line 301
    shuffled = tmp_path / "shuffled.csv"
    shuffled.write_text("".join(text))
    with caplog.at_level(logging.WARNING):
        assert main(["tqi", "--amplitudes", str(shuffled), "--out", str(tmp_path / "a.csv")]) == 0
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "sorted by time" in warnings[0]
    assert main(["tqi", "--amplitudes", str(amplitude_files[0]),
                 "--out", str(tmp_path / "b.csv")]) == 0
    a = read_table(tmp_path / "a.csv", required=("track_id", "time", "tqi"), text=("tqi",))
    b = read_table(tmp_path / "b.csv", required=("track_id", "time", "tqi"), text=("tqi",))
    order = np.lexsort((a["time"], a["track_id"]))
    for name in ("track_id", "time", "tqi"):
        np.testing.assert_array_equal(a[name][order], b[name])


def test_tqi_repeat_time_message_of_the_whole_file_reader(tmp_path, capsys):
    """A repeated time is refused with the whole-file reader's message, exit 2, no output."""
    f = tmp_path / "dup.csv"
    f.write_text("track_id,time,amplitude,residual\n0,0,1,0\n1,0,1,0\n0,1,1,0\n1,2,1,0\n1,2,3,0\n")
    out = tmp_path / "out.csv"
    assert main(["tqi", "--amplitudes", str(f), "--out", str(out)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"fusion tqi: error: {f}: track_id 1 has two rows at time 2; times must be "
                   "distinct within a track (merge or drop the repeats)"]
    assert not out.exists()


def test_tqi_bad_cell_in_a_late_chunk_leaves_no_output(tmp_path, monkeypatch, capsys,
                                                      amplitude_files):
    """NaN in the last chunk: exit 2, one line naming the line, the old output untouched."""
    monkeypatch.setattr(tqi_command, "iter_amplitudes",
                        functools.partial(iter_amplitudes, rows_per_chunk=100))
    lines = amplitude_files[0].read_text().splitlines(keepends=True)
    n = len(lines)
    lines[-1] = lines[-1].split(",")[0] + ",1e9,nan,0\n"
    bad = tmp_path / "bad.csv"
    bad.write_text("".join(lines))
    out = tmp_path / "out.csv"
    out.write_text("old\n")
    assert main(["tqi", "--amplitudes", str(bad), "--out", str(out)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"fusion tqi: error: {bad}: line {n}, column 'amplitude': value is nan"]
    assert out.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv", "out.csv"]


# --------------------------------------------------------------------------------------------
# fusion crossings
# --------------------------------------------------------------------------------------------
def _crossings_args(bearings, out, *extra):
    parser = argparse.ArgumentParser()
    crossings_command.register(parser.add_subparsers())
    return parser.parse_args(["crossings", "--bearings", str(bearings), "--out", str(out),
                              *extra])


@pytest.fixture(scope="module")
def bearing_files(tmp_path_factory):
    """Simulated bearing tables: plain and varied scenarios, and harder variants of one."""
    root = tmp_path_factory.mktemp("bearings")
    files = []
    for seed, vary in ((0, False), (1, False), (0, True)):
        out = root / f"s{seed}{'v' if vary else ''}"
        write_bearings(out, seed=seed, vary=vary)
        files.append(out / "bearings.csv")
    # the varied scenario's first 5,000 rows (a shorter run of the same picture)
    text = files[2].read_text().splitlines(keepends=True)
    files[2].write_text("".join(text[:5001]))
    # fractional times and gaps, missed detections, clutter rows (track -1), dense sampling
    for seed, period in ((5, 10.0), (6, 2.0)):  # files 3 and 4
        sc = simulate_bearings(seed=seed, n_tracks=8, duration_s=1800.0, sample_period_s=period,
                               p_detect=0.8, clutter_rate=1.0, gaps_per_hour=6.0)
        order = np.lexsort((sc.track_id, sc.time))
        f = root / f"hard{seed}.csv"
        write_table(f, {"track_id": sc.track_id[order],
                        "time": np.round(sc.time[order] * 1.0001 + 1234.567, 3),
                        "bearing_deg": sc.bearing_deg[order]})
        files.append(f)
    return files


@pytest.mark.parametrize(("which", "extra", "rows_per_chunk"), [
    (0, [], 41),  # plain scenarios
    (1, ["--windows", "1", "--window-s", "60"], 1000),
    (2, ["--windows", "3"], 1000),  # a varied scenario
    (3, [], 41),  # fractional times, gaps, missed detections, clutter
    (3, ["--max-gap-s", "25"], 1 << 16),
    (4, ["--period-s", "7"], 1000),  # 2 s data averaged onto a 7 s grid
])
def test_crossings_streamed_equals_whole_file(tmp_path, monkeypatch, capsys, bearing_files,
                                             which, extra, rows_per_chunk):
    """fusion crossings read in chunks writes the alerts of the whole-file path, byte for byte."""
    monkeypatch.setattr(crossings_command, "iter_bearings",
                        functools.partial(iter_bearings, rows_per_chunk=rows_per_chunk))
    monkeypatch.setattr(crossings_command, "_whole_file", _no_whole_file)
    f = bearing_files[which]
    streamed, whole = tmp_path / "streamed.csv", tmp_path / "whole.csv"
    assert main(["crossings", "--bearings", str(f), "--out", str(streamed), *extra]) == 0
    line = "".join(capsys.readouterr())
    alerts, st = _WHOLE_FILE(_crossings_args(f, whole, *extra))
    write_table(whole, crossings_command.alert_columns(alerts))
    assert streamed.read_bytes() == whole.read_bytes()
    assert st.describe() in line
    assert len(alerts) >= 3  # alerts to compare


_WHOLE_FILE = crossings_command._whole_file


def _no_whole_file(args):
    raise AssertionError("the streamed path fell back to the whole file")


def test_crossings_rows_grouped_by_track_use_the_whole_file(tmp_path, monkeypatch, bearing_files):
    """A table sorted by track (valid, not in time order overall) goes the whole-file way."""
    t = read_table(bearing_files[0], required=("track_id", "time", "bearing_deg"),
                   integer=("track_id",))
    order = np.lexsort((t["time"], t["track_id"]))
    grouped = tmp_path / "grouped.csv"
    write_table(grouped, {k: v[order] for k, v in t.columns.items()})
    calls = []
    monkeypatch.setattr(crossings_command, "_whole_file",
                        lambda args: calls.append(1) or _WHOLE_FILE(args))
    assert main(["crossings", "--bearings", str(grouped), "--out", str(tmp_path / "a.csv")]) == 0
    assert main(["crossings", "--bearings", str(bearing_files[0]),
                 "--out", str(tmp_path / "b.csv")]) == 0
    assert calls == [1]
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


def test_crossings_bad_cell_late_leaves_no_output(tmp_path, monkeypatch, capsys, bearing_files):
    """inf in the last chunk: exit 2, one line naming the line, no output written."""
    monkeypatch.setattr(crossings_command, "iter_bearings",
                        functools.partial(iter_bearings, rows_per_chunk=100))
    lines = bearing_files[0].read_text().splitlines(keepends=True)
    lines[-1] = lines[-1].rsplit(",", 1)[0] + ",inf\n"
    bad = tmp_path / "bad.csv"
    bad.write_text("".join(lines))
    out = tmp_path / "out.csv"
    assert main(["crossings", "--bearings", str(bad), "--out", str(out)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"fusion crossings: error: {bad}: line {len(lines)}, column 'bearing_deg': "
                   "value is inf"]
    assert not out.exists()
