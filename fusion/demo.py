"""``fusion demo``: every pipeline on built-in simulated scenarios.

Each part is a function ``run_demo(out_dir, *, seed) -> dict`` that writes its results and a
figure into its own folder and returns a few measured summary numbers. The demo runs the parts
in order, writes ``summary.json`` and ``summary.md`` (every figure linked, with what it shows and
its numbers: :mod:`fusion.demos.summary`) into the output folder, and reports a part that fails
without hiding the others' results.
"""

from __future__ import annotations

import importlib
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fusion._progress import track_progress
from fusion.demos.summary import write_summary
from fusion.io import write_json

logger = logging.getLogger(__name__)

#: (part name, "module:function") in the order the demo runs them.
PARTS: list[tuple[str, str]] = [
    ("acquisition", "fusion.demos.acquisition:run_demo"),
    ("clicks-scenario", "fusion.demos.clicks:run_demo"),
    ("tma", "fusion.demos.tma:run_demo"),
    ("tqi", "fusion.demos.tqi:run_demo"),
    ("crossings", "fusion.demos.crossings:run_demo"),
    ("active", "fusion.demos.active:run_demo"),
    ("smoothing", "fusion.demos.smoothing:run_demo"),
    ("passive", "fusion.demos.passive:run_demo"),
]


@dataclass(frozen=True)
class PartResult:
    """Outcome of one demo part.

    Attributes
    ----------
    name : str
        Part name (also its sub-folder).
    ok : bool
        Whether the part ran to the end.
    seconds : float
        Wall time, s.
    summary : dict
        The part's measured numbers, or ``{"error": message}``.
    """

    name: str
    ok: bool
    seconds: float
    summary: dict[str, Any] = field(default_factory=dict)


def _load(target: str) -> Callable[..., dict[str, Any]]:
    module, func = target.split(":")
    return getattr(importlib.import_module(module), func)


def run_demo(
    out_dir: Path, *, seed: int = 0, parts: Sequence[str] | None = None, quiet: bool = False
) -> list[PartResult]:
    """Run the demo parts and write the summary.

    Parameters
    ----------
    out_dir : pathlib.Path
        Output folder; each part writes into ``out_dir / name``.
    seed : int, optional
        Seed of every simulated scenario.
    parts : sequence of str, optional
        Names of the parts to run (default: all).
    quiet : bool, optional
        No progress bar (there is none either when standard error is not a terminal).

    Returns
    -------
    list of PartResult
    """
    import matplotlib

    matplotlib.use("Agg")
    known = [name for name, _ in PARTS]
    chosen = list(known) if parts is None else list(parts)
    unknown = [p for p in chosen if p not in known]
    if unknown:
        raise ValueError(f"unknown demo part(s) {', '.join(unknown)} (choose from {', '.join(known)})")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    results = []
    todo = [(name, target) for name, target in PARTS if name in chosen]
    for name, target in track_progress(todo, quiet=quiet, desc="demo", unit="part",
                                       total=len(todo)):
        t0 = time.perf_counter()
        part_dir = out_dir / name
        part_dir.mkdir(parents=True, exist_ok=True)
        try:
            summary = dict(_load(target)(part_dir, seed=seed))
            ok = True
        except Exception as e:  # a failing part is reported, the others still run
            logger.exception("demo part %s failed", name)
            summary, ok = {"error": f"{type(e).__name__}: {e}"}, False
        results.append(PartResult(name, ok, time.perf_counter() - t0, summary))
    write_json(
        out_dir / "summary.json",
        {"seed": seed, "parts": [r.__dict__ for r in results]},
    )
    write_summary(out_dir, seed=seed, results=results)  # every figure linked, with its numbers
    return results
