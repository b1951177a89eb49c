"""The fuzzy ranking example runs small and the clues help."""

from __future__ import annotations

import importlib.util
from pathlib import Path

EXAMPLE = Path(__file__).parents[2] / "examples" / "fuzzy_rank.py"


def load_example():
    spec = importlib.util.spec_from_file_location("fuzzy_rank_example", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_fuzzy_rank_example_runs_and_beats_nearest_neighbour(capsys):
    """A small run prints its summary; the fuzzy rank picks the target more often than NN."""
    summary = load_example().main(["--pings", "60", "--clutter", "6", "--seed", "3"])
    assert summary["pings"] == 60
    assert '"fuzzy_rank_correct"' in capsys.readouterr().out
    assert 0.0 <= summary["nearest_neighbour_correct"] <= 1.0
    assert summary["fuzzy_rank_correct"] > summary["nearest_neighbour_correct"]
