"""Tests of ``fusion report``: every result kind drawn from real command outputs, bad input refused."""

from __future__ import annotations

import contextlib
import io
import json
import os
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fusion.cli import EXIT_BAD_INPUT, main
from fusion.report.kinds import KINDS, detect_result

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _cli(*argv: object) -> int:
    try:
        return main([str(a) for a in argv])
    except SystemExit as e:  # argparse errors
        return int(e.code or 0)


@pytest.fixture(scope="module")
def outputs(tmp_path_factory) -> dict[str, Path]:
    """Small scenarios from the simulators, run through the real commands once for all tests."""
    from fusion.io import write_cube, write_table
    from fusion.simulate import amplitudes, multistatic, tma
    from fusion.simulate.bearings import simulate_bearings
    from fusion.simulate.clicks import simulate_clicks
    from fusion.simulate.cube import simulate_cube
    from fusion.simulate.passive import simulate_passive
    from fusion.simulate.whale_range.files import write_click_scenario

    d = tmp_path_factory.mktemp("report")
    f: dict[str, Path] = {"dir": d}
    cube = simulate_cube(seed=3, n_scans=40, n_bins=8, bearing0_deg=70.0,
                         bearing_rate_deg_per_min=30.0, snr_db=9.0)
    f["cube"] = write_cube(d / "cube.npz", cube.cube)
    f["acq"] = d / "acq.json"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):  # acquire prints its JSON: saved, as a user would
        assert _cli("acquire", "--cube", f["cube"], "--beam", cube.click_beam, "--freq-hz",
                    cube.click_freq) == 0
    f["acq"].write_text(printed.getvalue(), encoding="utf-8")
    f["freq"] = cube.click_freq  # type: ignore[assignment]
    amplitudes.write_scenario(d / "amp", seed=1)
    assert _cli("tqi", "--amplitudes", d / "amp" / "amplitudes.csv", "--out", d / "tqi.csv") == 0
    sc = simulate_bearings(seed=2, n_tracks=4, duration_s=900.0, n_wrap_crossings=0,
                           n_near_miss_pairs=0)
    f["bearings"] = write_table(d / "bearings.csv", {"track_id": sc.track_id, "time": sc.time,
                                                     "bearing_deg": sc.bearing_deg})
    assert _cli("crossings", "--bearings", f["bearings"], "--out", d / "alerts.csv") == 0
    assert _cli("smooth", "--bearings", f["bearings"], "--out", d / "smoothed.csv") == 0
    tma.write_scenario(d / "tma", seed=3)
    assert _cli("tma", "--bearings", d / "tma" / "bearings.csv", "--ownship",
                d / "tma" / "ownship.csv", "--out", d / "tma.csv") == 0
    multistatic.write_scenario(d / "ms", seed=3)
    f["detections"] = d / "ms" / "detections.csv"
    assert _cli("track", "--detections", f["detections"], "--out", d / "tracks.csv",
                "--smooth") == 0
    ps = simulate_passive(seed=1, n_scans=140, n_targets=3, n_crossing_pairs=1, n_fading=0)
    write_cube(d / "passive_cube.npz", ps.cube)
    clicks = [arg for b, fr, t in ps.clicks for arg in ("--click", f"{b},{fr},{t}")]
    assert _cli("passive", "--cube", d / "passive_cube.npz", *clicks, "--out", d / "passive") == 0
    write_click_scenario(d / "clicks", simulate_clicks(seed=2, n_sensors=5, n_sources=1,
                                                       duration_s=16.0))
    f["array"] = d / "clicks" / "array.json"
    assert _cli("localize", "--audio", d / "clicks" / "audio.flac", "--array", f["array"],
                "--out", d / "loc" / "rec.json", "--quiet") == 0
    return f


def _png_size(path: Path) -> tuple[int, int]:
    """Width and height of a PNG file from its IHDR chunk (checks the signature)."""
    head = path.read_bytes()[:24]
    assert head[:8] == PNG_SIGNATURE and head[12:16] == b"IHDR", path
    return struct.unpack(">II", head[16:24])


def _check_figures(out: Path, names: list[str]) -> None:
    """Exactly `names` were written, each a PNG of plausible size that is not blank."""
    import matplotlib.image

    assert sorted(p.name for p in out.iterdir()) == sorted([*names, "summary.md"])
    index = (out / "summary.md").read_text(encoding="utf-8")
    for name in names:  # each figure linked once, with what it shows and its counts
        line = next(ln for ln in index.splitlines() if ln.startswith(f"- [{name}]({name}): "))
        assert " — " in line and any(ch.isdigit() for ch in line.split(" — ", 1)[1]), line
    for name in names:
        w, h = _png_size(out / name)
        assert 500 <= w <= 2000 and 250 <= h <= 1500, (name, w, h)
        assert (out / name).stat().st_size > 15_000, name
        pixels = matplotlib.image.imread(out / name)
        assert pixels.shape[:2] == (h, w)
        assert float(pixels[..., :3].std()) > 0.05, name  # something drawn on the white


