"""``fusion simulate KIND --seed S --out DIR``: write a seeded scenario and its ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path

from fusion.cli import emit, number
from fusion.simulate import SIMULATORS, get_writer


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` subcommand."""
    p = sub.add_parser(
        "simulate",
        help="write a simulated scenario in the project's file formats",
        description="Write a seeded scenario (inputs of the other subcommands) plus ground truth.",
    )
    p.add_argument("kind", choices=sorted(SIMULATORS), help="scenario kind")
    p.add_argument("--seed", type=number(int, ge=0), default=0, help="random seed (default 0)")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.set_defaults(handler=run, inputs=(), out_is_dir=True)


def run(args: argparse.Namespace) -> int:
    """Write the scenario; print the written paths."""
    paths = get_writer(args.kind)(args.out, seed=args.seed)
    for path in paths:
        emit(str(path))
    return 0
