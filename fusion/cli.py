"""The ``fusion`` command line.

Subcommands live one per module in :mod:`fusion.commands`; each module registers its parser.
Bad input (a missing file, a malformed CSV, NaN values, a wrong channel count, degenerate sensor
geometry, ...) is reported as one line on stderr with exit code 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from fusion import __version__

#: Modules of :mod:`fusion.commands`, in the order they appear in ``fusion --help``.
COMMAND_MODULES: list[str] = [
    "fusion.commands.simulate",
    "fusion.commands.demo",
    "fusion.commands.acquire",
    "fusion.commands.crossings",
    "fusion.commands.tqi",
    "fusion.commands.tma",
    "fusion.commands.smooth",
    "fusion.commands.track",
]

#: Exit code for bad input or bad options.
EXIT_BAD_INPUT = 2


def emit(text: str, *, err: bool = False) -> None:
    """Write one line of command output: stdout for results, stderr (``err=True``) for notes."""
    print(text, file=sys.stderr if err else sys.stdout)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every registered subcommand."""
    parser = argparse.ArgumentParser(
        prog="fusion",
        description="Probabilistic sensor fusion for underwater acoustics on factor graphs.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="fusion: %(levelname)s: %(message)s",
        stream=sys.stderr,
    )
    try:
        return int(args.handler(args) or 0)
    except (ValueError, OSError) as e:  # FileNotFoundError is an OSError
        msg = " ".join(str(e).split()) or type(e).__name__
        print(f"fusion {args.command}: error: {msg}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("fusion: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
