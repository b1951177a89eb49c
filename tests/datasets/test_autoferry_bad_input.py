"""``fusion import autoferry`` on bad recordings: one line naming the file, nothing written.

Every number read is finite and plausible before anything is written; a folder of scenarios is
written all together or not at all; a scenario without ground truth is imported without its
truth files, with one warning line (docs/bad-input.md).
"""

import json
import math
import shutil

import pytest

from fusion.datasets.autoferry_files import FILES

RAW = "autoferry_raw/scenario2"
DET = "scenario2_detections.json"
GT = "scenario2_groundTruth.json"


def _radar(det):
    return next(i for i, s in enumerate(det) if s["sensorID"] == 2 and s["measurement"])


def _eo(det):
    return next(i for i, s in enumerate(det) if s["sensorID"] == 4 and s["measurement"])


def _set(key, value, index=5):
    def edit(det, gt):
        det[index][key] = value
    return edit


def _own(value):
    def edit(det, gt):
        det[5]["ownshipPosition"][0] = value
    return edit


def _meas(value, which=_radar):
    def edit(det, gt):
        det[which(det)]["measurement"] = value
    return edit


def _gt(value):
    def edit(det, gt):
        return value  # the whole ground-truth document
    return edit


def _gt_target(key, value):
    def edit(det, gt):
        gt[3][0][key] = value
    return edit


#: name -> (edit of the decoded files, file named, words of the message)
CASES = {
    "time-nan": (_set("time", math.nan), DET, "scan 5: 'time' is nan"),
    "time-1e308": (_set("time", 1e308), DET, "scan 5: 'time' = 1e+308 is not a Unix time"),
    "time-far": (_set("time", 1e9), DET, "a scenario spans at most"),
    "time-text": (_set("time", "x"), DET, "'time' is 'x', not a number"),
    "ownship-nan": (_own(math.nan), DET, "'ownshipPosition' value is nan"),
    "ownship-1e308": (_own(1e308), DET, "'ownshipPosition' value = 1e+308 is beyond"),
    "ownship-one-value": (_set("ownshipPosition", [1.0]), DET, "'ownshipPosition' has 1 values"),
    "sensor-unknown": (_set("sensorID", 7), DET, "unknown 'sensorID' 7"),
    "radar-3-values": (_meas([1.0, 2.0, 3.0]), DET, "(radar): 'measurement' has 3 values"),
    "radar-6-values": (_meas([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]), DET, "has 6 values"),
    "radar-3-rows": (_meas([[1.0], [2.0], [3.0]]), DET, "has rows of [1, 1, 1] values"),
    "radar-nan": (_meas([[math.nan], [1.0]]), DET, "'measurement' value is nan"),
    "radar-1e308": (_meas([[1e308], [1.0]]), DET, "'measurement' value = 1e+308 is beyond"),
    "radar-text": (_meas("abc"), DET, "'measurement' is 'abc'"),
    "bearing-1e308": (_meas([1e308], _eo), DET, "(EO): bearing = 1e+308 is beyond"),
    "bearing-degrees": (_meas([90.0], _eo), DET, "bearing = 90 is beyond"),
    "gt-dict": (_gt({"a": 1}), GT, "is dict, expected a list"),
    "gt-wrong-length": (_gt([[{"targetID": 1, "position": [1, 2, 0], "time": 1620114892.0}]]),
                        GT, "has 1 entries, scenario2_detections.json has 120 scans"),
    "gt-numbers": (lambda det, gt: [[1, 2, 3]] * len(gt), GT,
                   "entry 0: 1 is not a target"),
    "gt-position-nan": (_gt_target("position", [math.nan, 1.0, 0.0]), GT,
                        "entry 3: 'position' value is nan"),
    "gt-position-1e308": (_gt_target("position", [1e308, 1.0, 0.0]), GT, "is beyond"),
    "gt-position-one-value": (_gt_target("position", [1.0]), GT, "'position' has 1 values"),
    "gt-time-far": (_gt_target("time", 1e9), GT, "the ground truth of another recording"),
}


def _bad_copy(data_dir, folder, edit):
    shutil.copytree(data_dir / RAW, folder)
    det = json.loads((folder / DET).read_text())
    gt = json.loads((folder / GT).read_text())
    new = edit(det, gt)
    gt = gt if new is None else new
    (folder / DET).write_text(json.dumps(det))  # NaN and 1e308 as JSON writes them
    (folder / GT).write_text(json.dumps(gt))


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_recording_is_one_line_naming_the_file(case, run_cli, data_dir, tmp_path):
    """Not finite, implausible, of the wrong shape: exit 2, one line naming file and scan."""
    edit, name, words = CASES[case]
    _bad_copy(data_dir, tmp_path / "rec", edit)
    code, out, err = run_cli("import", "autoferry", tmp_path / "rec", "--out", tmp_path / "o")
    assert code == 2, (out, err)
    assert len(err.strip().splitlines()) == 1, err
    assert f"{tmp_path / 'rec' / name}:" in err and words in err, err
    assert not (tmp_path / "o").exists()


