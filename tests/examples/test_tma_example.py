"""The TMA example runs small: unobservable on the first leg, accurate after the turn."""

from __future__ import annotations

import importlib.util
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "tma.py"


def _load_main():
    spec = importlib.util.spec_from_file_location("tma_example", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


def test_example_runs_small(capsys):
    """A 20 min scenario: first leg flagged unobservable, both legs within 10 % in range."""
    summary = _load_main()(["--seed", "2", "--duration", "1200", "--period", "30"])
    assert not summary["first_leg"]["observable"]
    both = summary["both_legs"]
    assert both["observable"]
    assert abs(both["range_error_pct"]) < 10.0
    assert both["range_sigma_m"] > 0.0
    assert '"both_legs"' in capsys.readouterr().out
