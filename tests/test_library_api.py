"""The public API: ``import fusion`` is light, its entry points give the commands' numbers.

Cross-checks: each entry point (:func:`fusion.smooth_bearings`, :func:`fusion.find_crossings`,
:func:`fusion.track_quality`) on a simulated scenario writes the same bytes as the command of
the same job, with the same estimated settings. The smoothers refuse bearings in degrees.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fusion
from fusion.io import read_amplitudes, read_bearings, write_table
from fusion.passive.smoothing import (
    BearingSmoother,
    MultiTrackSmoother,
    NearestNeighbourTracker,
    OnlineBearingSmoother,
    TrackPrior,
)
from fusion.passive.smoothing.settings import fit_smooth_settings
from fusion.simulate import get_writer

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("gtsam", "scipy", "matplotlib", "filterpy")


def _modules_after(code: str) -> set[str]:
    r = subprocess.run([sys.executable, "-c", code + "\nimport sys; print(' '.join(sys.modules))"],
                       capture_output=True, text=True, cwd=ROOT, check=True)
    return set(r.stdout.split())


def test_import_fusion_loads_neither_gtsam_nor_scipy():
    loaded = _modules_after("import fusion; fusion.__all__")
    assert not loaded & set(HEAVY), loaded & set(HEAVY)
    assert "numpy" not in loaded  # the entry points' modules are not imported either
    # a reader brings numpy, not the solvers
    loaded = _modules_after("import fusion; fusion.read_bearings")
    assert "numpy" in loaded and not loaded & {"gtsam", "scipy"}


def test_every_public_name_resolves():
    for name in fusion.__all__:
        assert getattr(fusion, name) is not None, name
    assert set(fusion.__all__) <= set(dir(fusion))
    with pytest.raises(AttributeError):
        fusion.no_such_name  # noqa: B018


@pytest.mark.parametrize("package", sorted(
    ".".join(p.relative_to(ROOT).parent.parts) for p in (ROOT / "fusion").glob("**/__init__.py")))
def test_every_package_has_all_of_existing_names(package):
    """Each package's ``__all__`` names its attributes or its modules (checked without importing
    the modules)."""
    mod = importlib.import_module(package)
    assert isinstance(mod.__all__, list | tuple) and mod.__all__, package
    if (mod.__doc__ or "").startswith("Deprecated import path"):  # a forwarding shim: it warns
        for name in mod.__all__:
            with pytest.warns(DeprecationWarning, match="moved to .*the old path goes"):
                assert getattr(mod, name) is not None, (package, name)
        return
    for name in mod.__all__:
        assert hasattr(mod, name) or importlib.util.find_spec(f"{package}.{name}"), (package, name)


@pytest.fixture(scope="module")
def bearings(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("bearings")
    get_writer("bearings")(out, seed=3)
    return out


def _same_file(a: Path, b: Path) -> None:
    assert a.read_bytes() == b.read_bytes()


def test_smooth_bearings_equals_fusion_smooth(run_cli, bearings, tmp_path):
    src = bearings / "bearings.csv"
    code, out, err = run_cli("smooth", "--bearings", src, "--out", tmp_path / "cli.csv", "--quiet")
    assert code == 0, err
    res = fusion.smooth_bearings(fusion.read_bearings(src))
    fusion.write_table(tmp_path / "lib.csv", res.columns())
    _same_file(tmp_path / "cli.csv", tmp_path / "lib.csv")
    meta = json.loads((tmp_path / "cli.settings.json").read_text())
    assert meta["settings"] == res.settings.as_dict()
    assert res.settings.describe() in out
    # known answer: the scenario's bearing noise is 0.5 deg, estimated, not given
    truth = json.loads((bearings / "truth.json").read_text())
    assert "sigma_bearing_deg" in res.settings.estimated
    assert res.settings.sigma_bearing_deg == pytest.approx(truth["noise_deg"], rel=0.1)
    assert res.settings.period_s == pytest.approx(truth["sample_period_s"])
    assert len(res.tracks) == len(truth["track_ids"])
    assert all(np.all(np.abs(tr.bearing) <= np.pi) for tr in res.tracks)  # radians


def test_smooth_bearings_unknown_origin_and_grid_equal_the_command(run_cli, bearings, tmp_path):
    """Rows of unknown origin (the tracker, merging, the counted clutter) and the grid output."""
    t = read_bearings(bearings / "bearings.csv")
    keep = t["time"] <= 600.0
    cols = {k: v[keep] for k, v in t.columns.items()}
    cols["track_id"] = np.full(int(keep.sum()), -1)
    src = tmp_path / "unknown.csv"
    write_table(src, cols)
    code, out, err = run_cli("smooth", "--bearings", src, "--out", tmp_path / "cli.csv", "--quiet",
                             "--output-times", "grid", "--bearing-sigma-deg", "0.6")
    assert code == 0, err
    res = fusion.smooth_bearings(cols, output_times="grid", sigma_bearing_deg=0.6)
    write_table(tmp_path / "lib.csv", res.columns())
    _same_file(tmp_path / "cli.csv", tmp_path / "lib.csv")
    meta = json.loads((tmp_path / "cli.settings.json").read_text())
    assert meta["association_clutter_density"] == res.association_clutter_density
    assert res.settings.sigma_bearing_deg == 0.6
    assert "sigma_bearing_deg" not in res.settings.estimated


def test_find_crossings_equals_fusion_crossings(run_cli, bearings, tmp_path):
    src = bearings / "bearings.csv"
    code, out, err = run_cli("crossings", "--bearings", src, "--out", tmp_path / "cli.csv",
                             "--quiet", "--windows", "3")
    assert code == 0, err
    res = fusion.find_crossings(fusion.read_bearings(src), n_windows=3)
    write_table(tmp_path / "lib.csv", res.columns())
    _same_file(tmp_path / "cli.csv", tmp_path / "lib.csv")
    assert res.settings.describe() in out and res.alerts
    one = read_bearings(src)
    with pytest.raises(ValueError, match="at least two tracks"):
        fusion.find_crossings({k: v[one["track_id"] == 0] for k, v in one.columns.items()})


def test_track_quality_equals_fusion_tqi(run_cli, tmp_path):
    get_writer("amplitudes")(tmp_path, seed=4)
    src = tmp_path / "amplitudes.csv"
    code, _, err = run_cli("tqi", "--amplitudes", src, "--out", tmp_path / "cli.csv", "--quiet",
                           "--diagnostics", "--snr1-db", "12", "--sllr0-max", "4")
    assert code == 0, err
    cols = fusion.track_quality(read_amplitudes(src), diagnostics=True, snr1_db=12.0,
                                sllr0_max=4.0)
    write_table(tmp_path / "lib.csv", cols)
    _same_file(tmp_path / "cli.csv", tmp_path / "lib.csv")
    assert set(np.unique(cols["tqi"])) <= {"lost", "uncertain", "low_snr", "strong"}


DEGREES = np.array([10.0, 20.0, 30.0, 40.0])
TIMES = np.array([0.0, 1.0, 2.0, 3.0])


@pytest.mark.parametrize("call", [
    lambda: BearingSmoother(sigma_bearing=0.01, q=1e-6).smooth(TIMES, DEGREES),
    lambda: MultiTrackSmoother(sigma_bearing=0.01, q=1e-6).run(TIMES, DEGREES),
    lambda: NearestNeighbourTracker(sigma_bearing=0.01, q=1e-6).run(TIMES, DEGREES),
    lambda: OnlineBearingSmoother(prior=TrackPrior(0.1, 0.0, 0.01, 0.01), t0=0.0,
                                  sigma_bearing=0.01, q=1e-6).step(1.0, [DEGREES[1]]),
    lambda: TrackPrior(DEGREES[1], 0.0, 0.01, 0.01),
    lambda: fit_smooth_settings(np.zeros(4, int), TIMES, DEGREES),
], ids=["batch", "multitrack", "nearest", "online", "prior", "fit"])
def test_smoothers_refuse_degrees(call):
    with pytest.raises(ValueError, match=r"bearings? must be in radians: .*degrees\?") as e:
        call()
    assert "\n" not in str(e.value)


def test_radians_on_any_branch_within_one_turn_pass():
    z = np.array([6.0, 6.1, 6.2, 6.25])  # rad, near one full turn
    tr = BearingSmoother(sigma_bearing=0.05, q=1e-4).smooth(TIMES, z)
    assert np.allclose(np.mod(tr.bearing, 2 * np.pi), z, atol=0.1)
    assert fusion.check_radians([-2 * np.pi, 2 * np.pi]).shape == (2,)
    with pytest.raises(ValueError, match="radians"):
        fusion.check_radians([0.0, 2 * np.pi + 1e-3])


def test_readme_library_section_runs(tmp_path):
    """The blocks of the README's "Using the library" run, in order, in an empty folder."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Using the library", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```(bash|python)\n(.*?)```", section, flags=re.S)
    assert any(lang == "python" and "fusion.smooth_bearings" in b for lang, b in blocks)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for lang, block in blocks:
        if lang == "bash":
            for line in block.splitlines():
                if line.strip() and not line.startswith("#"):
                    argv = shlex.split(line)
                    assert argv[0] == "fusion"
                    subprocess.run([sys.executable, "-m", "fusion", *argv[1:]], cwd=tmp_path,
                                   env=env, check=True, capture_output=True)
        else:
            r = subprocess.run([sys.executable, "-c", block], cwd=tmp_path, env=env,
                               capture_output=True, text=True)
            assert r.returncode == 0, r.stderr
    assert (tmp_path / "smoothed.csv").read_text().startswith(
        "track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg")


