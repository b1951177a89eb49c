"""The passive pipeline example runs small, keeps identities and ends the faded track."""

from __future__ import annotations

import importlib.util
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "passive_pipeline.py"


def _load_main():
    spec = importlib.util.spec_from_file_location("passive_pipeline_example", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


def test_example_runs(capsys):
    """300 scans of seed 0: six tracks, every scored crossing kept, the fading track ended."""
    summary = _load_main()(["--seed", "0", "--scans", "300"])
    assert summary["tracks"] == 6
    scored = [o for o in summary["outcomes"] if o != "unscored"]
    assert scored and all(o == "kept" for o in scored)
    assert summary["rmse_deg"] < 0.5
    assert summary["ended"] == [4]
    assert "track 4" in capsys.readouterr().out
