"""The active-tracking example runs (small) and reports sensible numbers."""

from __future__ import annotations

import importlib.util
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "active_tracking.py"


def test_active_example_runs_small(capsys):
    """main() on a 10-ping scenario prints both modes; coverage is a fraction."""
    spec = importlib.util.spec_from_file_location("active_tracking", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.main(["--seed", "5", "--pings", "10"])
    assert set(out) == {"fuzzy", "kalman"}
    for coverage, false_tracks in out.values():
        assert 0.0 <= coverage <= 1.0 and false_tracks >= 0
    assert "fuzzy" in capsys.readouterr().out
