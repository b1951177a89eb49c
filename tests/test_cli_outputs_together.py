"""All outputs of a run are committed together, or none; a full disk is one line naming the file.

A full disk is simulated by a writer that raises ``OSError(ENOSPC)`` (or libsndfile's
``System error``) on its n-th call, after the first outputs of the run were written.
"""

import errno

import pytest

from fusion._output import TMP_MARK, atomic_output, outputs_together


def _fail_on_call(monkeypatch, owner, name, n, exc):
    """Make ``owner.name`` raise `exc` from its `n`-th call (the earlier calls work)."""
    real = getattr(owner, name)
    calls = {"n": 0}

    def writer(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] >= n:
            raise exc
        return real(*args, **kwargs)

    monkeypatch.setattr(owner, name, writer)
    return calls


def _enospc():
    return OSError(errno.ENOSPC, "No space left on device")  # no file name, as writers raise it


def _files(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))


@pytest.fixture
def sims(run_cli, tmp_path_factory):
    root = tmp_path_factory.mktemp("sims")
    for kind in ("amplitudes", "bearings", "passive"):
        assert run_cli("simulate", kind, "--seed", "1", "--out", root / kind)[0] == 0
    assert run_cli("tqi", "--amplitudes", root / "amplitudes" / "amplitudes.csv", "--out",
                   root / "tqi.csv")[0] == 0
    return root


def _argv(command, sims, data_dir, out):
    return {
        "import": ("import", "autoferry", data_dir / "autoferry_raw" / "scenario2", "--out", out),
        "simulate-tma": ("simulate", "tma", "--seed", "1", "--out", out),
        "passive": ("passive", "--cube", sims / "passive" / "cube.npz", "--clicks",
                    sims / "passive" / "clicks.csv", "--out", out),
        "tqi": ("tqi", "--amplitudes", sims / "amplitudes" / "amplitudes.csv", "--out",
                out / "deeper" / "q.csv"),
    }[command]


@pytest.mark.parametrize("command", ["import", "simulate-tma", "passive", "tqi"])
def test_full_disk_leaves_no_file_and_no_folder(command, run_cli, sims, data_dir, tmp_path,
                                                monkeypatch):
    """ENOSPC on the second CSV (the first on tqi): one line naming the file; nothing left."""
    import fusion.io.tables as tables

    out = tmp_path / "new" / "out"
    _fail_on_call(monkeypatch, tables, "_write_rows", 1 if command == "tqi" else 2, _enospc())
    code, _, err = run_cli(*_argv(command, sims, data_dir, out))
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert "No space left on device" in err and str(out) in err and "[Errno" not in err, err
    assert _files(tmp_path) == []  # no file, no temporary, no folder


def test_full_disk_keeps_an_existing_output_folder_unchanged(run_cli, tmp_path, monkeypatch):
    import fusion.io.tables as tables

    out = tmp_path / "out"
    assert run_cli("simulate", "tma", "--seed", "1", "--out", out)[0] == 0
    before = {p: p.read_bytes() for p in out.iterdir()}
    _fail_on_call(monkeypatch, tables, "_write_rows", 2, _enospc())
    code, _, err = run_cli("simulate", "tma", "--seed", "2", "--out", out)
    assert code == 2 and "No space left on device" in err
    assert {p: p.read_bytes() for p in out.iterdir()} == before


def test_full_disk_while_writing_audio_is_one_line(run_cli, tmp_path, monkeypatch):
    """simulate clicks: libsndfile's 'System error' (was: a LibsndfileError traceback)."""
    import soundfile

    _fail_on_call(monkeypatch, soundfile, "write", 1, soundfile.LibsndfileError(2))
    out = tmp_path / "new" / "clicks"
    code, _, err = run_cli("simulate", "clicks", "--seed", "1", "--duration-s", "2",
                           "--out", out)
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert f"{out / 'audio.flac'}: audio could not be written" in err, err
    assert _files(tmp_path) == []


