"""Bad input to every ``fusion`` subcommand: one stderr line, exit code 2, no output left behind.

The matrix below crosses each subcommand with the ways its input can be wrong: a missing file, a
directory where a file is expected, an empty file, a header without rows, a missing required
column, NaN / infinity / text in a numeric column, option values out of range, and the
command-specific cases (a beam or frequency outside the cube, own-ship positions that do not cover
the bearing times, a single sample per track, ...). Every case must give

- exit code 2,
- exactly one non-empty line on stderr, naming the file or the option at fault,
- no traceback,
- no output: the output path does not exist afterwards (and no temporary file is left beside it);
  an output that existed before is unchanged.

Output paths: a missing output folder is created (like ``mkdir -p``), so ``--out new/dir/x.csv``
works; an output path that cannot be written (its parent is a file, it is itself a folder) is bad
input and is reported before any work is done.

All inputs are tiny, so the whole file runs in a few seconds.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from fusion.cli import EXIT_BAD_INPUT

# --------------------------------------------------------------------------------------------
# valid inputs (small)
# --------------------------------------------------------------------------------------------
Columns = dict[str, list]


def _crossing_bearings() -> Columns:
    """Two tracks crossing, 30 samples 10 s apart."""
    t = np.arange(30) * 10.0
    cols: Columns = {"track_id": [], "time": [], "bearing_deg": []}
    for k, (b0, rate) in enumerate(((40.0, 0.1), (70.0, -0.1))):
        cols["track_id"] += [k] * t.size
        cols["time"] += t.tolist()
        cols["bearing_deg"] += (b0 + rate * t).tolist()
    return cols


def _smooth_bearings() -> Columns:
    """One track, 15 samples."""
    t = np.arange(15) * 10.0
    return {"track_id": [0] * t.size, "time": t.tolist(), "bearing_deg": (30 + 0.05 * t).tolist()}


def _amplitudes() -> Columns:
    """One track, 20 updates."""
    rng = np.random.default_rng(1)
    return {"track_id": [0] * 20, "time": list(range(20)),
            "amplitude": (10 * rng.exponential(size=20)).tolist(),
            "residual": rng.normal(0, 0.5, 20).tolist()}


def _ownship() -> Columns:
    """Own-ship leg east then north, every 5 s over 0..600 s."""
    t = np.arange(0, 601, 5.0)
    x = np.where(t <= 300, 5.0 * t, 1500.0)
    y = np.where(t <= 300, 0.0, 5.0 * (t - 300))
    return {"time": t.tolist(), "x": x.tolist(), "y": y.tolist()}


def _tma_bearings() -> Columns:
    """True bearings of a target at (4000, 6000) m moving south-west, every 20 s over 0..600 s."""
    os_ = _ownship()
    t = np.arange(0, 601, 20.0)
    ox = np.interp(t, os_["time"], os_["x"])
    oy = np.interp(t, os_["time"], os_["y"])
    tx, ty = 4000.0 - 2.0 * t, 6000.0 - 3.0 * t
    return {"time": t.tolist(), "bearing_deg": np.degrees(np.arctan2(tx - ox, ty - oy)).tolist()}


def _detections() -> Columns:
    """A target moving east, seen in 6 pings with one clutter point per ping."""
    cols: Columns = {"event": [], "time": [], "x": [], "y": []}
    for k in range(6):
        for x, y in ((1000.0 + 50 * k, 2000.0), (-3000.0 + 900 * k, 500.0 * k)):
            cols["event"].append(k)
            cols["time"].append(60.0 * k)
            cols["x"].append(x)
            cols["y"].append(y)
    return cols


CSV_INPUTS: dict[str, Callable[[], Columns]] = {
    "crossings.bearings": _crossing_bearings,
    "smooth.bearings": _smooth_bearings,
    "tqi.amplitudes": _amplitudes,
    "tma.bearings": _tma_bearings,
    "tma.ownship": _ownship,
    "track.detections": _detections,
}


def write_csv(path: Path, cols: Columns) -> Path:
    """Write columns as CSV (values written as given, so strings like 'nan' pass through)."""
    names = list(cols)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for row in zip(*(cols[n] for n in names), strict=True):
            w.writerow(row)
    return path


CUBE_SHAPE = (24, 12, 6)  # scans, beams, bins
CUBE_FREQS = 100.0 + np.arange(CUBE_SHAPE[2])


def write_cube_npz(path: Path, **override) -> Path:
    """A small noise cube with a line in it, as ``.npz``; keyword arguments replace arrays."""
    rng = np.random.default_rng(3)
    power = rng.exponential(size=CUBE_SHAPE)
    for s in range(CUBE_SHAPE[0]):
        power[s, 2 + s // 4, 2] += 8.0
    d = {"power": power, "freqs": CUBE_FREQS, "scan_period": 1.0, "aperture": 20.0,
         "sound_speed": 1500.0}
    d.update(override)
    d = {k: v for k, v in d.items() if v is not None}
    with path.open("wb") as fh:
        np.savez(fh, **d)
    return path


# --------------------------------------------------------------------------------------------
# command lines
# --------------------------------------------------------------------------------------------
#: subcommand -> (input options, has --out file)
COMMANDS: dict[str, tuple[tuple[str, ...], bool]] = {
    "crossings": (("bearings",), True),
    "smooth": (("bearings",), True),
    "tqi": (("amplitudes",), True),
    "tma": (("bearings", "ownship"), True),
    "track": (("detections",), True),
    "acquire": (("cube",), False),
}


def valid_inputs(cmd: str, tmp: Path) -> dict[str, Path]:
    """Write the valid input files of `cmd` into `tmp`; option name -> path."""
    paths = {}
    for opt in COMMANDS[cmd][0]:
        if cmd == "acquire":
            paths[opt] = write_cube_npz(tmp / "cube.npz")
        else:
            paths[opt] = write_csv(tmp / f"{opt}.csv", CSV_INPUTS[f"{cmd}.{opt}"]())
    return paths


def command_line(cmd: str, inputs: dict[str, Path], out: Path | None, extra=()) -> list[str]:
    argv = [cmd]
    for opt, p in inputs.items():
        argv += [f"--{opt}", str(p)]
    if cmd == "acquire":
        argv += ["--beam", "4", "--freq-hz", "102"]
    if out is not None:
        argv += ["--out", str(out)]
    return argv + [str(a) for a in extra]


def assert_bad_input(code: int, err: str, mention: str, outputs: list[Path]) -> None:
    """The standard's checks: exit 2, one line naming `mention`, no traceback, no output."""
    lines = err.splitlines()
    assert code == EXIT_BAD_INPUT, f"exit code {code}, stderr: {err!r}"
    assert "Traceback" not in err, err
    assert len(lines) == 1 and lines[0].strip(), f"expected one stderr line, got {err!r}"
    assert mention in lines[0], f"{mention!r} not named in {lines[0]!r}"
    for out in outputs:
        assert not out.exists(), f"{out} left behind"
        if out.parent.is_dir():
            leftovers = [p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}.")]
            assert not leftovers, f"temporary files left: {leftovers}"


