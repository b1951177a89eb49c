"""``fusion demo [--out DIR]``: run every pipeline on built-in simulated scenarios."""

from __future__ import annotations

import argparse
from pathlib import Path

from fusion.cli import emit, number, summary
from fusion.demo import run_demo


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``demo`` subcommand."""
    p = sub.add_parser(
        "demo",
        help="run every pipeline on built-in simulated scenarios",
        description="Run every pipeline on built-in scenarios; write results, figures and a summary.",
    )
    p.add_argument("--out", type=Path, default=Path("fusion-demo"),
                   help="output folder (default fusion-demo)")
    p.add_argument("--seed", type=number(int, ge=0), default=0, help="scenario seed (default 0)")
    p.add_argument("--part", action="append", default=None, help="run only this part (repeatable)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (none either when standard error is not a terminal)")
    p.set_defaults(handler=run, inputs=(), out_is_dir=True,
                   outputs_together=False)  # reads back its scenario files


def run(args: argparse.Namespace) -> int:
    """Run the demo; print one line per part; exit 1 if a part failed."""
    results = run_demo(args.out, seed=args.seed, parts=args.part, quiet=args.quiet)
    for r in results:
        status = "ok" if r.ok else "FAILED"
        nums = ", ".join(f"{k}={v}" for k, v in r.summary.items())
        emit(f"{r.name:<18} {status:<6} {r.seconds:6.1f} s  {nums}")
    n_ok = sum(r.ok for r in results)
    summary("demo", f"{n_ok} of {len(results)} part(s) ok -> {args.out}/ (summary.md, "
            "summary.json)")
    return 0 if all(r.ok for r in results) else 1
