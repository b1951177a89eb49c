"""The click front-end example runs small: valid TDOAs close to the truth."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "click_tdoas.py"


def _load_main():
    spec = importlib.util.spec_from_file_location("click_tdoas_example", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


def test_example_runs_small(capsys):
    """One whale, 16 s: every window between the first and last has valid TDOAs, all of them
    within 5 us of the truth."""
    summary = _load_main()(["--seed", "4", "--whales", "1", "--duration", "16"])
    assert len(summary["windows"]) == 3
    errors = [r["error_us"] for w in summary["windows"] for r in w["valid"]]
    assert len(errors) >= 6
    assert np.max(errors) < 5.0
    assert '"valid"' in capsys.readouterr().out
