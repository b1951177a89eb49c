"""End-to-end test of ``fusion demo``: every part runs and writes its results and figures."""

from __future__ import annotations

import json

from fusion.demo import PARTS


def test_fusion_demo_runs_every_part(run_cli, tmp_path):
    """`fusion demo --out DIR` exits 0 with every part ok, a figure per part and sane numbers."""
    out = tmp_path / "demo"
    code, stdout, _ = run_cli("demo", "--out", out)
    assert code == 0, stdout
    summary = json.loads((out / "summary.json").read_text())
    parts = {p["name"]: p for p in summary["parts"]}
    assert [p["name"] for p in summary["parts"]] == [name for name, _ in PARTS]
    failed = {name: p["summary"] for name, p in parts.items() if not p["ok"]}
    assert failed == {}
    for name, _ in PARTS:
        files = list((out / name).iterdir())
        assert any(f.suffix == ".png" for f in files), name  # every part draws a figure
        assert f"## {name} — ok" in (out / "summary.md").read_text(encoding="utf-8")
    acq = parts["acquisition"]["summary"]
    assert abs(acq["bearing_deg"] - acq["true_bearing_deg"]) < 2.0
    assert abs(acq["rate_deg_per_min"] - acq["true_rate_deg_per_min"]) < 5.0
    tma = parts["tma"]["summary"]
    assert tma["observable"] and tma["final_range_error_pct"] < 20.0
    tqi = parts["tqi"]["summary"]
    assert tqi["changes_hysteresis"] < tqi["changes_single_threshold"]  # hysteresis steadies
    assert tqi["lost_declared_hysteresis"] >= tqi["loss_onset_update"]
    smoothing = parts["smoothing"]["summary"]
    assert smoothing["tracks"] == smoothing["true_tracks"]
    assert smoothing["median_track_rmse_deg"] < smoothing["raw_noise_deg"]
