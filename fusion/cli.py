"""The ``fusion`` command line.

Subcommands live one per module in :mod:`fusion.commands`; each module registers its parser.
Bad input (a missing file, a malformed CSV, NaN values, a wrong channel count, degenerate sensor
geometry, an option out of range, an output path that cannot be written, ...) is reported as one
line on stderr with exit code 2, never as a traceback, and leaves no output behind. Usage errors
found by the argument parser are one line too (``fusion CMD: error: ...``); ``--help`` prints the
full usage.

Output paths: ``--out`` names a file (or, for commands that set ``out_is_dir``, a folder). Missing
folders on the way are created, like ``mkdir -p``; an output that cannot be written (a folder where
a file is expected, a parent that is a file, a read-only folder) is reported before any work is
done.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import math
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

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


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, and which rejects NaN/inf option values.

    argparse prints a usage block and then the error; users of a command-line tool expect the one
    error line (``fusion CMD: error: ...``), with ``--help`` for the usage. Subparsers inherit the
    class, so every subcommand behaves the same.
    """

    def error(self, message: str):  # type: ignore[override]
        """Print ``PROG: error: MESSAGE`` as one line and exit with code 2."""
        msg = " ".join(message.split())
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {msg} (see '{self.prog} --help')\n")

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        """Parse, then reject non-finite float option values (``--sigma nan``, ``--lag inf``)."""
        ns, extras = super().parse_known_args(args, namespace)
        for action in self._actions:
            if not action.option_strings or isinstance(action, argparse._HelpAction):
                continue
            value = getattr(ns, action.dest, None)
            values = value if isinstance(value, list | tuple) else [value]
            for v in values:
                if isinstance(v, float) and not math.isfinite(v) and v != action.default:
                    self.error(f"argument {'/'.join(action.option_strings)}: {v} is not a "
                               "finite number")
        return ns, extras


def number(
    kind: type = float,
    *,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
) -> Callable[[str], float]:
    """An argparse ``type`` for a finite number with bounds (``gt``: >, ``ge``: >=, ``le``: <=).

    ``number(float, gt=0)`` accepts positive floats; ``number(int, ge=1)`` positive integers. A
    bad value becomes the one-line usage error ``argument --opt: must be > 0, got '-1'``.
    """

    def convert(text: str):
        try:
            v = kind(text)
        except ValueError:
            what = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
        for bound, ok, sign in ((gt, lambda b: v > b, ">"), (ge, lambda b: v >= b, ">="),
                                (le, lambda b: v <= b, "<=")):
            if bound is not None and not ok(bound):
                raise argparse.ArgumentTypeError(f"must be {sign} {bound:g}, got {text!r}")
        return v

    convert.__name__ = kind.__name__
    return convert


def check_output(path: str | os.PathLike[str], *, is_dir: bool = False, option: str = "--out") -> None:
    """Raise ValueError (naming `option` and the path) if `path` cannot be written.

    A missing folder is fine (it is created when the output is written); a folder where a file is
    expected, a file where a folder is expected, a parent that is not a folder, or a folder that
    is not writable is not.
    """
    p = Path(path)
    where = f"{option} {p}"
    if is_dir:
        if p.exists() and not p.is_dir():
            raise ValueError(f"{where}: exists and is not a folder")
    elif p.is_dir():
        raise ValueError(f"{where}: is a folder, expected a file name")
    elif str(p).endswith(("/", os.sep)):
        raise ValueError(f"{where}: expected a file name, not a folder")
    parent = p if is_dir else p.parent
    parent = Path(os.path.abspath(parent))
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"{where}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{where}: folder {parent} is not writable")


def _os_error_message(e: OSError) -> str:
    """``path: reason`` of an OSError (the destination of a failed rename, not its temp file)."""
    name = e.filename2 if e.filename2 is not None else e.filename
    if name is not None and e.strerror:
        return f"{name}: {e.strerror}"
    return str(e)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every registered subcommand."""
    parser = Parser(
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
    """Run the command line; returns the exit code (2: bad input or usage, see module notes)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # usage error (exit 2, one line already printed), --help, --version
        if e.code is None:
            return 0
        return e.code if isinstance(e.code, int) else EXIT_BAD_INPUT
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="fusion: %(levelname)s: %(message)s",
        stream=sys.stderr,
    )
    try:
        out = getattr(args, "out", None)
        if out is not None:
            check_output(out, is_dir=bool(getattr(args, "out_is_dir", False)))
        return int(args.handler(args) or 0)
    except (ValueError, OSError) as e:  # FileNotFoundError is an OSError
        text = _os_error_message(e) if isinstance(e, OSError) else str(e)
        msg = " ".join(text.split()) or type(e).__name__
        print(f"fusion {args.command}: error: {msg}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("fusion: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
