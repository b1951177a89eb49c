"""The one output guard (:func:`fusion.cli.check_paths`) covers every output of a command.

Files written inside an ``--out`` folder, extra output options (``--replica-out``) and the files
read inside a folder input (``--recording DIR``) are checked against every input and against each
other before any work: exit 2, one stderr line, nothing written, nothing changed.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from fusion.cli import EXIT_BAD_INPUT


def _snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    """Every file under `folder`: its bytes and modification time."""
    return {str(p.relative_to(folder)): (p.read_bytes(), p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(run_cli, folder: Path, *argv: object, words: tuple[str, ...]) -> str:
    before = _snapshot(folder)
    code, out, err = run_cli(*argv)
    assert code == EXIT_BAD_INPUT, (code, err)
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    assert _snapshot(folder) == before
    return err


@pytest.fixture(scope="module")
def passive_files(tmp_path_factory) -> Path:
    from fusion.cli import main

    d = tmp_path_factory.mktemp("guard") / "p"
    assert main(["simulate", "passive", "--seed", "1", "--out", str(d)]) == 0
    return d


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    from fusion.cli import main

    d = tmp_path_factory.mktemp("guard") / "rec"
    assert main(["simulate", "clicks", "--seed", "1", "--out", str(d)]) == 0
    return d


@pytest.mark.parametrize("name", ["tracks.csv", "alerts.csv"])
def test_passive_input_inside_its_out_folder_is_refused(run_cli, passive_files, tmp_path, name):
    """``--clicks out/tracks.csv --out out`` (and ``--cube out/alerts.csv``) would replace it."""
    out = tmp_path / "out"
    out.mkdir()
    (out / name).write_bytes((passive_files / "clicks.csv").read_bytes())
    assert _refused(run_cli, tmp_path, "passive", "--cube", passive_files / "cube.npz",
                    "--clicks", out / name, "--out", out, "--quiet",
                    words=(name, "--clicks", "input"))
    (tmp_path / "x").mkdir()
    assert _refused(run_cli, tmp_path, "passive", "--cube", out / name, "--click", "1,100",
                    "--out", tmp_path / "x" / ".." / "out", "--quiet", words=(name, "--cube"))


def test_passive_writes_both_tables(run_cli, passive_files, tmp_path):
    code, _, err = run_cli("passive", "--cube", passive_files / "cube.npz", "--clicks",
                           passive_files / "clicks.csv", "--out", tmp_path / "o", "--quiet")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == [
        "alerts.csv", "passive.settings.json", "tracks.csv"]
    settings = json.loads((tmp_path / "o" / "passive.settings.json").read_text())
    assert settings["normalize"][str(passive_files / "cube.npz")]["normalized"] is False


@pytest.mark.parametrize("name", ["audio.flac", "array.json", "tdoa_labels.csv"])
@pytest.mark.parametrize("option", ["--out", "--replica-out"])
def test_train_validator_output_onto_a_recording_file_is_refused(run_cli, recording, tmp_path,
                                                                 name, option):
    argv = {"--out": tmp_path / "v.npz", "--replica-out": tmp_path / "r.npz"}
    argv[option] = recording / name
    _refused(run_cli, recording.parent, "train-validator", "--recording", recording,
             *[x for kv in argv.items() for x in kv], "--quiet",
             words=(option, f"(its {name})", "refusing to overwrite an input"))
    assert not (tmp_path / "v.npz").exists() and not (tmp_path / "r.npz").exists()


def test_train_validator_two_outputs_onto_one_file_are_refused(run_cli, recording, tmp_path):
    (tmp_path / "v.npz").write_bytes(b"keep")
    link = tmp_path / "link.npz"
    link.symlink_to(tmp_path / "v.npz")
    for other in (tmp_path / "v.npz", tmp_path / "sub" / ".." / "v.npz", link):
        if other.parent.name == "sub":
            (tmp_path / "sub").mkdir(exist_ok=True)
        _refused(run_cli, tmp_path, "train-validator", "--recording", recording,
                 "--out", tmp_path / "v.npz", "--replica-out", other, "--quiet",
                 words=("--replica-out", "same file as --out"))
    code, _, err = run_cli("train-validator", "--recording", recording, "--out", "v.npz",
                           "--replica-out", "-", "--quiet")
    assert code == EXIT_BAD_INPUT and "--replica-out -" in err


def test_train_validator_writes_exact_names_into_new_folders(run_cli, recording, tmp_path):
    """``--out new/x.npz --replica-out new2/r`` creates the folders, writes exactly those names."""
    from fusion.clicks.replica import load_replica
    from fusion.clicks.validate import TdoaValidator

    out, rep = tmp_path / "new" / "x.npz", tmp_path / "new2" / "r"
    code, _, err = run_cli("train-validator", "--recording", recording, "--out", out,
                           "--replica-out", rep, "--components", 1, "--quiet")
    assert code == 0, err
    assert f"-> {rep}" in err
    assert sorted(p.name for p in rep.parent.iterdir()) == ["r"]
    assert np.isfinite(TdoaValidator.load(out).threshold)
    assert load_replica(rep).samples.size > 0
    assert not [p for p in tmp_path.rglob("*") if "fusion-tmp" in p.name]


def test_train_validator_replica_without_recording_is_refused_before_work(run_cli, tmp_path):
    code, _, err = run_cli("train-validator", "--simulated", 1, "--out", tmp_path / "v.npz",
                           "--replica-out", tmp_path / "r.npz", "--quiet")
    assert code == EXIT_BAD_INPUT and "--replica-out" in err, err
    assert os.listdir(tmp_path) == []
