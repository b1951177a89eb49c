"""The ``fusion`` command line.

Subcommands live one per module in :mod:`fusion.commands` and are listed in :data:`COMMANDS`. Only
the chosen command's module is imported (``fusion --help`` imports none), so the top-level help
and usage errors are instant whatever the commands need.

Bad input (a missing file, a malformed CSV, NaN values, a wrong channel count, degenerate sensor
geometry, an option out of range, an output path that cannot be written, ...) is reported as one
line on stderr with exit code 2, never as a traceback, and leaves no output behind. Usage errors
found by the argument parser are one line too (``fusion CMD: error: ...``); ``--help`` prints the
full usage. Notes and warnings are lines ``fusion CMD: warning: ...`` on stderr, held until the
command ends (:mod:`fusion._notes`): a failing run prints its error line only. SIGTERM and SIGHUP
end a run like Ctrl-C (temporaries removed, exit 128 + signal).

Outputs never destroy anything. Before any work, ``--out`` is checked against the command's
inputs and the file system:

- no output (``--out``, each file written inside an ``--out`` folder, ``--replica-out``, ...)
  may be an input (also a file read inside an input folder) or another output;
- ``--out`` naming an input (the same file, also through another path, a symbolic link or a hard
  link) is refused;
- a symbolic link is written through: its target is replaced, the link stays a link;
- a folder where a file is expected, a FIFO, a device (``/dev/null``, ``/dev/full``,
  ``/dev/stdout`` on a pipe or a terminal), a socket, a parent that is not a folder or a folder
  that is not writable is refused;
- ``--out -`` writes a one-file output (a CSV table or JSON) to standard output -- the command's
  own messages then go to stderr; commands that write a folder refuse it (``./-`` names a file
  called ``-``);
- missing folders on the way are created, like ``mkdir -p``; writes are atomic
  (:func:`fusion.io.atomic_output`), and temporaries of killed runs are removed by the next run;
- all outputs of a run are committed together at its end, or none (:func:`_run_outputs`); a
  failed run (bad input found late, a full disk: ``out.csv: No space left on device``) removes
  the folders it created.

A command module declares its inputs with ``set_defaults(inputs=("bearings", ...))`` (the dest
names of the options that name files it reads); ``out_is_dir=True`` when ``--out`` is a folder;
``out_stdout=False`` to refuse ``--out -`` for a one-file output that is not text;
``outputs_together=False`` when it reads back what it wrote (see :func:`_run_outputs`).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import math
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import ModuleType

from fusion import __version__
from fusion._notes import held_notes
from fusion._options import (  # noqa: F401 (re-exported)
    DB_RANGE,
    MAX_OPTION_ABS,
    MAX_SCANS_OPTION,
    MIN_POSITIVE_OPTION,
    add_old_spellings,
    number,
    old_spelling_warnings,
)
from fusion._output import (
    STDOUT,
    Terminated,
    output_destination,
    outputs_together,
    termination_as_interrupt,
)
from fusion._validation import GridTooLarge

#: The subcommands, in the order of ``fusion --help``: name -> (module, one-line help).
#: A module is imported only when its command is chosen. To add a command, add one line.
COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("fusion.commands.simulate", "write a simulated scenario in the project's file formats"),
    "demo": ("fusion.commands.demo", "run every pipeline on built-in simulated scenarios"),
    "acquire": ("fusion.commands.acquire", "bearing, bearing rate and SNR of a clicked narrowband target"),
    "crossings": ("fusion.commands.crossings", "predict and detect crossings of bearing tracks"),
    "tqi": ("fusion.commands.tqi", "track quality (lost/uncertain/low_snr/strong) of tracker outputs"),
    "tma": ("fusion.commands.tma", "bearings-only target motion analysis"),
    "smooth": ("fusion.commands.smooth", "smooth bearing tracks (labelled, or detections of unknown origin)"),
    "track": ("fusion.commands.track", "track targets in active-sonar (or any position) detections"),
    "passive": ("fusion.commands.passive", "track narrowband lines through beam/frequency/time cubes"),
    "localize": ("fusion.commands.localize", "localize clicking sources (whales) from multichannel audio"),
    "train-validator": ("fusion.commands.train_validator", "retrain the TDOA validator on labelled audio"),
    "import": ("fusion.commands.import_data", "convert a recorded data set into the project's CSV files"),
    "report": ("fusion.commands.report", "PNG figures of any command's output, with axis labels and units"),
}

#: Exit code for bad input or bad options.
EXIT_BAD_INPUT = 2
#: Exit code when a command's module cannot be loaded (a broken installation).
EXIT_UNAVAILABLE = 1

_data_on_stdout = False  # set while a command writes its output to stdout (``--out -``)


def emit(text: str, *, err: bool = False) -> None:
    """Write one line of command output: stdout for results, stderr (``err=True``) for notes.

    While the command's ``--out`` is ``-`` (its result goes to stdout), every line goes to stderr.
    """
    print(text, file=sys.stderr if err or _data_on_stdout else sys.stdout)


#: Summary lines of the running command, printed after its held warnings (None: not held).
_held_summaries: list[tuple[str, bool]] | None = None


def summary(command: str, text: str, *, err: bool = False) -> None:
    """The one summary line every command ends with: ``fusion COMMAND: TEXT`` (see :func:`emit`).

    Inside :func:`main` the line is held and printed last, after the run's warnings (a failing
    run prints only its error line).
    """
    line = f"fusion {command}: {text}"
    if _held_summaries is None:
        emit(line, err=err)
    else:
        _held_summaries.append((line, err))


def path_argument(text: str) -> Path:
    """The value of a path option (``type=Path``): ``Path(text)``, but ``./-`` stays a file.

    ``Path("./-")`` is ``Path("-")``, which names standard output (``--out -``); the file called
    ``-`` that ``./-`` names is kept as its absolute path.

    >>> path_argument("./-") == Path.cwd() / "-", path_argument("-"), path_argument("a/b.csv")
    (True, PosixPath('-'), PosixPath('a/b.csv'))
    """
    p = Path(text)
    if os.fspath(p) == STDOUT and text != STDOUT:
        return Path(os.path.abspath(text))
    return p


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, and which rejects NaN/inf option values.

    argparse prints a usage block and then the error; users of a command-line tool expect the one
    error line (``fusion CMD: error: ...``), with ``--help`` for the usage. Subparsers inherit the
    class, so every subcommand behaves the same. Options of ``type=Path`` are read by
    :func:`path_argument` (``./-`` is a file called ``-``, not standard output).
    """

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.register("type", Path, path_argument)

    def error(self, message: str):  # type: ignore[override]
        """Print ``PROG: error: MESSAGE`` as one line and exit with code 2."""
        msg = " ".join(message.split())
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {msg} (see '{self.prog} --help')\n")

    def format_usage(self) -> str:
        """The usage, options required under any spelling shown required (``required_any``)."""
        with self._required_shown():
            return super().format_usage()

    def format_help(self) -> str:
        """The help, options required under any spelling shown required (``required_any``)."""
        with self._required_shown():
            return super().format_help()

    @contextlib.contextmanager
    def _required_shown(self) -> Iterator[None]:
        either = [a for a in self._actions if getattr(a, "required_any", False)]
        for action in either:
            action.required = True
        try:
            yield
        finally:
            for action in either:
                action.required = False

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        """Parse, then reject non-finite float option values (``--sigma nan``, ``--graph-lag-s inf``)."""
        ns, extras = super().parse_known_args(args, namespace)
        for action in self._actions:
            if not action.option_strings or isinstance(action, argparse._HelpAction):
                continue
            if action.help == argparse.SUPPRESS and action.default == argparse.SUPPRESS:
                continue  # an old spelling (fusion._options.OLD_SPELLINGS): checked as the new
            if getattr(action, "required_any", False) and getattr(ns, action.dest, None) is None:
                self.error(f"the following arguments are required: {action.option_strings[0]}")
            value = getattr(ns, action.dest, None)
            values = value if isinstance(value, list | tuple) else [value]
            for v in values:
                if isinstance(v, float) and not math.isfinite(v) and v != action.default:
                    self.error(f"argument {'/'.join(action.option_strings)}: {v} is not a "
                               "finite number")
        return ns, extras