def test_report_full_disk_on_the_second_figure(run_cli, sims, tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    _fail_on_call(monkeypatch, Figure, "savefig", 2, _enospc())
    out = tmp_path / "figs"
    code, _, err = run_cli("report", sims / "tqi.csv", "--bearings",
                           sims / "bearings" / "bearings.csv", "--out", out)
    assert code == 2 and "tqi_bearing_time.png: No space left on device" in err, err
    assert _files(tmp_path) == []


@pytest.mark.parametrize("result", ["tqi.csv", "crossings.csv"])
def test_report_with_a_bad_extra_input_writes_no_figure(result, run_cli, sims, tmp_path):
    """report RESULT --bearings bad.csv: one line, no tqi.png (was: tqi.png, then exit 2)."""
    if result == "crossings.csv":
        assert run_cli("crossings", "--bearings", sims / "bearings" / "bearings.csv", "--out",
                       sims / "crossings.csv")[0] == 0
    bad = tmp_path / "bad.csv"
    bad.write_text("track_id,time,bearing_deg\n")
    code, _, err = run_cli("report", sims / result, "--bearings", bad, "--out", tmp_path / "f")
    assert code == 2 and f"{bad}: no data rows" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "f").exists()


def test_outputs_together_commits_all_or_none(tmp_path):
    """Library level: nothing is renamed before the block ends; a failure leaves nothing."""
    a, b = tmp_path / "x" / "a.txt", tmp_path / "x" / "y" / "b.txt"
    with pytest.raises(RuntimeError), outputs_together(tmp_path / "x"):
        with atomic_output(a) as tmp:
            tmp.write_text("a")
        assert not a.exists()  # held until the block ends
        raise RuntimeError("late bad input")
    assert _files(tmp_path) == []
    with outputs_together(tmp_path / "x"):
        for p in (a, b):
            with atomic_output(p) as tmp:
                tmp.write_text(p.name)
    assert a.read_text() == "a.txt" and b.read_text() == "b.txt"
    assert not [p for p in tmp_path.rglob("*") if TMP_MARK in p.name]


def test_enospc_names_the_destination_not_the_temporary(tmp_path):
    with pytest.raises(OSError) as info, atomic_output(tmp_path / "new" / "o.csv"):
        raise _enospc()
    assert info.value.filename == str(tmp_path / "new" / "o.csv")
    assert info.value.errno == errno.ENOSPC
    assert not (tmp_path / "new").exists()  # the folder made for it is removed again


# --------------------------------------------------------------------------------------------
# options bounded to plausible ranges; localize --audio DIR declares its outputs
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [
    ("tqi", "--snr0-db", "1e300"),
    ("tqi", "--snr1-db", "101"),
    ("tqi", "--tu", "1e300"),
    ("tqi", "--n-looks", "1000000"),
    ("crossings", "--windows", "100000"),
    ("crossings", "--horizon-s", "1e300"),
    ("smooth", "--accel-psd-deg2-per-s3", "1e300"),
    ("smooth", "--max-gap-scans", "1000000000"),
    ("tma", "--accel-psd-m2-per-s3", "1e300"),
    ("track", "--map-memory-pings", "1000000000"),
    ("simulate", "--snr-db", "1e300"),
])
def test_option_beyond_its_plausible_range_is_a_usage_error(argv, run_cli, tmp_path):
    """--snr0-db 1e300 (was: success with an overflow warning), --windows 100000 (40 GiB)."""
    command, option, value = argv
    needs = {"tqi": ("--amplitudes",), "crossings": ("--bearings",), "smooth": ("--bearings",),
             "tma": ("--bearings", "--ownship"), "track": ("--detections",),
             "simulate": ()}[command]
    (tmp_path / "x.csv").write_text("a\n1\n")
    args = [command, *(["clicks"] if command == "simulate" else [])]
    for n in needs:
        args += [n, tmp_path / "x.csv"]
    code, _, err = run_cli(*args, f"{option}={value}", "--out", tmp_path / "o")
    assert code == 2 and f"argument {option}" in err and "must be" in err, err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_localize_folder_outputs_are_declared_to_the_guard(tmp_path):
    """--audio DIR --array OUT/x.json --out OUT: OUT/x.json would become x.flac's result."""
    from fusion.cli import _option_names, build_parser, check_paths

    rec, out = tmp_path / "rec", tmp_path / "out"
    rec.mkdir()
    out.mkdir()
    (rec / "x.flac").write_bytes(b"")
    (out / "x.json").write_text("{}")
    parser = build_parser("localize")
    args = parser.parse_args(["localize", "--audio", str(rec), "--array", str(out / "x.json"),
                              "--out", str(out)])
    assert "x.json" in args.out_files and "localize.settings.json" in args.out_files
    sub = next(a for a in parser._actions if a.dest == "command")
    with pytest.raises(ValueError, match=r"its x\.json\) is the same file as the input --array"):
        check_paths(args, _option_names(sub.choices["localize"]))
