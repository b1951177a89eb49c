"""Seeded scenario generators; ``fusion simulate KIND`` writes their files.

Each kind's ``write_scenario(out_dir, *, seed) -> list[Path]`` writes the scenario in the
project's file formats plus its ground truth: `out_dir` is the output folder (created if
missing), `seed` the scenario seed, and the paths of the written files are returned. Options a
kind takes beyond these (such as ``vary``) are documented by its writer, which refers here for
the rest. The same generators serve tests, examples, benchmarks and ``fusion demo``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from pathlib import Path

__all__ = ["SIMULATORS", "get_writer"]

#: Scenario kind -> "module:function" of its writer.
SIMULATORS: dict[str, str] = {
    "cube": "fusion.simulate.cube:write_scenario",
    "clicks": "fusion.simulate.clicks:write_scenario",
    "bearings": "fusion.simulate.bearings:write_scenario",
    "amplitudes": "fusion.simulate.amplitudes:write_scenario",
    "tma": "fusion.simulate.tma:write_scenario",
    "multistatic": "fusion.simulate.multistatic:write_scenario",
    "passive": "fusion.simulate.passive:write_scenario",
}


def get_writer(kind: str) -> Callable[..., list[Path]]:
    """The ``write_scenario`` function of a scenario kind."""
    if kind not in SIMULATORS:
        raise ValueError(f"unknown scenario kind {kind!r} (choose from {', '.join(SIMULATORS)})")
    module, func = SIMULATORS[kind].split(":")
    return getattr(importlib.import_module(module), func)
