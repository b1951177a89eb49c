"""Progress bars of the long commands: shown on a terminal, never with --quiet or in a pipe."""

from __future__ import annotations

import fcntl
import os
import pty
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

from fusion._progress import progress, track_progress

ROOT = Path(__file__).resolve().parents[1]


def _fusion(*argv: object, tty: bool) -> tuple[int, str]:
    """Run ``fusion`` in a subprocess; standard error a pseudo-terminal when `tty`."""
    cmd = [sys.executable, "-m", "fusion", *map(str, argv)]
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "COLUMNS": "100"}
    if not tty:
        p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
        return p.returncode, p.stderr
    main, sub = pty.openpty()
    fcntl.ioctl(sub, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # rows, columns
    try:
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=sub, env=env, cwd=ROOT)
        os.close(sub)
        chunks = []
        while True:
            try:
                data = os.read(main, 65536)
            except OSError:  # the child closed its end
                break
            if not data:
                break
            chunks.append(data)
        return p.wait(timeout=300), b"".join(chunks).decode(errors="replace")
    finally:
        os.close(main)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    """Small simulated inputs of tqi, crossings and track."""
    d = tmp_path_factory.mktemp("progress")
    for kind in ("amplitudes", "bearings", "multistatic", "passive"):
        code, err = _fusion("simulate", kind, "--seed", 3, "--out", d / kind, tty=False)
        assert code == 0, err
    return d


COMMANDS = {
    "tqi": ("tqi", "--amplitudes", "amplitudes/amplitudes.csv", "row"),
    "crossings": ("crossings", "--bearings", "bearings/bearings.csv", "row"),
    "track": ("track", "--detections", "multistatic/detections.csv", "ping"),
    "smooth": ("smooth", "--bearings", "bearings/bearings.csv", "row"),
    "passive": ("passive", "--cube", "passive/cube.npz", "scan"),
}


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_bar_on_a_terminal_none_when_quiet_or_piped(inputs, tmp_path, name):
    """A tqdm bar (its unit and rate) on a terminal; none with --quiet (or piped); same output."""
    command, flag, rel, unit = COMMANDS[name]
    outs = {}
    for mode in ("tty", "quiet", "pipe") if name == "tqi" else ("tty", "quiet"):
        out = tmp_path / f"{mode}.csv"
        extra = ["--clicks", inputs / "passive/clicks.csv"] if command == "passive" else []
        argv = [command, flag, inputs / rel, *extra, "--out", out,
                *(["--quiet"] if mode == "quiet" else [])]
        code, err = _fusion(*argv, tty=mode != "pipe")
        assert code == 0, err
        shown = f"{unit}/s]" in err or f"{unit}s/s]" in err
        assert shown == (mode == "tty"), (mode, err)
        outs[mode] = (out / "tracks.csv" if out.is_dir() else out).read_bytes()
    assert len(set(outs.values())) == 1


def test_progress_stand_in_counts_nothing_and_iterates_everything(monkeypatch):
    """Without a terminal the bar is a stand-in; track_progress still yields every item in order."""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    bar = progress(10)
    assert not hasattr(bar, "n")
    assert list(track_progress(iter(range(7)), weight=lambda i: i)) == list(range(7))


def test_progress_on_a_terminal_counts_weights(monkeypatch, capsys):
    """On a terminal the bar is tqdm and counts the items' weights; --quiet gives the stand-in."""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    bar = progress(None, unit="row")
    bar.update(5)
    bar.update(2)
    assert bar.n == 7
    bar.close()
    assert not hasattr(progress(3, quiet=True), "n")



def test_smooth_of_one_long_track_shows_progress_before_the_end(inputs, tmp_path, monkeypatch,
                                                                 run_cli):
    """One labelled track: the bar moves (settings fitted) before the track's smoothing ends.

    It counts rows twice, as fitted and as smoothed (was: one update, 0 % then 100 %).
    """
    import fusion.commands.smooth as smooth

    lines = (inputs / "bearings/bearings.csv").read_text().splitlines()
    one = tmp_path / "one.csv"
    rows = [r for r in lines[1:] if r.startswith("0,")]
    one.write_text("\n".join([lines[0], *rows]) + "\n")
    seen = []

    class Bar:
        def __init__(self, total, **kwargs):
            seen.append(("total", total))

        def update(self, n=1):
            seen.append(("update", n))

        def close(self):
            seen.append(("close", None))

    monkeypatch.setattr(smooth, "progress", Bar)
    code, _, err = run_cli("smooth", "--bearings", one, "--out", tmp_path / "s.csv")
    assert code == 0, err
    assert seen == [("total", 2 * len(rows)), ("update", len(rows)), ("update", len(rows)),
                    ("close", None)]
