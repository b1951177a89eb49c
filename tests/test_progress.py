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



def _smooth_updates(run_cli, monkeypatch, tmp_path, src: Path) -> tuple[int, list[int]]:
    """(total, updates) of ``fusion smooth``'s bar on `src`, closed once at the end."""
    import fusion.commands.smooth as smooth

    seen = []

    class Bar:
        def __init__(self, total, **kwargs):
            seen.append(("total", total))

        def update(self, n=1):
            seen.append(("update", n))

        def close(self):
            seen.append(("close", None))

    monkeypatch.setattr(smooth, "progress", Bar)
    code, _, err = run_cli("smooth", "--bearings", src, "--out", tmp_path / "s.csv")
    assert code == 0, err
    assert seen[0][0] == "total" and seen[-1] == ("close", None)
    assert [k for k, _ in seen[1:-1]] == ["update"] * (len(seen) - 2)
    return seen[0][1], [n for _, n in seen[1:-1]]


def test_smooth_of_one_long_track_shows_progress_before_the_end(inputs, tmp_path, monkeypatch,
                                                                 run_cli):
    """One labelled track: the bar moves while the track is smoothed, not once at its end.

    It counts rows twice, as fitted and as smoothed; the smoothing's half moves after each
    Levenberg-Marquardt iteration and each block of marginals (was: one update per track, so a
    file of one track showed 50 % until the end)."""
    lines = (inputs / "bearings/bearings.csv").read_text().splitlines()
    one = tmp_path / "one.csv"
    rows = [r for r in lines[1:] if r.startswith("0,")]
    one.write_text("\n".join([lines[0], *rows]) + "\n")
    total, updates = _smooth_updates(run_cli, monkeypatch, tmp_path, one)
    assert total == 2 * len(rows) and sum(updates) == total
    assert updates[0] == len(rows)  # the settings fitted
    smoothing = updates[1:]
    assert len(smoothing) >= 4 and max(smoothing) <= len(rows) // 2, smoothing


def test_smooth_of_unknown_origin_rows_shows_progress_per_scan_and_track(inputs, tmp_path,
                                                                          monkeypatch, run_cli):
    """Rows of unknown origin (track -1): the bar moves over the tracker's scans and after each
    track formed (was: one update for all of them)."""
    lines = (inputs / "bearings/bearings.csv").read_text().splitlines()
    unk = tmp_path / "unk.csv"
    unk.write_text("\n".join([lines[0], *("-1" + r[r.index(","):] for r in lines[1:])]) + "\n")
    total, updates = _smooth_updates(run_cli, monkeypatch, tmp_path, unk)
    n = len(lines) - 1
    assert total == 2 * n and sum(updates) == total
    assert updates[0] == n and len(updates[1:]) >= 10 and max(updates[1:]) < n // 2, updates


@pytest.mark.parametrize("robust", ["none", "huber", "cauchy"])
def test_progress_of_the_smoothing_changes_no_number(inputs, robust):
    """The smoothed tracks are the same bit for bit with the progress callback as without."""
    import numpy as np

    from fusion.io import read_bearings
    from fusion.passive.smoothing import BearingSmoother, MultiTrackSmoother
    from fusion.passive.smoothing.table import smooth_bearings

    t = read_bearings(inputs / "bearings/bearings.csv")
    ids = np.where(t["track_id"] == 1, -1, t["track_id"])  # one track of unknown origin
    z = np.radians(t["bearing_deg"])
    kw = {"single": BearingSmoother(sigma_bearing=0.01, q=1e-8, robust=robust),
          "multi": MultiTrackSmoother(sigma_bearing=0.01, q=1e-8)}
    counted = []
    plain = smooth_bearings(ids, t["time"], z, **kw)
    shown = smooth_bearings(ids, t["time"], z, **kw, on_rows=counted.append)
    assert sum(counted) == ids.size and len(counted) > 3
    assert len(plain) == len(shown)
    for a, b in zip(plain, shown, strict=True):
        for name in ("times", "bearing", "rate", "sigma_bearing", "sigma_rate"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