# --------------------------------------------------------------------------------------------
# the matrix
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Case:
    """One bad-input case: how to spoil a valid command line, and what the error must name.

    ``spoil(tmp, inputs) -> (inputs, extra_args, mention)``: the spoiled input files, extra
    command-line words, and the text (file name or option) the error line must contain.
    """

    cmd: str
    name: str
    spoil: Callable[[Path, dict[str, Path]], tuple[dict[str, Path], list[str], str]]


def _replace(opt: str, make: Callable[[Path], Path]):
    def spoil(tmp, inputs):
        p = make(tmp)
        return {**inputs, opt: p}, [], p.name

    return spoil


def _missing(tmp: Path) -> Path:
    return tmp / "no_such_file.csv"


def _directory(tmp: Path) -> Path:
    d = tmp / "a_directory"
    d.mkdir()
    return d


def _text(content: str, name: str = "bad.csv"):
    def make(tmp: Path) -> Path:
        p = tmp / name
        p.write_text(content)
        return p

    return make


def _table_variant(cmd: str, opt: str, kind: str):
    """A spoiled copy of the valid table of ``cmd --opt``."""

    def make(tmp: Path) -> Path:
        cols = CSV_INPUTS[f"{cmd}.{opt}"]()
        names = list(cols)
        numeric = names[-1]
        if kind == "header":
            cols = {k: [] for k in names}
        elif kind == "nocol":
            del cols[numeric]
        elif kind in ("nan", "inf", "-inf", "abc", "", "1e308", "-1e13"):
            cols[numeric] = list(cols[numeric])
            cols[numeric][1] = kind
        elif kind == "long-field":  # one cell over the csv module's 128 KiB field limit
            cols[numeric] = list(cols[numeric])
            cols[numeric][1] = "1" * (200 * 1024)
        elif kind == "duplicate-time":  # the second row repeated: same track, same time
            cols = {k: [v[0], v[1], *v[1:]] for k, v in cols.items()}
        elif kind == "single":  # one sample per track
            ids = np.asarray(cols["track_id"])
            first = [int(np.flatnonzero(ids == k)[0]) for k in np.unique(ids)]
            cols = {k: [v[i] for i in first] for k, v in cols.items()}
        elif kind == "two_rows":
            cols = {k: v[:2] for k, v in cols.items()}
        else:  # pragma: no cover
            raise AssertionError(kind)
        return write_csv(tmp / f"{opt}_{kind or 'blank'}.csv", cols)

    return make


