"""Shared fixtures of the test suite."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

DATA = Path(__file__).parent / "data"


@pytest.fixture
def data_dir() -> Path:
    """Folder of the recorded-data copies the tests use."""
    return DATA


@pytest.fixture
def run_cli(capsys):
    """Run ``fusion`` in-process: returns (exit code, stdout, stderr)."""
    from fusion.cli import main

    def _run(*argv: str) -> tuple[int, str, str]:
        try:
            code = main([str(a) for a in argv])
        except SystemExit as e:  # argparse errors
            code = int(e.code or 0)
        out = capsys.readouterr()
        return code, out.out, out.err

    return _run


# Hypothesis: deterministic in CI (derandomize), a few hundred examples per property by default;
# FUSION_HYPOTHESIS_EXAMPLES=2000 for a long run, HYPOTHESIS_PROFILE=random for fresh examples.
from hypothesis import HealthCheck, settings  # noqa: E402

_EXAMPLES = int(os.environ.get("FUSION_HYPOTHESIS_EXAMPLES", "200"))
_COMMON = {"max_examples": _EXAMPLES, "deadline": None,
           "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large]}
settings.register_profile("ci", derandomize=True, database=None, **_COMMON)
settings.register_profile("random", **_COMMON)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
