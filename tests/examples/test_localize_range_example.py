"""The range example runs small: a whale with bottom and surface echoes localized within 10 m."""

from __future__ import annotations

import importlib.util
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "localize_range.py"


def _load_main():
    spec = importlib.util.spec_from_file_location("localize_range_example", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


def test_example_runs_small(capsys):
    """One whale, 20 s, bottom and surface echoes: every window's whale found, no false fix,
    TDOAs within a microsecond at their own time; the command reports its decisions."""
    s = _load_main()(["--seed", "21", "--whales", "1", "--echo", "both", "--duration-s", "20"])
    assert s["windows"] == 5
    assert s["found_fraction"] >= 0.8 and s["false_fraction"] == 0.0
    assert s["median_error_m"] < 1.0 and s["median_tdoa_error_us"] < 1.0
    err = capsys.readouterr().err
    assert "replica: estimated" in err and "bottom echoes" in err and "sound speed" in err
    assert abs(s["sound_speed_mps"] - s["array_file_sound_speed_mps"]) < 1.0  # the file was right
