"""Outputs that never destroy anything, row-order rules, and bad input beyond the matrix.

Companion of ``test_cli_bad_input.py`` (same standard: exit 2, one stderr line naming the culprit,
no traceback, no output, inputs untouched). Covers

- ``--out`` onto an input (same path, another spelling, a symbolic link, a hard link), onto a
  symbolic link (written through), a FIFO, ``/dev/null``, ``/dev/full``, ``/dev/stdout`` on a
  pipe; ``--out -`` (standard output);
- temporaries of killed runs (a real SIGKILL mid-write) removed by the next run, temporaries of
  live runs kept, permissions of written files;
- rows out of time order (sorted, one warning, same result as sorted input), repeated times;
- values like 1e308, a CSV field over 128 KiB, a text file named ``.npz``.
"""

from __future__ import annotations

import csv
import logging
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from fusion._output import TMP_MARK
from fusion.cli import EXIT_BAD_INPUT
from fusion.io import read_table, write_table

PYTHON = sys.executable


def write_csv(path: Path, cols: dict[str, list]) -> Path:
    """Columns as CSV, values as given."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(cols))
        w.writerows(zip(*cols.values(), strict=True))
    return path


def crossing_bearings() -> dict[str, list]:
    """Two tracks crossing, 30 samples 10 s apart, interleaved by time."""
    rows = [(k, 10.0 * i, b0 + rate * 10.0 * i) for i in range(30)
            for k, (b0, rate) in enumerate(((40.0, 0.1), (70.0, -0.1)))]
    return {"track_id": [r[0] for r in rows], "time": [r[1] for r in rows],
            "bearing_deg": [r[2] for r in rows]}


def amplitudes() -> dict[str, list]:
    """Two tracks, 20 updates each."""
    rng = np.random.default_rng(1)
    n = 20
    return {"track_id": [0] * n + [1] * n, "time": list(range(n)) * 2,
            "amplitude": (10 * rng.exponential(size=2 * n)).tolist(),
            "residual": rng.normal(0, 0.5, 2 * n).tolist()}


def ownship() -> dict[str, list]:
    """Own-ship leg east then north, every 5 s over 0..600 s."""
    t = np.arange(0, 601, 5.0)
    return {"time": t.tolist(), "x": np.where(t <= 300, 5.0 * t, 1500.0).tolist(),
            "y": np.where(t <= 300, 0.0, 5.0 * (t - 300)).tolist()}


def tma_bearings() -> dict[str, list]:
    """True bearings of a target at (4000, 6000) m moving south-west, every 20 s."""
    os_ = ownship()
    t = np.arange(0, 601, 20.0)
    ox, oy = np.interp(t, os_["time"], os_["x"]), np.interp(t, os_["time"], os_["y"])
    b = np.degrees(np.arctan2(4000.0 - 2.0 * t - ox, 6000.0 - 3.0 * t - oy))
    return {"time": t.tolist(), "bearing_deg": b.tolist()}


def detections() -> dict[str, list]:
    """A target moving east in 6 pings, one clutter point per ping."""
    cols: dict[str, list] = {"event": [], "time": [], "x": [], "y": []}
    for k in range(6):
        for x, y in ((1000.0 + 50 * k, 2000.0), (-3000.0 + 900 * k, 500.0 * k)):
            for name, v in zip(cols, (k, 60.0 * k, x, y), strict=True):
                cols[name].append(v)
    return cols


#: command -> {input option: columns}
INPUTS = {
    "crossings": {"bearings": crossing_bearings},
    "smooth": {"bearings": crossing_bearings},
    "tqi": {"amplitudes": amplitudes},
    "tma": {"bearings": tma_bearings, "ownship": ownship},
    "track": {"detections": detections},
}


def make_inputs(cmd: str, folder: Path) -> dict[str, Path]:
    """Valid inputs of `cmd` written into `folder`; option -> path."""
    return {opt: write_csv(folder / f"{opt}.csv", make()) for opt, make in INPUTS[cmd].items()}


def argv(cmd: str, inputs: dict[str, Path], out: object, *extra: str) -> list[str]:
    """The command line."""
    words = [cmd]
    for opt, p in inputs.items():
        words += [f"--{opt}", str(p)]
    return [*words, "--out", str(out), *extra]


def snapshot(paths) -> dict[Path, tuple[bytes, int]]:
    """Content and modification time of files, to check they were not touched."""
    return {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in paths}


def assert_one_line(code: int, err: str, *mentions: str) -> None:
    """Exit 2, one stderr line containing every mention, no traceback."""
    assert code == EXIT_BAD_INPUT, err
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    for m in mentions:
        assert m in lines[0], (m, lines[0])


def temporaries(folder: Path) -> list[str]:
    """Names of temporary output files in `folder`."""
    return sorted(p.name for p in folder.iterdir() if TMP_MARK in p.name)


# --------------------------------------------------------------------------------------------
# --out onto an input
# --------------------------------------------------------------------------------------------
def _same_path(tmp: Path, inp: Path) -> Path:
    return inp


def _other_spelling(tmp: Path, inp: Path) -> Path:
    (tmp / "sub").mkdir()
    return tmp / "sub" / ".." / "." / inp.name


def _symlink(tmp: Path, inp: Path) -> Path:
    link = tmp / "link.csv"
    link.symlink_to(inp.name)
    return link


def _hard_link(tmp: Path, inp: Path) -> Path:
    hard = tmp / "hard.csv"
    os.link(inp, hard)
    return hard


@pytest.mark.parametrize("how", [_same_path, _other_spelling, _symlink, _hard_link],
                         ids=["same-path", "other-spelling", "symlink", "hard-link"])
@pytest.mark.parametrize("cmd", sorted(INPUTS))
def test_out_onto_an_input_is_refused(cmd, how, run_cli, tmp_path):
    """``--out`` naming an input in any spelling: one line, exit 2, the input untouched."""
    inputs = make_inputs(cmd, tmp_path)
    victim = list(inputs.values())[-1]
    out = how(tmp_path, victim)
    before = snapshot(inputs.values())
    code, stdout, err = run_cli(*argv(cmd, inputs, out))
    assert_one_line(code, err, "--out", "same file as the input", victim.name)
    assert snapshot(inputs.values()) == before
    assert temporaries(tmp_path) == []


def test_out_onto_the_rules_file_is_refused(run_cli, tmp_path):
    """A path option that is not a table input (``track --rules``) is protected too."""
    inputs = make_inputs("track", tmp_path)
    rules = tmp_path / "rules.json"
    rules.write_text("{}")
    code, _, err = run_cli(*argv("track", inputs, rules, "--rules", str(rules)))
    assert_one_line(code, err, "--rules", "rules.json")
    assert rules.read_text() == "{}"


# --------------------------------------------------------------------------------------------
# --out onto links and special files
# --------------------------------------------------------------------------------------------
def test_out_symlink_is_written_through(run_cli, tmp_path):
    """``--out`` a symbolic link: its target gets the result, the link stays a link."""
    inputs = make_inputs("tqi", tmp_path)
    (tmp_path / "results").mkdir()
    target = tmp_path / "results" / "q.csv"
    target.write_text("old\n")
    link = tmp_path / "latest.csv"
    link.symlink_to(Path("results") / "q.csv")
    code, _, err = run_cli(*argv("tqi", inputs, link))
    assert code == 0, err
    assert link.is_symlink() and os.readlink(link) == str(Path("results") / "q.csv")
    q = read_table(target, required=("track_id", "tqi"), text=("tqi",))
    assert len(q) == 40
    assert temporaries(tmp_path) == [] and temporaries(target.parent) == []


def test_out_dangling_symlink_creates_its_target(run_cli, tmp_path):
    """A dangling link as ``--out`` gets its target created, like a shell redirection."""
    inputs = make_inputs("tqi", tmp_path)
    link = tmp_path / "latest.csv"
    link.symlink_to("new_target.csv")
    code, _, err = run_cli(*argv("tqi", inputs, link))
    assert code == 0, err
    assert link.is_symlink() and (tmp_path / "new_target.csv").is_file()


def test_out_symlink_loop_is_refused(run_cli, tmp_path):
    """A symbolic-link loop as ``--out``: one line, exit 2."""
    inputs = make_inputs("tqi", tmp_path)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.symlink_to(b.name)
    b.symlink_to(a.name)
    code, _, err = run_cli(*argv("tqi", inputs, a))
    assert_one_line(code, err, "--out", "a.csv")


def test_out_fifo_is_refused_without_blocking(run_cli, tmp_path):
    """A FIFO as ``--out`` is refused at once (not opened, so nothing blocks)."""
    inputs = make_inputs("tqi", tmp_path)
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    code, _, err = run_cli(*argv("tqi", inputs, fifo))
    assert_one_line(code, err, "--out", "pipe", "FIFO")
    assert temporaries(tmp_path) == []


@pytest.mark.parametrize("device", ["/dev/null", "/dev/full"])
def test_out_device_is_refused(device, run_cli, tmp_path):
    """A character device as ``--out``: one line, exit 2, the device node left alone."""
    if not os.path.exists(device):
        pytest.skip(f"no {device}")
    inputs = make_inputs("tqi", tmp_path)
    code, _, err = run_cli(*argv("tqi", inputs, device))
    assert_one_line(code, err, "--out", device, "character device")
    assert not os.path.isfile(device)


def test_out_dev_stdout_on_a_pipe_is_refused(tmp_path):
    """``--out /dev/stdout`` with stdout a pipe (a real process): one line, exit 2, no output."""
    inputs = make_inputs("tqi", tmp_path)
    r = subprocess.run([PYTHON, "-m", "fusion", *argv("tqi", inputs, "/dev/stdout")],
                       capture_output=True, text=True, check=False, timeout=120)
    assert_one_line(r.returncode, r.stderr, "--out /dev/stdout", "named pipe")
    assert r.stdout == ""


# --------------------------------------------------------------------------------------------
# --out - (standard output)
# --------------------------------------------------------------------------------------------
def test_out_dash_writes_the_table_to_stdout(run_cli, tmp_path):
    """``--out -`` prints exactly the CSV that ``--out FILE`` writes; notes go to stderr."""
    inputs = make_inputs("crossings", tmp_path)
    code, _, err = run_cli(*argv("crossings", inputs, tmp_path / "alerts.csv"))
    assert code == 0, err
    code, stdout, err = run_cli(*argv("crossings", inputs, "-"))
    assert code == 0, err
    assert stdout == (tmp_path / "alerts.csv").read_text()
    assert "alert(s)" in err  # the summary line moved to stderr
    assert not (tmp_path / "-").exists()


@pytest.mark.parametrize("cmd", sorted(INPUTS))
def test_out_dot_slash_dash_writes_a_file_called_dash(cmd, run_cli, tmp_path, monkeypatch):
    """``--out ./-`` names a file called ``-``, as documented, also where ``--out`` is a
    ``Path`` option (was: ``Path("./-")`` is ``Path("-")``: the table went to stdout and no file
    was written; found by the property test)."""
    inputs = make_inputs(cmd, tmp_path)
    code, _, err = run_cli(*argv(cmd, inputs, tmp_path / "o.csv"))
    assert code == 0, err
    monkeypatch.chdir(tmp_path)
    code, stdout, err = run_cli(*argv(cmd, inputs, "./-"))
    assert code == 0, err
    assert (tmp_path / "-").read_text() == (tmp_path / "o.csv").read_text()
    assert "track_id" not in stdout and "time," not in stdout


@pytest.mark.parametrize("cmd", ["simulate", "demo"])
def test_out_dash_refused_for_folder_outputs(cmd, run_cli, tmp_path, monkeypatch):
    """Commands that write a folder refuse ``--out -`` before any work."""
    monkeypatch.chdir(tmp_path)
    words = ["simulate", "amplitudes"] if cmd == "simulate" else ["demo", "--part", "tqi"]
    code, stdout, err = run_cli(*words, "--out", "-")
    assert_one_line(code, err, "--out -", "folder")
    assert stdout == "" and list(tmp_path.iterdir()) == []


def test_library_writer_to_stdout(capsysbinary):
    """``write_table("-", ...)`` writes the CSV to standard output and no file."""
    write_table("-", {"a": [1, 2], "b": [0.5, 1e20]})
    assert capsysbinary.readouterr().out == b"a,b\n1,0.500000\n2,1e+20\n"


# --------------------------------------------------------------------------------------------
# temporaries of killed runs, permissions
# --------------------------------------------------------------------------------------------
_WRITER = textwrap.dedent("""
    import sys, time
    from fusion.io import atomic_output
    with atomic_output(sys.argv[1]) as tmp, tmp.open("w") as fh:
        fh.write("x" * 1_000_000)
        fh.flush()
        print(tmp, flush=True)
        time.sleep(60)