def _option(*args: str, mention: str | None = None):
    def spoil(tmp, inputs):
        return inputs, list(args), mention or args[0]

    return spoil


def _sparse(size: int, name: str):
    """A file of `size` zero bytes that takes no disk space (a sparse file)."""

    def make(tmp: Path) -> Path:
        p = tmp / name
        with p.open("wb") as fh:
            fh.truncate(size)
        return p

    return make


def _csv_cases(cmd: str, opt: str) -> list[Case]:
    cases = [
        Case(cmd, f"{opt}-missing", _replace(opt, _missing)),
        Case(cmd, f"{opt}-directory", _replace(opt, _directory)),
        Case(cmd, f"{opt}-empty", _replace(opt, _text("", f"{opt}_empty.csv"))),
        Case(cmd, f"{opt}-blank-lines", _replace(opt, _text("\n\n  \n", f"{opt}_blank.csv"))),
        Case(cmd, f"{opt}-binary", _replace(opt, _text("\x00\xff\xfe garbage", f"{opt}_bin.csv"))),
        Case(cmd, f"{opt}-sparse-2GiB", _replace(opt, _sparse(2 << 30, f"{opt}_huge.csv"))),
        Case(cmd, f"{opt}-sparse-8MiB-one-line", _replace(opt, _sparse(8 << 20, f"{opt}_nul.csv"))),
    ]
    for kind in ("header", "nocol", "nan", "inf", "-inf", "abc", "", "1e308", "-1e13", "long-field"):
        cases.append(Case(cmd, f"{opt}-{kind or 'blank-cell'}",
                          _replace(opt, _table_variant(cmd, opt, kind))))
    return cases


def _cube_case(name: str, **override) -> Case:
    def make(tmp: Path) -> Path:
        return write_cube_npz(tmp / f"cube_{name}.npz", **override)

    return Case("acquire", name, _replace("cube", make))


def _bad_npz_missing_power(tmp: Path) -> Path:
    return write_cube_npz(tmp / "cube_nopower.npz", power=None)


def _ownship_short(tmp: Path) -> Path:
    """Own-ship positions covering only the first half of the bearing times."""
    cols = {k: v[:60] for k, v in _ownship().items()}  # 0..295 s; bearings go to 600 s
    return write_csv(tmp / "ownship_short.csv", cols)


