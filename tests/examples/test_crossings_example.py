"""The crossings example runs end to end on a small scenario."""

from __future__ import annotations

import importlib.util
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "crossings.py"


def test_crossings_example_runs_small(capsys):
    """examples/crossings.py detects the crossings of a short scenario."""
    spec = importlib.util.spec_from_file_location("crossings_example", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = mod.main(["--seed", "1", "--tracks", "8", "--minutes", "20"])
    assert out["true_crossings"] >= 1
    assert out["detected"] == out["true_crossings"]
    assert "t_cross=" in capsys.readouterr().out