""")


def test_temporary_of_a_killed_run_is_removed_by_the_next_run(run_cli, tmp_path):
    """SIGKILL mid-write leaves a temporary; the next run of the command removes it."""
    inputs = make_inputs("tqi", tmp_path)
    out = tmp_path / "q.csv"
    proc = subprocess.Popen([PYTHON, "-c", _WRITER, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        tmp = Path(proc.stdout.readline().strip())
        assert tmp.parent == tmp_path and tmp.stat().st_size == 1_000_000
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        proc.stdout.close()
    assert temporaries(tmp_path) == [tmp.name] and not out.exists()
    code, _, err = run_cli(*argv("tqi", inputs, out))
    assert code == 0, err
    assert temporaries(tmp_path) == [] and out.is_file()


def test_temporary_of_a_live_run_is_kept(run_cli, tmp_path):
    """A temporary whose writer is still running (a concurrent run) is not deleted."""
    inputs = make_inputs("tqi", tmp_path)
    proc = subprocess.Popen([PYTHON, "-c", "import time; time.sleep(60)"])
    try:
        live = tmp_path / f".q.csv.{proc.pid}.{TMP_MARK}.csv"
        live.write_text("in progress")
        code, _, err = run_cli(*argv("tqi", inputs, tmp_path / "q.csv"))
        assert code == 0, err
        assert live.read_text() == "in progress"
    finally:
        proc.kill()
        proc.wait(timeout=30)


def test_stale_temporary_of_a_dead_process_is_removed(run_cli, tmp_path):
    """A leftover ``.NAME.PID.fusion-tmp`` of a process that no longer exists is removed."""
    inputs = make_inputs("tqi", tmp_path)
    proc = subprocess.Popen([PYTHON, "-c", "pass"])
    proc.wait(timeout=30)  # its pid is now free
    stale = tmp_path / f".q.csv.{proc.pid}.{TMP_MARK}.csv"
    stale.write_bytes(b"\0" * 4096)
    unrelated = tmp_path / ".q.csv.backup"
    unrelated.write_text("mine")
    code, _, err = run_cli(*argv("tqi", inputs, tmp_path / "q.csv"))
    assert code == 0, err
    assert not stale.exists() and unrelated.read_text() == "mine"


def test_replaced_output_has_usual_permissions(run_cli, tmp_path):
    """An output written over an existing file gets the umask's usual permissions."""
    umask = os.umask(0)
    os.umask(umask)
    inputs = make_inputs("tqi", tmp_path)
    out = tmp_path / "q.csv"
    out.write_text("old")
    out.chmod(0o600)
    code, _, err = run_cli(*argv("tqi", inputs, out))
    assert code == 0, err
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask


# --------------------------------------------------------------------------------------------
# row order and repeated times
# --------------------------------------------------------------------------------------------
def _permuted(cmd: str, opt: str, cols: dict[str, list]) -> dict[str, list]:
    """Rows out of time order: reversed (detections: whole pings reversed, order within kept)."""
    n = len(next(iter(cols.values())))
    if cmd == "track":
        ev = np.asarray(cols["event"])
        order = np.concatenate([np.flatnonzero(ev == e) for e in np.unique(ev)[::-1]])
    else:
        order = np.arange(n)[::-1]
    return {k: [v[i] for i in order] for k, v in cols.items()}


@pytest.mark.parametrize("cmd", sorted(INPUTS))
def test_rows_out_of_order_are_sorted_with_one_note(cmd, run_cli, tmp_path, caplog):
    """Every command sorts rows out of time order (one warning) and gives the sorted result.

    The sorted input is grouped by track (tqi) or interleaved by time (the others).
    """
    inputs = make_inputs(cmd, tmp_path)
    code, _, err = run_cli(*argv(cmd, inputs, tmp_path / "sorted_result.csv"))
    assert code == 0, err
    shuffled = {opt: write_csv(tmp_path / f"{opt}_shuffled.csv",
                               _permuted(cmd, opt, INPUTS[cmd][opt]()))
                for opt in inputs}
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="fusion.io"):
        code, _, err = run_cli(*argv(cmd, shuffled, tmp_path / "result.csv"))
    assert code == 0, err
    notes = [r.getMessage() for r in caplog.records if r.name == "fusion.io"]
    assert len(notes) == len(shuffled), notes
    assert all("sorted by" in m for m in notes)
    got = (tmp_path / "result.csv").read_text().splitlines()
    want = (tmp_path / "sorted_result.csv").read_text().splitlines()
    if cmd == "tqi":  # one output row per input row, in the (sorted) input's order
        got, want = sorted(got), sorted(want)
    assert got == want