def _ownship_late(tmp: Path) -> Path:
    """Own-ship positions starting after the first bearing."""
    cols = {k: v[10:] for k, v in _ownship().items()}  # from 50 s; bearings start at 0 s
    return write_csv(tmp / "ownship_late.csv", cols)


def _rules(content: str):
    def spoil(tmp, inputs):
        p = tmp / "rules.json"
        if content != "<missing>":
            p.write_text(content)
        return inputs, ["--rules", str(p)], "rules.json"

    return spoil


CASES: list[Case] = [
    # ---- crossings
    *_csv_cases("crossings", "bearings"),
    Case("crossings", "single-sample-per-track",
         _replace("bearings", _table_variant("crossings", "bearings", "single"))),
    Case("crossings", "single-sample-with-period",
         lambda tmp, inputs: ({**inputs, "bearings": _table_variant("crossings", "bearings",
                                                                     "single")(tmp)},
                              ["--period-s", "10"], "bearings_single.csv")),
    Case("crossings", "duplicate-time-strict",  # merged unless --strict (issue 19)
         lambda tmp, inputs: ({**inputs, "bearings": _table_variant(
             "crossings", "bearings", "duplicate-time")(tmp)}, ["--strict"],
             "bearings_duplicate-time.csv")),
    Case("crossings", "one-track",
         _replace("bearings", lambda tmp: write_csv(tmp / "one_track.csv", _smooth_bearings()))),
    Case("crossings", "window-zero", _option("--window-samples", "0")),
    Case("crossings", "window-negative", _option("--window-samples", "-5")),
    Case("crossings", "window-not-int", _option("--window-samples", "ten")),
    Case("crossings", "window-longer-than-tracks", _option("--window-samples", "1000")),
    Case("crossings", "period-zero", _option("--period-s", "0")),
    Case("crossings", "period-negative", _option("--period-s", "-10")),
    Case("crossings", "period-nan", _option("--period-s", "nan")),
    Case("crossings", "horizon-negative", _option("--horizon-s", "-1")),
    Case("crossings", "merge-window-inf", _option("--merge-window-s", "inf")),
    Case("crossings", "max-gap-zero", _option("--max-gap-s", "0")),
    # ---- smooth
    *_csv_cases("smooth", "bearings"),
    Case("smooth", "single-sample-per-track",
         _replace("bearings", _table_variant("smooth", "bearings", "single"))),
    Case("smooth", "duplicate-time",
         _replace("bearings", _table_variant("smooth", "bearings", "duplicate-time"))),
    Case("smooth", "sigma-zero", _option("--bearing-sigma-deg", "0")),
    Case("smooth", "sigma-negative", _option("--bearing-sigma-deg", "-0.5")),
    Case("smooth", "sigma-nan", _option("--bearing-sigma-deg", "nan")),
    Case("smooth", "q-negative", _option("--accel-psd-deg2-per-s3=-1e-6", mention="--accel-psd-deg2-per-s3")),
    Case("smooth", "q-negative-separate-word", _option("--accel-psd-deg2-per-s3", "-1e-6")),
    Case("smooth", "clutter-negative", _option("--clutter-density", "-0.1")),
    Case("smooth", "p-detect-zero", _option("--detection-probability", "0")),
    Case("smooth", "p-detect-above-one", _option("--detection-probability", "1.5")),
    Case("smooth", "min-length-zero", _option("--min-length", "0")),
    Case("smooth", "robust-unknown", _option("--robust", "l1")),
    # ---- tqi
    *_csv_cases("tqi", "amplitudes"),
    Case("tqi", "amplitude-negative",
         _replace("amplitudes", lambda tmp: write_csv(tmp / "neg.csv", {
             **_amplitudes(), "amplitude": [-1.0] + _amplitudes()["amplitude"][1:]}))),
    Case("tqi", "duplicate-time",
         _replace("amplitudes", _table_variant("tqi", "amplitudes", "duplicate-time"))),
    Case("tqi", "track-id-fractional",
         _replace("amplitudes", lambda tmp: write_csv(tmp / "frac.csv", {
             **_amplitudes(), "track_id": [0.5] * 20}))),
    Case("tqi", "n-looks-zero", _option("--n-looks", "0")),
    Case("tqi", "snr0-above-snr1", _option("--snr0-db", "12", mention="--snr0-db")),
    Case("tqi", "snr1-nan", _option("--snr1-db", "nan")),
    Case("tqi", "tl-above-tu", _option("--tl", "5", mention="--tl")),
    Case("tqi", "lh-negative", _option("--lh", "-1")),
    Case("tqi", "omega-zero", _option("--omega-per-deg", "0")),
    Case("tqi", "t-err-negative", _option("--t-err", "-1")),
    Case("tqi", "smoothing-zero", _option("--residual-smoothing", "0")),
    Case("tqi", "smoothing-above-one", _option("--residual-smoothing", "2")),
    # ---- tma
    *_csv_cases("tma", "bearings"),
    *_csv_cases("tma", "ownship"),
    Case("tma", "ownship-ends-early", _replace("ownship", _ownship_short)),
    Case("tma", "ownship-starts-late", _replace("ownship", _ownship_late)),
    Case("tma", "two-bearings", _replace("bearings", _table_variant("tma", "bearings", "two_rows"))),
    Case("tma", "bearing-duplicate-time",
         _replace("bearings", _table_variant("tma", "bearings", "duplicate-time"))),
    Case("tma", "ownship-duplicate-time",
         _replace("ownship", _table_variant("tma", "ownship", "duplicate-time"))),
    Case("tma", "ownship-single-position",
         _replace("ownship", lambda tmp: write_csv(tmp / "os1.csv", {"time": [0.0], "x": [0.0],
                                                                    "y": [0.0]}))),
    Case("tma", "sigma-zero", _option("--bearing-sigma-deg", "0")),
    Case("tma", "sigma-negative", _option("--bearing-sigma-deg", "-1")),
    Case("tma", "q-negative", _option("--motion", "chain", "--accel-psd-m2-per-s3", "-1",
                                      mention="--accel-psd-m2-per-s3")),
    Case("tma", "robust-k-zero", _option("--robust", "huber", "--robust-k", "0",
                                          mention="--robust-k")),
    # ---- track
    *_csv_cases("track", "detections"),
    Case("track", "score-out-of-range",
         _replace("detections", lambda tmp: write_csv(tmp / "score.csv", {
             **_detections(), "score": [1.5] * 12}))),
    Case("track", "position-sigma-zero", _option("--position-sigma-m", "0")),
    Case("track", "position-sigma-negative", _option("--position-sigma-m", "-100")),
    Case("track", "accel-psd-negative", _option("--accel-psd-m2-per-s3", "-1")),
    Case("track", "confirm-m-above-n", _option("--confirm", "5", "4", mention="--confirm")),
    Case("track", "confirm-zero", _option("--confirm", "0", "0", mention="--confirm")),
    Case("track", "max-misses-zero", _option("--max-misses", "0")),
    Case("track", "hotspot-cell-zero", _option("--hotspot-cell-m", "0")),
    Case("track", "min-rank-nan", _option("--min-rank", "nan")),
    Case("track", "rules-missing", _rules("<missing>")),
    Case("track", "rules-malformed", _rules("{not json")),
    Case("track", "rules-wrong-structure", _rules('{"rules": 3}')),
    # ---- acquire
    Case("acquire", "cube-missing", _replace("cube", _missing)),
    Case("acquire", "cube-directory", _replace("cube", _directory)),
    Case("acquire", "cube-empty", _replace("cube", _text("", "empty.npz"))),
    Case("acquire", "cube-not-npz", _replace("cube", _text("power,freqs\n1,2\n", "cube.csv"))),
    Case("acquire", "cube-npy-not-npz", _replace(
        "cube", lambda tmp: (np.save(tmp / "cube.npy", np.ones(CUBE_SHAPE)), tmp / "cube.npy")[1])),
    Case("acquire", "cube-missing-array", _replace("cube", _bad_npz_missing_power)),
    _cube_case("power-2d", power=np.ones(CUBE_SHAPE[:2])),
    _cube_case("power-4d", power=np.ones((*CUBE_SHAPE, 2))),
    _cube_case("freqs-wrong-length", freqs=CUBE_FREQS[:-1]),
    _cube_case("power-nan", power=np.full(CUBE_SHAPE, np.nan)),
    _cube_case("power-negative", power=-np.ones(CUBE_SHAPE)),
    _cube_case("scan-period-zero", scan_period=0.0),
    _cube_case("aperture-negative", aperture=-1.0),
    _cube_case("power-text", power=np.array(["a", "b"])),
    _cube_case("power-object", power=np.array([{"a": 1}], dtype=object)),
    _cube_case("one-bin", power=np.ones((24, 12, 1)), freqs=np.array([100.0])),
    _cube_case("power-complex", power=np.ones(CUBE_SHAPE) * (1 + 1j)),
    _cube_case("power-numeric-text", power=np.full(CUBE_SHAPE, "1.0")),
    _cube_case("power-bool", power=np.ones(CUBE_SHAPE, dtype=bool)),
    _cube_case("freqs-text", freqs=np.array([str(f) for f in CUBE_FREQS])),
    _cube_case("scan-period-text", scan_period=np.array("1.0")),
    _cube_case("aperture-two-values", aperture=np.array([20.0, 30.0])),
    Case("acquire", "cube-text-named-npz",
         _replace("cube", _text("power,freqs\n1,2\n", "looks_like.npz"))),
    Case("acquire", "beam-negative", _option("--beam", "-1")),
    Case("acquire", "beam-past-last", _option("--beam", str(CUBE_SHAPE[1]), mention="--beam")),
    Case("acquire", "beam-not-int", _option("--beam", "4.5")),
    Case("acquire", "freq-below", _option("--freq-hz", "10")),
    Case("acquire", "freq-above", _option("--freq-hz", "1e6")),
    Case("acquire", "freq-nan", _option("--freq-hz", "nan")),
    Case("acquire", "freq-text", _option("--freq-hz", "abc")),
    Case("acquire", "lag-inf", _option("--display-lag-s", "inf")),
    Case("acquire", "lag-negative", _option("--display-lag-s", "-1")),
    Case("acquire", "ibw-zero", _option("--ibw-hz", "0")),
    Case("acquire", "ibw-negative", _option("--ibw-hz", "-1")),
    Case("acquire", "min-scans-zero", _option("--min-scans", "0")),
    Case("acquire", "min-scans-above-cube", _option("--min-scans", "1000")),
    Case("acquire", "noise-dof-zero", _option("--noise-dof", "0")),
    # ---- argparse usage errors, on every command
    Case("crossings", "unknown-option", _option("--frobnicate", "1")),
    Case("acquire", "unknown-option", _option("--frobnicate")),
    Case("tma", "bad-choice", _option("--motion", "zigzag", mention="--motion")),
]


