"""``fusion simulate KIND --seed S --out DIR``: write a seeded scenario and its ground truth."""

from __future__ import annotations

import argparse
import inspect
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
    p.add_argument("--vary", action="store_true",
                   help="draw the physical assumptions from the simulator's documented ranges")
    p.set_defaults(handler=run, inputs=(), out_is_dir=True)


def run(args: argparse.Namespace) -> int:
    """Write the scenario; print the written paths."""
    writer = get_writer(args.kind)
    if args.vary and "vary" not in inspect.signature(writer).parameters:
        raise ValueError(f"scenario kind {args.kind!r} has no --vary")
    paths = writer(args.out, seed=args.seed, **({"vary": True} if args.vary else {}))
    for path in paths:
        emit(str(path))
    return 0
