"""The acquisition example runs small and recovers a high bearing rate."""

from __future__ import annotations

import importlib.util
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "acquisition.py"


def _load_main():
    spec = importlib.util.spec_from_file_location("acquisition_example", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


def test_example_runs(capsys):
    """At 10 dB and 30 deg/min the example's estimate is within 25 % and no default is used."""
    summary = _load_main()(["--seed", "1", "--rate", "30", "--snr", "10"])
    assert not summary["default_used"]
    assert abs(summary["bearing_rate_deg_per_min"] - 30.0) <= 7.5
    assert abs(summary["bearing_deg"] - summary["true_bearing_deg"]) < 5.0
    assert '"bearing_rate_deg_per_min"' in capsys.readouterr().out