def test_folder_with_one_bad_scenario_writes_nothing(run_cli, data_dir, tmp_path):
    """A good scenario beside a bad one: nothing written, not even the good one's folder."""
    shutil.copytree(data_dir / RAW, tmp_path / "rec" / "a_good")
    _bad_copy(data_dir, tmp_path / "rec" / "b_bad", CASES["time-nan"][0])
    code, _, err = run_cli("import", "autoferry", tmp_path / "rec", "--out", tmp_path / "o")
    assert code == 2 and "b_bad" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "o").exists()
    # an existing output folder keeps exactly what it had
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "keep.txt").write_text("x")
    code, _, _ = run_cli("import", "autoferry", tmp_path / "rec", "--out", tmp_path / "o")
    assert code == 2
    assert [p.name for p in (tmp_path / "o").iterdir()] == ["keep.txt"]


def test_scenario_without_ground_truth_is_imported_with_a_note(run_cli, data_dir, tmp_path):
    """No *_groundTruth.json: the detections are imported, the truth files are not, one note."""
    shutil.copytree(data_dir / RAW, tmp_path / "rec" / "a")
    shutil.copytree(data_dir / RAW, tmp_path / "rec" / "b")
    (tmp_path / "rec" / "b" / GT).unlink()
    code, out, err = run_cli("import", "autoferry", tmp_path / "rec", "--out", tmp_path / "o")
    assert code == 0, err
    assert "b: t0" in out  # not skipped
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "warning" in lines[0] and "no ground truth" in lines[0], err
    assert "truth.csv, truth_bearings.csv not written" in lines[0]
    written = sorted(p.name for p in (tmp_path / "o" / "b").iterdir())
    assert written == sorted({*FILES, "import.json"} - {"truth.csv", "truth_bearings.csv"})
    doc = json.loads((tmp_path / "o" / "b" / "import.json").read_text())
    assert set(doc["not_written"]) == {"truth.csv", "truth_bearings.csv"}
    assert (tmp_path / "o" / "a" / "truth.csv").exists()
    # the next command reads every file written
    code, _, err = run_cli("smooth", "--bearings", tmp_path / "o" / "b" / "ir_bearings.csv",
                           "--out", tmp_path / "s.csv")
    assert code == 0, err


def test_stale_truth_of_an_earlier_import_is_refused(run_cli, data_dir, tmp_path):
    """truth.csv of another recording in --out is not left beside the new files."""
    shutil.copytree(data_dir / RAW, tmp_path / "rec")
    assert run_cli("import", "autoferry", tmp_path / "rec", "--out", tmp_path / "o")[0] == 0
    (tmp_path / "rec" / GT).unlink()
    before = (tmp_path / "o" / "radar.csv").stat().st_mtime_ns
    code, _, err = run_cli("import", "autoferry", tmp_path / "rec", "--out", tmp_path / "o")
    assert code == 2 and "truth.csv: exists" in err and len(err.strip().splitlines()) == 1
    assert (tmp_path / "o" / "radar.csv").stat().st_mtime_ns == before


def test_empty_ground_truth_names_the_file(run_cli, data_dir, tmp_path):
    """An empty ground truth (was: 'need at least one array to concatenate') is no truth."""
    _bad_copy(data_dir, tmp_path / "rec", _gt([]))
    code, _, err = run_cli("import", "autoferry", tmp_path / "rec", "--out", tmp_path / "o")
    assert code == 0 and f"{tmp_path / 'rec' / GT} holds no GNSS fix" in err, err


def test_ground_truth_only_folder_is_not_skipped_silently(run_cli, data_dir, tmp_path):
    shutil.copytree(data_dir / RAW, tmp_path / "rec" / "a")
    (tmp_path / "rec" / "b").mkdir()
    shutil.copy(data_dir / RAW / GT, tmp_path / "rec" / "b" / GT)
    code, _, err = run_cli("import", "autoferry", tmp_path / "rec", "--out", tmp_path / "o")
    assert code == 2 and "no *_detections.json" in err and str(tmp_path / "rec" / "b") in err
    assert not (tmp_path / "o").exists()
