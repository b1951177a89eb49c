"""The report example runs small: smooth and crossings outputs drawn as PNG figures."""

from __future__ import annotations

import importlib.util
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "report_figures.py"


def test_report_example_runs_small(tmp_path, capsys):
    """examples/report_figures.py writes the smoothed and crossings figures of a 15-minute run."""
    spec = importlib.util.spec_from_file_location("report_example", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = mod.main(["--seed", "1", "--tracks", "4", "--minutes", "15", "--out", str(tmp_path)])
    names = sorted(Path(p).name for p in out["figures"])
    assert names == ["crossings.png", "crossings_bearing_time.png", "smoothed.png"]
    assert out["alerts"] >= 1  # the scenario's crossing pair raises alerts
    for p in out["figures"]:
        assert Path(p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and Path(p).stat().st_size > 15_000
    assert "fusion report" in capsys.readouterr().out
