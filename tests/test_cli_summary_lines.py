"""Every command ends with one summary line of the same form: ``fusion COMMAND: ...``."""

from __future__ import annotations

import json

import pytest

from fusion.io import read_table


def _last_lines(out: str, err: str) -> list[str]:
    """The last line of each stream that has one."""
    return [s.strip().splitlines()[-1] for s in (out, err) if s.strip()]


@pytest.fixture(scope="module")
def scenarios(tmp_path_factory):
    """Small simulated inputs (bearings, amplitudes, cube), written once."""
    from fusion.cli import main

    root = tmp_path_factory.mktemp("summary")
    for kind in ("bearings", "amplitudes", "cube"):
        assert main(["simulate", kind, "--seed", "1", "--out", str(root / kind)]) == 0
    return root


def test_summary_helper_prefixes_the_command(capsys):
    from fusion.cli import summary

    summary("tqi", "2 track(s) -> out.csv")
    summary("localize", "3 windows", err=True)
    out = capsys.readouterr()
    assert out.out == "fusion tqi: 2 track(s) -> out.csv\n"
    assert out.err == "fusion localize: 3 windows\n"


def test_simulate_tqi_crossings_and_acquire_end_with_their_summary(run_cli, scenarios,
                                                                          tmp_path):
    code, out, err = run_cli("simulate", "amplitudes", "--seed", "2", "--out", tmp_path / "a")
    assert code == 0 and _last_lines(out, err)[-1].startswith("fusion simulate: amplitudes")

    code, out, err = run_cli("tqi", "--amplitudes", scenarios / "amplitudes" / "amplitudes.csv", "--out",
                             tmp_path / "tqi.csv", "--quiet")
    assert code == 0
    amplitudes = read_table(scenarios / "amplitudes" / "amplitudes.csv", required=("track_id",))
    n_tracks = len(set(amplitudes["track_id"].tolist()))
    assert f"fusion tqi: {n_tracks} track(s)" in _last_lines(out, err)[0]

    code, out, err = run_cli("crossings", "--bearings", scenarios / "bearings" / "bearings.csv", "--out",
                             tmp_path / "alerts.csv", "--quiet")
    assert code == 0 and any(s.startswith("fusion crossings: ") for s in _last_lines(out, err))

    click = json.loads((scenarios / "cube" / "truth.json").read_text())  # the operator's click
    code, out, err = run_cli("acquire", "--cube", scenarios / "cube" / "cube.npz", "--beam",
                             click["click_beam"], "--freq-hz", click["click_freq"])
    assert code == 0, err
    result = json.loads(out.strip().splitlines()[0])
    assert err.strip().splitlines()[-1] == (
        f"fusion acquire: bearing {result['bearing_deg']:.2f} deg, rate "
        f"{result['bearing_rate_deg_per_min']:.3g} deg/min, SNR {result['snr_db']:.1f} dB"
        + (" (defaults used)" if result["default_used"] else ""))