def _case_id(c: Case) -> str:
    return f"{c.cmd}-{c.name}"


@pytest.mark.parametrize("case", [pytest.param(c, id=_case_id(c)) for c in CASES])
def test_bad_input(case: Case, run_cli, tmp_path):
    """Each bad input: exit 2, one stderr line naming the culprit, no traceback, no output."""
    inputs = valid_inputs(case.cmd, tmp_path)
    inputs, extra, mention = case.spoil(tmp_path, inputs)
    has_out = COMMANDS[case.cmd][1]
    out = tmp_path / "result.csv" if has_out else None
    code, stdout, err = run_cli(*command_line(case.cmd, inputs, out, extra))
    assert_bad_input(code, err, mention, [out] if out else [])
    if not has_out:
        assert stdout == ""


# --------------------------------------------------------------------------------------------
# valid runs (so that the matrix fails for the reason it names) and output paths
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cmd", sorted(COMMANDS))
def test_valid_input_runs(cmd, run_cli, tmp_path):
    """The unspoiled command lines of the matrix succeed."""
    out = tmp_path / "result.csv" if COMMANDS[cmd][1] else None
    code, stdout, err = run_cli(*command_line(cmd, valid_inputs(cmd, tmp_path), out))
    assert code == 0, err
    assert "Traceback" not in err
    if out is not None:
        assert out.is_file() and out.read_text().count("\n") >= 2
    else:
        assert '"bearing_deg"' in stdout