# --------------------------------------------------------------------------------------------
# paths: outputs and inputs
# --------------------------------------------------------------------------------------------
def check_output(path: str | os.PathLike[str], *, is_dir: bool = False, option: str = "--out") -> None:
    """Raise ValueError (naming `option` and the path) if `path` cannot be written safely.

    A missing file or folder is fine (it is created when the output is written), and so is a
    symbolic link (the output replaces its target). A folder where a file is expected, a file
    where a folder is expected, a FIFO, a device or a socket, a symbolic-link loop, a parent that
    is not a folder, or a folder that is not writable is not.
    """
    text = os.fspath(path)
    p = Path(text)
    where = f"{option} {p}"
    if is_dir:
        if p.exists() and not p.is_dir():
            raise ValueError(f"{where}: exists and is not a folder")
        target = p
    else:
        if text.endswith(("/", os.sep)):
            raise ValueError(f"{where}: expected a file name, not a folder")
        try:
            target = output_destination(p)
        except ValueError as e:
            raise ValueError(f"{option} {e}") from None
    parent = target if is_dir else target.parent
    parent = Path(os.path.abspath(parent))
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"{where}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{where}: folder {parent} is not writable")


def _option_names(parser: argparse.ArgumentParser) -> dict[str, str]:
    """dest -> how the user wrote it (``--bearings``, or the metavar of a positional)."""
    names = {}
    for action in parser._actions:
        if action.help == argparse.SUPPRESS and action.dest in names:
            continue  # an old spelling: the new one names the option
        if action.option_strings:
            names[action.dest] = max(action.option_strings, key=len)
        else:
            names[action.dest] = action.metavar if isinstance(action.metavar, str) else action.dest
    return names


