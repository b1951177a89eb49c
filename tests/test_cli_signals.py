"""SIGTERM/SIGHUP like Ctrl-C, temporary folders of killed runs, one writer per output.

- SIGTERM and SIGHUP end a run as Ctrl-C does: its temporaries are removed, one stderr line,
  exit code 128 + signal;
- the private folders of ``--out -`` runs killed by SIGKILL (``/tmp/fusion-localize-PID-*``) are
  removed by the next run when their process is gone, never while it lives;
- two runs writing one output: the second is refused with one line naming the first's process;
  the lock of a killed run is taken over.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fusion._output import lock_path, output_lock, private_folder
from fusion.cli import EXIT_BAD_INPUT

ROOT = Path(__file__).resolve().parents[1]


def _env(tmp: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(tmp)}


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    from fusion.cli import main

    d = tmp_path_factory.mktemp("sig") / "rec"
    assert main(["simulate", "clicks", "--seed", "1", "--out", str(d)]) == 0
    return d


def _wait_for(predicate, seconds: float = 60.0) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_termination_signal_removes_temporaries(recording, tmp_path, sig):
    """``kill -TERM`` of ``fusion localize --out -`` mid-run: its temporary folder is removed."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    proc = subprocess.Popen(
        [sys.executable, "-m", "fusion", "localize", "--audio", recording / "audio.flac",
         "--array", recording / "array.json", "--out", "-", "--chunk-s", "2", "--quiet"],
        env=_env(tmp), stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    parts = lambda: list(tmp.glob(f"fusion-localize-{proc.pid}-*/parts/*"))  # noqa: E731
    assert _wait_for(parts), proc.communicate()
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    if proc.returncode == 0:  # pragma: no cover - finished before the signal arrived
        pytest.skip("the run finished before the signal")
    assert proc.returncode == 128 + sig, err
    assert err.decode().strip().splitlines() == [f"fusion: terminated (signal {int(sig)})"]
    assert out == b""
    assert list(tmp.iterdir()) == []


def test_folders_of_killed_runs_are_removed_live_ones_kept(tmp_path, monkeypatch):
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)  # read TMPDIR again
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f"fusion-localize-{dead.pid}-abc"
    (stale / "parts").mkdir(parents=True)
    live = tmp_path / f"fusion-localize-{os.getppid()}-def"
    live.mkdir()
    other = tmp_path / "fusion-localize-old"  # no process id: not ours to judge
    other.mkdir()
    with private_folder("fusion-localize-") as mine:
        assert mine.name.startswith(f"fusion-localize-{os.getpid()}-") and mine.is_dir()
        assert not stale.exists() and live.is_dir() and other.is_dir()
    assert not mine.exists()


def _hold_lock(path: Path, tmp: Path) -> subprocess.Popen:
    code = ("import sys, time; from fusion._output import output_lock\n"
            "with output_lock(sys.argv[1]):\n"
            "    print('locked', flush=True); time.sleep(120)\n")
    proc = subprocess.Popen([sys.executable, "-c", code, str(path)], env=_env(tmp),
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "locked"
    return proc


def test_second_run_on_one_output_is_refused(run_cli, recording, tmp_path):
    out = tmp_path / "loc.json"
    holder = _hold_lock(out, tmp_path)
    try:
        code, _, err = run_cli("localize", "--audio", recording / "audio.flac", "--array",
                               recording / "array.json", "--out", out, "--quiet")
    finally:
        holder.kill()
        holder.wait()
    assert code == EXIT_BAD_INPUT, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert f"another fusion run (process {holder.pid}) is writing this output" in err
    assert not out.exists() and not Path(f"{out}.parts").exists()
    # the holder was killed (SIGKILL): its lock is taken over, and released at the end
    assert lock_path(out).exists()
    with output_lock(out):
        assert lock_path(out).read_text().strip() == str(os.getpid())
    assert not lock_path(out).exists()


def test_lock_in_process_and_for_folders(tmp_path):
    folder = tmp_path / "o"
    folder.mkdir()
    with output_lock(folder):
        assert lock_path(folder) == tmp_path / ".o.fusion-lock"
    with output_lock("-"):  # standard output: nothing to lock
        pass
    assert sorted(os.listdir(tmp_path)) == ["o"]
