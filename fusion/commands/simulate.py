"""``fusion simulate KIND --seed S --out DIR``: write a seeded scenario and its ground truth.

Kind ``clicks`` takes more options: ``--duration-s``, ``--whales``, ``--sensors``, ``--snr-db``
and ``--echo`` (see :func:`fusion.simulate.clicks.write_scenario`); given for another kind they
are an error. Options given override the ones ``--vary`` draws.
"""

from __future__ import annotations

import argparse
import inspect
from pathlib import Path

from fusion.cli import DB_RANGE, emit, number, summary
from fusion.simulate import SIMULATORS, get_writer

#: Options of ``fusion simulate clicks`` only: dest -> (option as written, keyword of the writer).
CLICK_OPTIONS = {
    "duration_s": ("--duration-s", "duration_s"),
    "whales": ("--whales", "n_sources"),
    "sensors": ("--sensors", "n_sensors"),
    "snr_db": ("--snr-db", "snr_db"),
    "echo": ("--echo", "echo"),
    "vary_only": ("--vary-only", "vary_only"),
}

#: Groups of ``--vary-only`` (fusion.simulate.whale_range.varied.VARIED_GROUPS; not imported
#: here: --help stays light; a test keeps the two equal).
VARY_GROUPS = ("counts", "floor", "spacing", "sound-speed", "survey", "click-shape",
               "interferers")


def _groups(text: str) -> tuple[str, ...]:
    names = tuple(x.strip() for x in text.split(",") if x.strip())
    bad = [n for n in names if n not in VARY_GROUPS]
    if not names or bad:
        raise argparse.ArgumentTypeError(
            f"expected a comma list of {', '.join(VARY_GROUPS)}, got {text!r}")
    return names


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
    p.add_argument("--traffic", action="store_true",
                   help="bearings only: manoeuvring vessel traffic around a fixed sensor (turns, "
                        "speed changes, close passes, ferries, loiterers; repeated crossings)")
    g = p.add_argument_group("clicks only", "options of `fusion simulate clicks`; they override "
                             "the default (or, with --vary, drawn) values")
    g.add_argument("--duration-s", dest="duration_s", type=number(float, gt=0, le=3600.0),
                   default=None, metavar="SECONDS",
                   help="audio length, s, at most 3600 (held in memory; default 30)")
    g.add_argument("--whales", type=number(int, ge=1), default=None, metavar="N",
                   help="number of whales, 1-5 (default 2)")
    g.add_argument("--sensors", type=number(int, ge=1), default=None, metavar="N",
                   help="number of hydrophones, 3-10 (default 5)")
    g.add_argument("--snr-db", dest="snr_db", type=number(float, ge=DB_RANGE[0], le=DB_RANGE[1]),
                   default=None, metavar="DB",
                   help="SNR of a nominal click at 1 km over the in-band noise (default 30)")
    g.add_argument("--echo", choices=("none", "surface", "bottom", "both"), default=None,
                   help="echoes rendered; puts the hydrophones above a sea floor (default: "
                        "today's surface echo, or both with --vary)")
    g.add_argument("--vary-only", dest="vary_only", type=_groups, default=None,
                   metavar="GROUPS",
                   help="draw only these effects of --vary, the rest as the default scenario "
                        f"(a comma list of {', '.join(VARY_GROUPS)}; e.g. sound-speed)")
    p.set_defaults(handler=run, inputs=(), out_is_dir=True)


def run(args: argparse.Namespace) -> int:
    """Write the scenario; print the written paths."""
    writer = get_writer(args.kind)
    if args.vary and "vary" not in inspect.signature(writer).parameters:
        raise ValueError(f"scenario kind {args.kind!r} has no --vary")
    extra = {kw: getattr(args, dest) for dest, (_, kw) in CLICK_OPTIONS.items()
             if getattr(args, dest, None) is not None}
    if args.kind != "clicks":
        for dest, (option, _) in CLICK_OPTIONS.items():
            if getattr(args, dest, None) is not None:
                raise ValueError(f"{option} applies to `fusion simulate clicks` only")
    if args.traffic and args.kind != "bearings":
        raise ValueError("--traffic applies to `fusion simulate bearings` only")
    if args.traffic:
        extra["traffic"] = True
    paths = writer(args.out, seed=args.seed, **({"vary": True} if args.vary else {}), **extra)
    for path in paths:
        emit(str(path))
    summary("simulate", f"{args.kind} scenario, seed {args.seed}"
            f"{' (varied)' if args.vary else ''}: {len(paths)} file(s) -> {args.out}", err=True)
    return 0