@pytest.mark.parametrize(("result", "extra", "kind", "names"), [
    ("acq", ("--cube", "cube", "--freq-hz", "freq"), "acquisition", ["btr.png"]),
    ("tqi.csv", ("--bearings", "bearings"), "tqi", ["tqi.png", "tqi_bearing_time.png"]),
    ("alerts.csv", ("--bearings", "bearings"), "alerts",
     ["crossings.png", "crossings_bearing_time.png"]),
    ("smoothed.csv", ("--bearings", "bearings", "--alerts", "alerts.csv"), "smoothed",
     ["smoothed.png", "crossings.png"]),
    ("tma.csv", ("--ownship", "tma/ownship.csv"), "tma", ["tma.png"]),
    ("tracks.csv", ("--detections", "detections"), "tracks", ["tracks.png", "tracks_sigma.png"]),
    ("passive", (), "passive", ["passive_tracks.png"]),
    ("loc/rec.json", ("--array", "array"), "localization", ["localize.png",
                                                             "localize_surface.png"]),
    ("loc", (), "localization_folder", ["rec_localize.png"]),
])
def test_each_kind_draws_its_figures(outputs, tmp_path, result, extra, kind, names):
    """Each command's real output is recognised and drawn as the expected, non-blank PNG files."""
    d = outputs["dir"]

    def resolve(v: str) -> object:
        return outputs.get(v, d / v)

    path = resolve(result)
    before = {p: p.read_bytes() for p in d.rglob("*") if p.is_file()}
    assert detect_result(path).kind == kind
    out = tmp_path / "figs"
    assert _cli("report", path, "--out", out, *[resolve(v) if i % 2 else v
                                                for i, v in enumerate(extra)]) == 0
    _check_figures(out, names)
    assert {p: p.read_bytes() for p in d.rglob("*") if p.is_file()} == before  # inputs untouched


def test_out_folder_that_is_the_result_is_refused(outputs, capsys):
    """--out naming the result folder itself is refused (one line, exit 2), nothing written."""
    folder = outputs["dir"] / "passive"
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert _cli("report", folder, "--out", folder) == EXIT_BAD_INPUT
    assert "refusing to overwrite an input" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def _bad_inputs(outputs: dict[str, Path], tmp: Path) -> list[tuple[list[object], str]]:
    d = outputs["dir"]
    (tmp / "other.json").write_text(json.dumps({"hello": 1}), encoding="utf-8")
    (tmp / "binary.csv").write_bytes(b"\x00\x01\x02PK\x03")
    (tmp / "empty").mkdir()
    (tmp / "bad_tqi.csv").write_text("track_id,time,amplitude,residual,tqi\n0,0,1,0,great\n",
                                     encoding="utf-8")
    (tmp / "acq_nan.json").write_text('{"bearing_deg": "x", "bearing_rate_deg_per_min": 1, '
                                      '"snr_db": 2}', encoding="utf-8")
    (tmp / "a_file").write_text("x", encoding="utf-8")
    return [
        ([d / "bearings.csv"], "not a result the report knows"),  # an input, not an output
        ([tmp / "other.json"], "not a result the report knows"),
        ([tmp / "binary.csv"], "not a result the report knows"),
        ([tmp / "empty"], "a folder without a fusion result"),
        ([tmp / "missing.csv"], "no such file"),
        ([tmp / "bad_tqi.csv"], "great"),
        ([outputs["acq"]], "needs --cube"),
        ([tmp / "acq_nan.json", "--cube", outputs["cube"]], "finite number"),
        ([d / "tqi.csv", "--cube", outputs["cube"]], "--cube: not used for a result of fusion tqi"),
        ([outputs["acq"], "--cube", outputs["cube"], "--freq-hz", "5000"], "outside the band"),
        ([d / "tqi.csv", "--out", tmp / "a_file"], "not a folder"),
    ]


def test_bad_inputs_exit_2_with_one_line(outputs, tmp_path, capsys):
    """Unknown or broken results, missing or unused extra inputs: one error line, exit 2, no PNG."""
    for argv, message in _bad_inputs(outputs, tmp_path):
        out = tmp_path / "figs"
        if "--out" not in argv:
            argv = [*argv, "--out", out]
        capsys.readouterr()
        code = _cli("report", *argv)
        err = capsys.readouterr().err
        assert code == EXIT_BAD_INPUT, (argv, err)
        assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err, err
        assert not out.exists() or not any(out.iterdir()), argv  # no partial output


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_special_file_as_result_is_refused(tmp_path, capsys):
    """A FIFO given as the result is refused at once (never opened for reading)."""
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    assert _cli("report", fifo, "--out", tmp_path / "figs") == EXIT_BAD_INPUT
    assert "named pipe" in capsys.readouterr().err