def test_file_bearings_beyond_one_turn_are_wrapped_not_refused(run_cli, tmp_path):
    """A file's degrees beyond 360 are wrapped by the entry point (the command gives what it
    gave before the degree guard): 400..403 deg smooth as 40..43 deg do."""
    rows = {"track_id": np.zeros(4, np.int64), "time": TIMES * 10.0,
            "bearing_deg": np.array([400.0, 401.0, 402.2, 402.9])}
    write_table(tmp_path / "b.csv", rows)
    code, _, err = run_cli("smooth", "--bearings", tmp_path / "b.csv", "--out", tmp_path / "s.csv")
    assert code == 0, err
    wrapped = fusion.smooth_bearings({**rows, "bearing_deg": rows["bearing_deg"] - 360.0})
    assert read_bearings(tmp_path / "s.csv")["bearing_deg"] == pytest.approx(
        wrapped.columns()["bearing_deg"], abs=1e-5)


@pytest.fixture(scope="module")
def detections(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("multistatic")
    get_writer("multistatic")(out, seed=5)
    return out / "detections.csv"


@pytest.mark.parametrize("argv, options", [
    ((), {}),  # the command streams, the library reads the whole table: same rows
    (("--smooth", "--confirmed-only", "--position-sigma-m", "80"),
     {"smooth": True, "confirmed_only": True, "position_sigma_m": 80.0}),
], ids=["default", "smooth"])
def test_track_detections_equals_fusion_track(run_cli, detections, tmp_path, argv, options):
    code, _, err = run_cli("track", "--detections", detections, "--out", tmp_path / "cli.csv",
                           "--quiet", *argv)
    assert code == 0, err
    run = fusion.track_detections(fusion.read_detections(detections), **options)
    write_table(tmp_path / "lib.csv", run.columns)
    _same_file(tmp_path / "cli.csv", tmp_path / "lib.csv")
    assert run.settings.describe() in err
    meta = json.loads((tmp_path / "cli.settings.json").read_text())
    assert meta["settings"] == json.loads(json.dumps(run.settings.metadata()))
    assert meta["confirmed_tracks"] == len(run.result.confirmed_ids()) > 0


def test_track_options_defaults_are_the_command_defaults():
    """One set of defaults: the parser's defaults, mapped to the library's names, are
    :class:`fusion.TrackOptions`'s."""
    from fusion.cli import build_parser
    from fusion.commands.track import track_options

    args = build_parser("track").parse_args(["track", "--detections", "d.csv", "--out", "t.csv"])
    assert track_options(args) == fusion.TrackOptions()
    with pytest.raises(ValueError, match="M must not exceed N"):
        fusion.TrackOptions(confirm=(4, 3))