def test_sort_note_is_one_stderr_line(tmp_path):
    """In a real run the sort note is one line ``fusion tqi: warning: FILE: ... sorted ...``,
    before the summary line."""
    cols = _permuted("tqi", "amplitudes", amplitudes())
    inp = write_csv(tmp_path / "shuffled.csv", cols)
    r = subprocess.run([PYTHON, "-m", "fusion", "tqi", "--amplitudes", str(inp), "--out", "-"],
                       capture_output=True, text=True, check=False, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()  # the note, then the summary (on stderr: the data is on stdout)
    assert len(lines) == 2 and lines[0].startswith("fusion tqi: warning: ")
    assert "shuffled.csv" in lines[0] and "sorted by time" in lines[0]
    assert lines[1] == "fusion tqi: 2 track(s), 40 update(s) -> -"
    assert r.stdout.splitlines()[0] == "track_id,time,amplitude,residual,tqi"
    assert len(r.stdout.splitlines()) == 41


def test_unknown_origin_rows_may_share_times(run_cli, tmp_path):
    """Rows of track -1 (unknown origin) at one time are accepted; a labelled repeat is not."""
    cols = crossing_bearings()
    for k in cols:
        cols[k] = cols[k] + [cols[k][0], cols[k][0]]
    cols["track_id"][-2:] = [-1, -1]
    ok = write_csv(tmp_path / "ok.csv", cols)
    code, _, err = run_cli("crossings", "--bearings", ok, "--out", tmp_path / "a.csv")
    assert code == 0, err
    cols["track_id"][-1] = 0
    bad = write_csv(tmp_path / "bad.csv", cols)
    code, _, err = run_cli("smooth", "--bearings", bad, "--out", tmp_path / "s.csv")
    assert_one_line(code, err, "bad.csv", "track_id 0 has two rows at time 0")
    assert not (tmp_path / "s.csv").exists()


# --------------------------------------------------------------------------------------------
# values and files the matrix only names: the messages themselves
# --------------------------------------------------------------------------------------------
def test_huge_value_is_refused_with_the_bound(run_cli, tmp_path):
    """1e308 in a time column: one line naming line, column and the bound."""
    cols = tma_bearings()
    cols["time"][3] = "1e308"
    inp = {"bearings": write_csv(tmp_path / "b.csv", cols),
           "ownship": write_csv(tmp_path / "o.csv", ownship())}
    code, _, err = run_cli(*argv("tma", inp, tmp_path / "t.csv"))
    assert_one_line(code, err, "b.csv: line 5, column 'time'", "1e+12")


def test_long_field_is_refused_naming_the_line(run_cli, tmp_path):
    """A 200 KiB field: one line naming the file and line, not a csv traceback."""
    cols = amplitudes()
    cols["residual"][0] = "9" * (200 * 1024)
    inp = write_csv(tmp_path / "a.csv", cols)
    code, _, err = run_cli("tqi", "--amplitudes", inp, "--out", tmp_path / "q.csv")
    assert_one_line(code, err, "a.csv: line 2", "longer than 131,072 characters")


def test_sparse_file_is_refused_before_reading(run_cli, tmp_path):
    """A 2 GiB sparse file as a CSV is refused by its size, at once."""
    big = tmp_path / "big.csv"
    with big.open("wb") as fh:
        fh.truncate(2 << 30)
    t0 = time.perf_counter()
    code, _, err = run_cli("smooth", "--bearings", big, "--out", tmp_path / "s.csv")
    assert time.perf_counter() - t0 < 5.0
    assert_one_line(code, err, "big.csv", "larger than the 1 GiB limit")


def test_text_named_npz(run_cli, tmp_path):
    """A text file named ``.npz``: 'not a valid .npz file', no talk of pickles."""
    p = tmp_path / "cube.npz"
    p.write_text("power,freqs\n1,2\n")
    code, stdout, err = run_cli("acquire", "--cube", p, "--beam", "1", "--freq-hz", "100")
    assert_one_line(code, err, "cube.npz: not a valid .npz file")
    assert "pickle" not in err and stdout == ""


@pytest.mark.parametrize(("power", "dtype"), [
    (np.ones((6, 4, 3)) * (1 + 0.5j), "complex"), (np.full((6, 4, 3), "1.0"), "<U3"),
    (np.ones((6, 4, 3), dtype=bool), "bool"),
])
def test_cube_power_must_be_real(power, dtype, run_cli, tmp_path):
    """Complex, text or boolean ``power``: one line naming the array and its type."""
    p = tmp_path / "cube.npz"
    np.savez(p, power=power, freqs=np.array([100.0, 101, 102]), scan_period=1.0, aperture=20.0,
             sound_speed=1500.0)
    code, _, err = run_cli("acquire", "--cube", p, "--beam", "1", "--freq-hz", "100")
    assert_one_line(code, err, "cube.npz: 'power' must hold real numbers", dtype)