def _paths(value: object) -> Iterator[Path]:
    """The paths in an argument value (a str/Path, or a list/tuple of them)."""
    for v in value if isinstance(value, list | tuple) else [value]:
        if isinstance(v, str | os.PathLike) and os.fspath(v) not in ("", STDOUT):
            yield Path(v)


def _same_file(a: Path, b: Path) -> bool:
    """Whether `a` and `b` exist and are one file (same device and inode: links, other paths)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _inputs(args: argparse.Namespace, names: dict[str, str]) -> Iterator[tuple[str, Path]]:
    """(how the user named it, path) of every file the command may read.

    Declared inputs (``args.inputs``), any other path-typed option, and inside a folder input
    the files the command reads there (``args.input_files``: dest -> file names).
    """
    declared = tuple(getattr(args, "inputs", ()))
    outs = {"out", *getattr(args, "more_outputs", ())}
    others = [d for d, v in vars(args).items() if d not in declared and isinstance(v, os.PathLike)]
    inside = dict(getattr(args, "input_files", {}))
    for dest in (*declared, *others):
        if dest in outs:
            continue
        for p in _paths(getattr(args, dest, None)):
            yield f"{names.get(dest, dest)} {p}", p
            for name in inside.get(dest, ()):
                yield f"{names.get(dest, dest)} {p} (its {name})", p / name


def _outputs(args: argparse.Namespace, names: dict[str, str]) -> list[tuple[str, Path]]:
    """(how the user named it, path) of every file the command writes (``--out - `` excluded).

    ``--out`` itself, or for a folder output each file it writes there (``args.out_files``);
    and every other output option (``args.more_outputs``: dests), each checked writable.
    """
    out = getattr(args, "out", None)
    found = []
    if out is not None and os.fspath(out) != STDOUT:
        if getattr(args, "out_is_dir", False):
            found += [(f"--out {out}", Path(out))]  # the folder itself is no input either
            found += [(f"--out {out} (its {name})", Path(out) / name)
                      for name in getattr(args, "out_files", ())]
        else:
            found.append((f"--out {out}", Path(out)))
    for dest in getattr(args, "more_outputs", ()):
        if os.fspath(getattr(args, dest, None) or "") == STDOUT:
            raise ValueError(f"{names.get(dest, dest)} -: this output cannot go to standard "
                             "output; name a file (./- for a file called '-')")
        for p in _paths(getattr(args, dest, None)):
            check_output(p, option=names.get(dest, dest))
            found.append((f"{names.get(dest, dest)} {p}", p))
    return found


def _destination(p: Path) -> str:
    """The absolute file an output to `p` replaces (links resolved), to compare outputs."""
    return os.path.realpath(p if os.path.isdir(p) else output_destination(p))


def check_paths(args: argparse.Namespace, names: dict[str, str]) -> bool:
    """Check inputs and outputs before any work; return whether the output goes to stdout.

    Declared inputs (``args.inputs``) must exist. ``--out`` must be writable
    (:func:`check_output`), and so must every other output (``args.more_outputs``). No output
    -- ``--out``, each file written inside an ``--out`` folder (``args.out_files``), another
    output option -- may be the same file as any input (declared, any other path-typed option,
    or a file read inside a folder input: ``args.input_files``), nor the same file as another
    output. ``--out -`` is accepted for one-file outputs.

    Raises
    ------
    ValueError
        One line naming the option(s) and path(s) at fault.
    """
    out = getattr(args, "out", None)
    is_dir = bool(getattr(args, "out_is_dir", False))
    for dest in getattr(args, "inputs", ()):
        for p in _paths(getattr(args, dest, None)):
            if not os.path.exists(p):
                raise ValueError(f"{names.get(dest, dest)} {p}: no such file")
    to_stdout = out is not None and os.fspath(out) == STDOUT
    if to_stdout:
        if is_dir:
            raise ValueError("--out -: this command writes a folder, not one file; name a folder "
                             "(./- for a folder called '-')")
        if not getattr(args, "out_stdout", True):
            raise ValueError("--out -: this command's output cannot go to standard output")
    elif out is not None:
        check_output(out, is_dir=is_dir)
    outputs = _outputs(args, names)
    inputs = list(_inputs(args, names))
    seen: dict[str, str] = {}
    for what, p in outputs:
        for source, q in inputs:
            if _same_file(p, q):
                raise ValueError(f"{what} is the same file as the input {source}; refusing to "
                                 "overwrite an input")
        dest = _destination(p)
        if dest in seen:
            raise ValueError(f"{what} is the same file as {seen[dest]}; name two different "
                             "files")
        seen[dest] = what
    return to_stdout


# --------------------------------------------------------------------------------------------
# parser and entry point
# --------------------------------------------------------------------------------------------
def chosen_command(argv: Sequence[str]) -> str | None:
    """The subcommand named in `argv` (its first word that is not a top-level option), if any.

    ``None`` when `argv` asks for the top-level help or version first, or names no known command.
    """
    for word in argv:
        if word in ("-h", "--help", "--version"):
            return None
        if word.startswith("-"):
            continue
        return word if word in COMMANDS else None
    return None


def load_command(name: str) -> ModuleType:
    """Import the module of subcommand `name` (see :data:`COMMANDS`)."""
    return importlib.import_module(COMMANDS[name][0])


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser: every subcommand listed, only `command`'s module loaded.

    The other subcommands get a placeholder parser with their one-line help (enough for
    ``fusion --help`` and for the list of choices in usage errors).
    """
    parser = Parser(
        prog="fusion",
        description="Probabilistic sensor fusion for underwater acoustics on factor graphs.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, (_module, help_text) in COMMANDS.items():
        if name == command:
            load_command(name).register(sub)
            add_old_spellings(sub.choices[name], name)  # hidden, warn when used
        else:
            sub.add_parser(name, help=help_text, add_help=False)
    return parser


class _LineFormatter(logging.Formatter):
    """``fusion CMD: warning: message`` -- the form of the command's error lines."""

    def __init__(self, command: str) -> None:
        super().__init__()
        self.command = command

    def format(self, record: logging.LogRecord) -> str:
        line = f"fusion {self.command}: {record.levelname.lower()}: {record.getMessage()}"
        if record.exc_info:
            line += "\n" + self.formatException(record.exc_info)
        return line


def _os_error_message(e: OSError) -> str:
    """``path: reason`` of an OSError (the destination of a failed rename, not its temp file)."""
    name = e.filename2 if e.filename2 is not None else e.filename
    if name is not None and e.strerror:
        return f"{name}: {e.strerror}"
    return str(e)


def _run_outputs(args: argparse.Namespace) -> contextlib.AbstractContextManager[None]:
    """A run's outputs, committed together at its end, none on failure (``outputs_together``).

    Commands that read back what they wrote (``localize``, ``demo``) declare
    ``outputs_together=False``; each of their files is still written atomically.
    """
    if not getattr(args, "outputs_together", True):
        return contextlib.nullcontext()
    out = getattr(args, "out", None)
    folders = [out] if out is not None and getattr(args, "out_is_dir", False) else []
    return outputs_together(*folders)


def _silence_stdout() -> None:
    """After a broken pipe on stdout, send what is left to /dev/null (no second error at exit)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # not a real file (tests, embedding)
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (2: bad input or usage, see module notes)."""
    global _data_on_stdout, _held_summaries
    argv = list(sys.argv[1:] if argv is None else argv)
    command = chosen_command(argv)
    try:
        parser = build_parser(command)
    except ImportError as e:
        print(f"fusion {command}: error: the command cannot be loaded ({e})", file=sys.stderr)
        return EXIT_UNAVAILABLE
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # usage error (exit 2, one line already printed), --help, --version
        if e.code is None:
            return 0
        return e.code if isinstance(e.code, int) else EXIT_BAD_INPUT
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_LineFormatter(args.command))
    logging.basicConfig(level=logging.WARNING - 10 * min(args.verbose, 2), handlers=[handler])
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    try:
        _held_summaries = []
        with termination_as_interrupt(), held_notes(handler):  # SIGTERM, SIGHUP: like Ctrl-C
            for line in old_spelling_warnings(args):
                warnings.warn(line, DeprecationWarning, stacklevel=1)
            _data_on_stdout = check_paths(args, _option_names(sub.choices[args.command]))
            with _run_outputs(args):
                code = int(args.handler(args) or 0)
        held, _held_summaries = _held_summaries, None
        for line, err in held:  # after the warnings: the command ends with its summary
            emit(line, err=err)
        return code
    except BrokenPipeError:  # `fusion ... --out - | head`: the reader left; not an error of ours
        _silence_stdout()
        return 1
    except (ValueError, OSError) as e:  # FileNotFoundError is an OSError
        text = _os_error_message(e) if isinstance(e, OSError) else str(e)
        if isinstance(e, GridTooLarge):  # sized by the data of the (first) input file
            first = next(_paths(getattr(args, next(iter(getattr(args, "inputs", ())), ""), None)),
                         None)
            text = text if first is None else f"{first}: {text}"
        msg = " ".join(text.split()) or type(e).__name__
        print(f"fusion {args.command}: error: {msg}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt as e:  # Ctrl-C, or SIGTERM/SIGHUP (Terminated)
        signum = e.signum if isinstance(e, Terminated) else 2
        print("fusion: interrupted" if signum == 2 else f"fusion: terminated (signal {signum})",
              file=sys.stderr)
        return 128 + signum
    finally:
        _data_on_stdout, _held_summaries = False, None


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
