"""End-to-end test of ``fusion demo``: every part runs and writes its results and figures."""

from __future__ import annotations

import json
import re

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
    clicks = parts["clicks-scenario"]["summary"]  # counts first: found and false, then errors
    found, whale_windows = (int(v) for v in clicks["whales_found"].split("/"))
    assert 0 < found <= whale_windows and clicks["false_fixes"] >= 0
    line = next(ln for ln in (out / "summary.md").read_text(encoding="utf-8").splitlines()
                if ln.startswith("- [clicks_tracks.png]"))
    assert line.index("whales_found=") < line.index("false_fixes=") < line.index("source_error")
    _check_summary_links(out)


def _check_summary_links(out):
    """summary.md links every PNG the demo wrote exactly once, relative, each with a description."""
    text = (out / "summary.md").read_text(encoding="utf-8")
    links = re.findall(r"^- \[([^\]]+)\]\(([^)]+)\): (.+)$", text, flags=re.M)
    targets = [t for _, t, _ in links]
    pngs = sorted(str(p.relative_to(out)) for p in out.rglob("*.png"))
    assert sorted(targets) == pngs
    for name, target, what in links:
        assert not target.startswith("/") and (out / target).is_file() and target.endswith(name)
        assert len(what) > 20


def test_summary_links_figures_with_their_numbers(tmp_path):
    """Each figure line says what it shows and carries its part's numbers; unknown figures linked."""
    from fusion.demo import PartResult
    from fusion.demos.summary import FIGURES, summary_lines

    for part, png in (("tma", "tma.png"), ("tma", "extra.png"), ("tqi", "tqi_timeline.png")):
        (tmp_path / part).mkdir(exist_ok=True)
        (tmp_path / part / png).write_bytes(b"png")
    results = [PartResult("tma", True, 1.25, {"final_range_error_pct": 1.5, "observable": True,
                                              "n_bearings": 91}),
               PartResult("tqi", False, 0.5, {"error": "ValueError: boom"})]
    lines = summary_lines(tmp_path, seed=4, results=results)
    what = FIGURES["tma/tma.png"][0]
    assert f"- [tma.png](tma/tma.png): {what} — final_range_error_pct=1.5, observable=True" in lines
    assert "- [extra.png](tma/extra.png): figure of the tma part" in lines
    assert "- numbers: n_bearings=91" in lines  # numbers no figure line carries
    assert "## tqi — FAILED (0.5 s)" in lines and "- numbers: error=ValueError: boom" in lines