@pytest.mark.parametrize("cmd", [c for c in sorted(COMMANDS) if COMMANDS[c][1]])
def test_output_in_missing_folder_is_created(cmd, run_cli, tmp_path):
    """``--out new/sub/x.csv`` creates the missing folders (documented: like ``mkdir -p``)."""
    out = tmp_path / "new" / "sub" / "result.csv"
    code, _, err = run_cli(*command_line(cmd, valid_inputs(cmd, tmp_path), out))
    assert code == 0, err
    assert out.is_file()


@pytest.mark.parametrize("cmd", [c for c in sorted(COMMANDS) if COMMANDS[c][1]])
def test_bad_input_creates_no_output_folder(cmd, run_cli, tmp_path):
    """Bad input with ``--out`` in a missing folder leaves no folder behind either."""
    inputs = valid_inputs(cmd, tmp_path)
    opt = COMMANDS[cmd][0][0]
    inputs[opt] = tmp_path / "no_such_file.csv"
    out = tmp_path / "new" / "result.csv"
    code, _, err = run_cli(*command_line(cmd, inputs, out))
    assert_bad_input(code, err, "no_such_file.csv", [out])
    assert not out.parent.exists()


@pytest.mark.parametrize("cmd", [c for c in sorted(COMMANDS) if COMMANDS[c][1]])
def test_existing_output_unchanged_on_bad_input(cmd, run_cli, tmp_path):
    """An output file that existed before a failed run keeps its content and time stamp."""
    out = tmp_path / "result.csv"
    out.write_text("previous result\n")
    os.utime(out, (1_000_000_000, 1_000_000_000))
    inputs = valid_inputs(cmd, tmp_path)
    opt = COMMANDS[cmd][0][-1]
    inputs[opt] = _table_variant(cmd, opt, "nan")(tmp_path)
    code, _, err = run_cli(*command_line(cmd, inputs, out))
    assert code == EXIT_BAD_INPUT and len(err.splitlines()) == 1, err
    assert out.read_text() == "previous result\n"
    assert out.stat().st_mtime == 1_000_000_000
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".result.csv.")] == []


