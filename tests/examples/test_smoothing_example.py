"""The smoothing example runs small and produces sensible numbers."""

import importlib.util
from pathlib import Path

import numpy as np

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "smoothing.py"


def test_example_runs_small():
    """main() on a short two-track scenario returns tracks with sub-degree error."""
    spec = importlib.util.spec_from_file_location("smoothing_example", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = mod.main(["--seed", "1", "--duration", "600", "--tracks", "2"])
    assert out["tracks"] >= 2
    assert np.isfinite(out["median_track_rmse_deg"]) and out["median_track_rmse_deg"] < 1.0
