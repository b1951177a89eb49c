"""`fusion train-validator` from the command line: a labelled recording in, a usable model out."""

from __future__ import annotations

import re

import numpy as np
import pytest

from fusion.cli import EXIT_BAD_INPUT, main
from fusion.clicks.validate import TdoaValidator


def _cli(*argv: object) -> int:
    try:
        return main([str(a) for a in argv])
    except SystemExit as e:  # argparse errors
        return int(e.code or 0)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A short simulated click recording with its TDOA labels (what `fusion simulate` writes)."""
    d = tmp_path_factory.mktemp("train") / "rec"
    assert _cli("simulate", "clicks", "--seed", 2, "--out", d) == 0
    return d


def test_trains_a_model_that_loads_with_the_printed_threshold(recording, tmp_path, capsys):
    """The model loads, has the asked mixture size, the threshold printed, and is reproducible."""
    outs = []
    for k in range(2):
        out = tmp_path / f"v{k}.npz"
        capsys.readouterr()
        assert _cli("train-validator", "--recording", recording, "--out", out,
                    "--components", 1, "--quiet") == 0
        err = capsys.readouterr().err
        outs.append(out.read_bytes())
    m = re.search(r"(\d+) valid / (\d+) invalid candidates, threshold ([-\d.]+)", err)
    assert m, err
    assert int(m.group(1)) > 0 and int(m.group(2)) > 0
    v = TdoaValidator.load(tmp_path / "v0.npz")
    assert v.valid.means.shape[0] == 1 and v.invalid.means.shape[0] == 1
    assert v.threshold == pytest.approx(float(m.group(3)), abs=0.051)
    # features of the valid class score above those of the invalid class
    assert v.llr(v.valid.means * v.feature_scale + v.feature_mean)[0] > \
        v.llr(v.invalid.means * v.feature_scale + v.feature_mean)[0]
    assert np.isfinite(v.threshold)
    assert outs[0] == outs[1]  # same inputs, same model


def test_recording_without_labels_is_one_line_exit_2(recording, tmp_path, capsys):
    """A recording folder without tdoa_labels.csv: one error line, exit 2, no model written."""
    bare = tmp_path / "bare"
    bare.mkdir()
    for name in ("audio.flac", "array.json"):
        (bare / name).write_bytes((recording / name).read_bytes())
    out = tmp_path / "v.npz"
    capsys.readouterr()
    assert _cli("train-validator", "--recording", bare, "--out", out) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert not out.exists()


@pytest.mark.parametrize("labels", ["far", "none"])
def test_training_that_fails_after_reading_prints_only_its_error(recording, tmp_path, capsys,
                                                                  labels):
    """Training that fails once the recordings are read (no candidate labelled valid, or no
    candidate at all): the error is the only stderr line (was: each recording's count line
    ``rec/audio.flac: 53 candidate TDOAs, 0 valid so far`` first), no model written."""
    rec = tmp_path / "rec"
    rec.mkdir()
    for name in ("audio.flac", "array.json", "tdoa_labels.csv"):
        (rec / name).write_bytes((recording / name).read_bytes())
    if labels == "far":  # every label 1 s off any candidate's delay: nothing valid
        lines = (rec / "tdoa_labels.csv").read_text().splitlines()
        head = lines[0].split(",")
        k = head.index("tau")
        rows = [r.split(",") for r in lines[1:]]
        for r in rows:
            r[k] = "1.0"
        (rec / "tdoa_labels.csv").write_text("\n".join([lines[0], *map(",".join, rows)]) + "\n")
        extra = ()
    else:  # silence: no click, no candidate at all
        import soundfile as sf

        audio, fs = sf.read(rec / "audio.flac")
        sf.write(rec / "audio.flac", np.zeros_like(audio), fs)
        extra = ()
    out = tmp_path / "v.npz"
    capsys.readouterr()
    assert _cli("train-validator", "--recording", rec, "--out", out, "--quiet",
                *extra) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "error:" in err and "so far" not in err, err
    assert not out.exists()