def test_figure_never_replaces_an_input(outputs, tmp_path):
    """A figure whose name is an input's (by a link) is refused rather than written over it."""
    from fusion.report.figures import FigureWriter, new_figure

    src = tmp_path / "data.png"
    src.write_bytes(b"input")
    out = tmp_path / "figs"
    out.mkdir()
    (out / "tqi.png").symlink_to(src)
    fig, _ = new_figure()
    with pytest.raises(ValueError, match="refusing to overwrite an input"):
        FigureWriter(out, inputs=[src]).save(fig, "tqi.png")
    assert src.read_bytes() == b"input"


@pytest.mark.parametrize(("header", "kind"), [
    ("track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg,tqi", "passive_tracks"),
    ("track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg", "smoothed"),
    ("track_id,time,amplitude,residual,tqi,sllr0", "tqi"),
    ("time,track_a,track_b,t_cross,kind,t_cross_low,t_cross_high", "alerts"),
    ("track_id,event,time,x,y,vx,vy,status,sigma_x,sigma_y", "tracks"),
    ("time,x,y,vx,vy,sigma_x,sigma_y,range", "tma"),
])
def test_kind_from_the_header(tmp_path, header, kind):
    """A CSV result's kind follows from its header line alone (extra columns allowed)."""
    p = tmp_path / "r.csv"
    p.write_text(header + "\n", encoding="utf-8")
    assert detect_result(p).kind == kind


def test_acquisition_btr_bin_and_line(outputs):
    """The BTR bin is the clicked one, and without a click the bin holding the simulated line."""
    from fusion.io import read_cube
    from fusion.report.acquisition import btr_bin

    cube = read_cube(outputs["cube"])
    k = btr_bin(cube, float(outputs["freq"]))
    assert abs(cube.freqs[k] - float(outputs["freq"])) <= 0.5 * np.diff(cube.freqs)[0]
    assert btr_bin(cube, None) == k  # the line at 9 dB stands out in its own bin


def test_report_help_imports_no_matplotlib():
    """`fusion report --help` stays light: matplotlib is imported only when figures are drawn."""
    code = ("import sys\nfrom fusion.cli import main\ntry:\n    main(['report', '--help'])\n"
            "except SystemExit:\n    pass\nprint('matplotlib' in sys.modules, file=sys.stderr)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert r.stderr.strip().splitlines()[-1] == "False"


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=300))
def test_detect_result_of_any_bytes_is_a_kind_or_one_valueerror(tmp_path, data):
    """Whatever a file holds, telling its kind gives a known kind or a ValueError naming the file."""
    p = tmp_path / "r.csv"
    p.write_bytes(data)
    try:
        kind = detect_result(p).kind
    except ValueError as e:
        assert str(p) in str(e) and "\n" not in str(e)
    else:
        assert kind in KINDS


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(columns=st.permutations(["track_id", "time", "amplitude", "residual", "tqi", "x", "note"]),
       keep=st.integers(3, 7))
def test_kind_needs_every_required_column(tmp_path, columns, keep):
    """A header is the tqi kind exactly when it holds all five tqi columns, in any order."""
    header = columns[:keep]
    p = tmp_path / "h.csv"
    p.write_text(",".join(header) + "\n", encoding="utf-8")
    needed = {"track_id", "time", "amplitude", "residual", "tqi"}
    if needed <= set(header):
        assert detect_result(p).kind == "tqi"
    else:
        with pytest.raises(ValueError, match="not a result the report knows"):
            detect_result(p)


def test_clutter_map_scales_come_from_the_track_settings(outputs, tmp_path):
    """The report's hotspots use the scales fusion track wrote beside its output, else defaults."""
    import json

    from fusion.report.positions import track_map_settings

    tracks = outputs["dir"] / "tracks.csv"
    written = json.loads(tracks.with_name("tracks.settings.json").read_text())["settings"]
    got = track_map_settings(tracks)
    assert got == {"position_sigma_m": pytest.approx(written["position_sigma_m"]),
                   "feature_sigma_m": pytest.approx(written["feature_sigma_m"])}
    lone = tmp_path / "t.csv"
    lone.write_bytes(tracks.read_bytes())
    assert track_map_settings(lone) == {}  # no settings file: the map's defaults
    (tmp_path / "t.settings.json").write_text('{"settings": {"position_sigma_m": "nan"}}')
    assert track_map_settings(lone) == {}  # unusable values are not passed on