def _out_parent_is_file(tmp: Path) -> tuple[Path, str]:
    f = tmp / "plain_file"
    f.write_text("x")
    return f / "result.csv", "plain_file"


def _out_is_directory(tmp: Path) -> tuple[Path, str]:
    d = tmp / "out_dir"
    d.mkdir()
    return d, "out_dir"


def _out_unwritable(tmp: Path) -> tuple[Path, str]:
    d = tmp / "read_only"
    d.mkdir()
    d.chmod(0o555)
    return d / "result.csv", "read_only"


@pytest.mark.parametrize("where", [_out_parent_is_file, _out_is_directory, _out_unwritable],
                         ids=["parent-is-file", "out-is-directory", "read-only-folder"])
@pytest.mark.parametrize("cmd", [c for c in sorted(COMMANDS) if COMMANDS[c][1]])
def test_unwritable_output(cmd, where, run_cli, tmp_path, monkeypatch):
    """An output that cannot be written is one line and exit 2, and nothing is written."""
    out, mention = where(tmp_path)
    if where is _out_unwritable and os.access(out.parent, os.W_OK):
        # permissions do not restrict root: make the check see what a normal user would
        real_access = os.access
        monkeypatch.setattr("fusion.cli.os.access", lambda p, mode: (
            False if Path(p) == out.parent and mode & os.W_OK else real_access(p, mode)))
    before = sorted(p.name for p in out.parent.iterdir()) if out.parent.is_dir() else None
    try:
        code, _, err = run_cli(*command_line(cmd, valid_inputs(cmd, tmp_path), out))
    finally:
        if where is _out_unwritable:
            out.parent.chmod(0o755)
    assert code == EXIT_BAD_INPUT, err
    lines = err.splitlines()
    assert len(lines) == 1 and mention in lines[0] and "--out" in lines[0], err
    assert "Traceback" not in err
    if out.is_dir():
        assert list(out.iterdir()) == []
    else:
        assert not out.exists()
        after = sorted(p.name for p in out.parent.iterdir()) if out.parent.is_dir() else None
        assert after == before


