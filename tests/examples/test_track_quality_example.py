"""The track-quality example runs, small."""

from __future__ import annotations

import runpy
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "track_quality.py"


def test_track_quality_example_runs(capsys):
    """main() runs on a few tracks and its summary is consistent."""
    main = runpy.run_path(str(EXAMPLE))["main"]
    s = main(n_tracks=4, seed=1)
    assert s["tracks"] == 4
    assert s["changes_hysteresis"] <= s["changes_single_threshold"]
    assert s["lost_when_strong"] < 0.05
    assert "changes_hysteresis" in capsys.readouterr().out
