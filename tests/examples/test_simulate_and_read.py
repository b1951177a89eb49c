"""The simulate-and-read example runs small and reports what it wrote."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from fusion.io import read_array

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "simulate_and_read.py"


def _load_main():
    spec = importlib.util.spec_from_file_location("simulate_and_read", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


def test_example_runs_small(tmp_path, capsys):
    """A 2 s, 3-sensor run writes the three files and its summary matches the options."""
    main = _load_main()
    summary = main(["--seed", "1", "--duration", "2", "--sensors", "3", "--sources", "1",
                    "--out", str(tmp_path)])
    assert {p.name for p in tmp_path.iterdir()} == {"audio.flac", "array.json", "truth.json",
                                                    "tdoa_labels.csv"}
    assert summary["channels"] == 3 and len(summary["sensors"]) == 3
    assert summary["fs"] == 96_000.0
    assert summary["duration_s"] == pytest.approx(2.0)
    assert summary["n_sources"] == 1 and summary["n_clicks"] >= 3
    assert summary["file_peak"] == pytest.approx(0.5, abs=1e-6)
    # the largest TDOA cannot exceed the largest sensor separation over the sound speed
    pos = read_array(tmp_path / "array.json").positions
    span = np.linalg.norm(pos[:, None] - pos[None], axis=2).max()
    assert 0.0 < summary["max_abs_tdoa_s"] <= span / summary["sound_speed"]
    assert '"n_clicks"' in capsys.readouterr().out