# --------------------------------------------------------------------------------------------
# simulate, demo and the parser itself
# --------------------------------------------------------------------------------------------
def test_simulate_out_is_a_file(run_cli, tmp_path):
    """``simulate --out`` naming an existing file: one line, exit 2, file unchanged."""
    f = tmp_path / "plain_file"
    f.write_text("keep\n")
    code, _, err = run_cli("simulate", "amplitudes", "--out", f)
    assert_bad_input(code, err, "plain_file", [])
    assert f.read_text() == "keep\n"


def test_simulate_out_inside_a_file(run_cli, tmp_path):
    """``simulate --out file/sub``: one line, exit 2."""
    f = tmp_path / "plain_file"
    f.write_text("keep\n")
    code, _, err = run_cli("simulate", "amplitudes", "--out", f / "sub")
    assert_bad_input(code, err, "plain_file", [])


@pytest.mark.parametrize("cmd", ["simulate", "demo"])
def test_negative_seed(cmd, run_cli, tmp_path):
    """A negative seed is rejected before anything is written."""
    out = tmp_path / "out"
    argv = ["simulate", "amplitudes"] if cmd == "simulate" else ["demo", "--part", "tqi"]
    code, _, err = run_cli(*argv, "--seed", "-1", "--out", out)
    assert_bad_input(code, err, "--seed", [out])


def test_demo_out_is_a_file(run_cli, tmp_path):
    """``demo --out`` naming an existing file: one line, exit 2, file unchanged."""
    f = tmp_path / "plain_file"
    f.write_text("keep\n")
    code, _, err = run_cli("demo", "--part", "tqi", "--out", f)
    assert_bad_input(code, err, "plain_file", [])
    assert f.read_text() == "keep\n"


@pytest.mark.parametrize("argv, mention", [
    ([], "COMMAND"),
    (["no-such-command"], "no-such-command"),
    (["crossings"], "--bearings"),
    (["acquire", "--cube", "c.npz", "--beam", "3"], "--freq-hz"),
    (["simulate", "no-such-kind", "--out", "x"], "no-such-kind"),
    (["tqi", "--amplitudes", "a.csv", "--out", "q.csv", "--frobnicate"], "--frobnicate"),
    (["smooth", "--bearings", "b.csv", "--out", "s.csv", "--detection-probability", "1.5"],
     "--detection-probability"),
    (["track", "--detections", "d.csv", "--out", "t.csv", "--min-rank", "nan"], "--min-rank"),
])
def test_usage_errors_are_one_line(argv, mention, run_cli):
    """argparse's own errors: one line ``fusion[ CMD]: error: ...``, exit 2, no usage block."""
    code, out, err = run_cli(*argv)
    lines = err.splitlines()
    assert code == EXIT_BAD_INPUT
    assert len(lines) == 1 and lines[0].startswith("fusion") and ": error: " in lines[0], err
    assert mention in lines[0]
    assert out == ""


@pytest.mark.parametrize("argv", [["--help"], ["acquire", "--help"], ["tma", "-h"]])
def test_help_still_works(argv, run_cli):
    """``--help`` prints the full usage on stdout and exits 0."""
    code, out, err = run_cli(*argv)
    assert code == 0 and out.startswith("usage: fusion") and err == ""
