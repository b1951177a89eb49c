"""Hypothesis: every command, any argument set or damaged input: its output, or exit 2 and one line.

Two properties per command (``fusion --help`` lists them; ``simulate`` is split into its click
kind and the others, ``localize`` into audio and ``--events``):

- ``test_arguments[CMD]``: a valid command line, then some of its values replaced and some of the
  command's other options added, every option read from the command's own parser (a new option
  is drawn without touching this file). Values mix valid, boundary and hostile ones: ``nan``,
  ``inf``, ``1e308``, ``5e-324``, negative, 0, huge integers, empty strings, text, paths into the
  inputs, into the output, into a folder, ``-``, ``/dev/null``.
- ``test_inputs[CMD]``: the valid command line with one of its input files damaged: CSV rows and
  cells mutated, JSON values replaced (NaN, 1e308, wrong types), ``.npz`` arrays replaced or
  removed, audio truncated or rewritten with another shape.

Each run happens in-process (:func:`fusion.cli.main`) in a fresh copy of tiny inputs made once
per session (a 3 s simulated click recording, short simulated tables and cubes, the recorded
test data), with that copy as the working folder. It must end with exit 0 and its output
written (the inputs unchanged), or exit 2 with exactly one stderr line ``fusion CMD: error:
...``, no traceback and nothing written or changed (``check_cli_run`` in ``conftest.py``).

Examples: ``FUSION_HYPOTHESIS_EXAMPLES`` per property when set (e.g. 1000 for the long run of
docs/bad-input.md); unset (CI), the per-command counts of :data:`COMMANDS` (the file takes
about a minute). ``FUSION_PROPERTY_TIMEOUT_S`` (unset in CI) fails an example that runs longer,
to find hangs in long runs.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import shutil
import signal
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from hypothesis import event, given, note, settings
from hypothesis import strategies as st

from fusion.cli import build_parser, main

DATA = Path(__file__).parent / "data"


@dataclass(frozen=True)
class Command:
    """A valid command line (paths relative to the sandbox) and its CI examples.

    ``skip``: options never drawn (each with its reason in :data:`COMMANDS`)."""

    argv: tuple[str, ...]
    examples: int
    skip: tuple[str, ...] = ()


_DASK = ("--workers", "--scheduler")  # start a Dask cluster; bounds: tests/test_cli_limits.py
#: command key -> a valid run on the session's inputs (in/...), writing into out...
COMMANDS: dict[str, Command] = {
    "simulate-clicks": Command(("simulate", "clicks", "--duration-s", "1", "--sensors", "4",
                                "--out", "out"), 12),
    "simulate": Command(("simulate", "tma", "--out", "out"), 20),
    "demo": Command(("demo", "--part", "tqi", "--quiet", "--out", "out"), 4),
    "acquire": Command(("acquire", "--cube", "in/cube.npz", "--beam", "10", "--freq-hz", "300"), 20),
    "crossings": Command(("crossings", "--bearings", "in/bearings.csv", "--out", "out.csv",
                          "--quiet"), 20),
    "tqi": Command(("tqi", "--amplitudes", "in/amplitudes.csv", "--out", "out.csv", "--quiet"), 20),
    "tma": Command(("tma", "--bearings", "in/tma_bearings.csv", "--ownship", "in/ownship.csv",
                    "--out", "out.csv"), 20),
    "smooth": Command(("smooth", "--bearings", "in/bearings.csv", "--out", "out.csv", "--quiet"),
                      10),
    "track": Command(("track", "--detections", "in/detections.csv", "--fit-pings", "20",
                      "--out", "out.csv", "--quiet"), 12),
    "passive": Command(("passive", "--cube", "in/pcube.npz", "--clicks", "in/clicks.csv",
                        "--out", "out", "--quiet"), 5),
    "localize": Command(("localize", "--audio", "in/rec/audio.flac", "--array", "in/rec/array.json",
                         "--window-s", "2", "--hop-s", "1", "--replica", "generic", "--out",
                         "out.json", "--quiet"), 6, _DASK),
    "localize-events": Command(("localize", "--audio", *(f"in/xav/cut1_AMAR173.{i}.flac"
                                                         for i in range(1, 7)),
                                "--array", "in/xav/array.json", "--events", "in/xav/events.csv",
                                "--out", "out.json", "--quiet"), 12, _DASK),
    "train-validator": Command(("train-validator", "--recording", "in/rec", "--window-s", "2",
                                "--hop-s", "1", "--components", "2", "--out", "v.npz",
                                "--quiet"), 5, ("--simulated",)),  # minutes per scenario
    "import": Command(("import", "autoferry", "in/autoferry", "--out", "out"), 20),
    "report": Command(("report", "in/results/tma.csv", "--ownship", "in/ownship.csv", "--out",
                       "out"), 10),
}


def _examples(key: str) -> int:
    given_n = os.environ.get("FUSION_HYPOTHESIS_EXAMPLES")
    return int(given_n) if given_n else COMMANDS[key].examples


# --------------------------------------------------------------------------------------------
# the session's inputs
# --------------------------------------------------------------------------------------------
def _run(*argv: str) -> None:
    with contextlib.redirect_stdout(open(os.devnull, "w")), \
            contextlib.redirect_stderr(open(os.devnull, "w")):
        assert main([str(a) for a in argv]) == 0, argv


def _head(src: Path, dst: Path, rows: int) -> None:
    lines = src.read_text().splitlines()
    dst.write_text("\n".join(lines[: rows + 1]) + "\n")


@pytest.fixture(scope="session")
def inputs(tmp_path_factory) -> Path:
    """Tiny inputs of every command (``in/``), made once: simulated at seed 1, cut short."""
    root = tmp_path_factory.mktemp("prop")
    sim, d = root / "sim", root / "in"
    d.mkdir()
    for kind in ("amplitudes", "bearings", "cube", "multistatic", "passive", "tma"):
        _run("simulate", kind, "--seed", "1", "--out", sim / kind)
    _run("simulate", "clicks", "--seed", "1", "--duration-s", "3", "--out", d / "rec")
    _head(sim / "amplitudes/amplitudes.csv", d / "amplitudes.csv", 300)
    _head(sim / "bearings/bearings.csv", d / "bearings.csv", 300)
    _head(sim / "multistatic/detections.csv", d / "detections.csv", 200)
    shutil.copy(sim / "tma/bearings.csv", d / "tma_bearings.csv")
    shutil.copy(sim / "tma/ownship.csv", d / "ownship.csv")
    shutil.copy(sim / "cube/cube.npz", d / "cube.npz")
    shutil.copy(sim / "passive/cube.npz", d / "pcube.npz")  # 400 scans of 64 beams, 32 bins
    shutil.copy(sim / "passive/clicks.csv", d / "clicks.csv")
    (d / "xav").mkdir()
    for i in range(1, 7):
        shutil.copy(DATA / f"xav/cut1_AMAR173.{i}.flac", d / f"xav/cut1_AMAR173.{i}.flac")
    shutil.copy(DATA / "xav/array.json", d / "xav/array.json")
    _head(DATA / "xav/cut1_events.csv", d / "xav/events.csv", 2)
    shutil.copytree(DATA / "autoferry_raw/scenario2", d / "autoferry")
    res = d / "results"
    _run("tma", "--bearings", d / "tma_bearings.csv", "--ownship", d / "ownship.csv",
         "--out", res / "tma.csv")
    _run("tqi", "--amplitudes", d / "amplitudes.csv", "--out", res / "tqi.csv", "--quiet")
    _run("crossings", "--bearings", d / "bearings.csv", "--out", res / "crossings.csv", "--quiet")
    shutil.rmtree(sim)
    return d


# --------------------------------------------------------------------------------------------
# values
# --------------------------------------------------------------------------------------------
NUMBERS = ["nan", "inf", "-inf", "1e308", "-1e308", "5e-324", "-5e-324", "0", "-0", "-1", "1",
           "2", "0.5", "1e12", "1e13", "-1e12", "999999999999", "99999999999999999999", "100000",
           "100001", "1e-300", "", " ", "abc", "0x10", "1_0", "1e3", "1.5"]
PATHS = ["", "-", "./-", "/dev/null", "missing.csv", "in", "in/", "in/bearings.csv",
         "in/amplitudes.csv", "in/ownship.csv", "in/cube.npz", "in/pcube.npz", "in/clicks.csv",
         "in/rec", "in/rec/audio.flac", "in/rec/array.json", "in/rec/tdoa_labels.csv",
         "in/xav/array.json", "in/xav/events.csv", "in/autoferry", "in/results/tma.csv",
         "in/results/tqi.csv", "in/results/crossings.csv", "out", "out.csv", "out/x.csv",
         "new/deeper/x.csv", "in/new.csv", "v.npz", "out.json", "generic"]


def _number(action: argparse.Action) -> st.SearchStrategy[str]:
    near = []
    if isinstance(action.default, int | float) and not isinstance(action.default, bool):
        near = [repr(action.default * f) for f in (1, 2, 0.5, 10, 0.1, -1)]
    return st.one_of(st.sampled_from(NUMBERS + near), st.integers(-2, 40).map(str),
                     st.floats(allow_nan=True, allow_infinity=True).map(repr))


def _is_path(action: argparse.Action) -> bool:
    return action.type is Path or action.dest in ("out", "bearings", "replica", "scheduler")


def value(action: argparse.Action) -> st.SearchStrategy[list[str]]:
    """Words for one option or positional of the parser (valid, boundary or hostile)."""
    if action.nargs == 0:
        return st.just([])
    if action.choices is not None:
        one = st.sampled_from([*action.choices, "bogus", ""])
    elif _is_path(action):
        one = st.sampled_from(PATHS)
    elif getattr(action.type, "__name__", "") in ("int", "float"):
        one = _number(action)
    else:
        one = st.one_of(st.sampled_from(NUMBERS + PATHS + ["1,300", "10,300,59", "a,b"]),
                        st.text(max_size=5))
    n = action.nargs if isinstance(action.nargs, int) else 1
    if action.nargs in ("+", "*"):
        return st.lists(one, min_size=1, max_size=3)
    return st.lists(one, min_size=n, max_size=n)


def _parser(command: str) -> argparse.ArgumentParser:
    p = build_parser(command)
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[command]


def _options(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    """The documented options of a command (no --help, no hidden old spellings)."""
    return {max(a.option_strings, key=len): a for a in parser._actions
            if a.option_strings and a.help != argparse.SUPPRESS
            and not isinstance(a, argparse._HelpAction)}


def _split(argv: tuple[str, ...], options: dict[str, argparse.Action]) -> tuple[list, list]:
    """(positionals, [(option, words)]) of a command line."""
    alias = {s: max(a.option_strings, key=len) for a in options.values() for s in a.option_strings}
    pos, opts, i = [], [], 1
    while i < len(argv):
        if argv[i] in alias:
            j = i + 1
            while j < len(argv) and argv[j] not in alias:
                j += 1
            nargs = options[alias[argv[i]]].nargs
            if nargs is None:
                j = min(j, i + 2)
            opts.append((alias[argv[i]], list(argv[i + 1: j])))
            i = j
        else:
            pos.append(argv[i])
            i += 1
    return pos, opts


@st.composite
def command_lines(draw, key: str) -> list[str]:
    """The valid command line of `key`, some words replaced, dropped or added."""
    spec = COMMANDS[key]
    command = spec.argv[0]
    parser = _parser(command)
    options = _options(parser)
    positionals = [a for a in parser._actions if not a.option_strings]
    pos, opts = _split(spec.argv, options)
    for k, action in enumerate(positionals):
        if k < len(pos) and draw(st.integers(0, 9)) == 9:
            pos[k] = draw(value(action))[0]
    kept = []
    for name, words in opts:
        what = draw(st.sampled_from(["keep"] * 8 + ["drop", "change"]))
        if what == "change":
            words = draw(value(options[name]))
        if what != "drop":
            kept.append((name, words))
    drawable = sorted(n for n in options if n not in spec.skip)
    for name in draw(st.lists(st.sampled_from(drawable), max_size=4, unique=True)):
        kept.append((name, draw(value(options[name]))))
    argv = [command, *pos]
    for name, words in kept:
        if len(words) == 1 and options[name].nargs is None:
            argv.append(f"{name}={words[0]}")
        else:
            argv += [name, *words]
    return argv


# --------------------------------------------------------------------------------------------
# damaged files
# --------------------------------------------------------------------------------------------
CELLS = ["", "nan", "inf", "-inf", "1e308", "-1e308", "5e-324", "-1e12", "9e11", "1e12", "abc",
         "-1", "0", "1,2", "\"", "\x00", "100000000", "99999999999999999999", " ", "é"]
JSON_VALUES = [None, True, "", "abc", -1, 0, 1e308, -1e308, 5e-324, math.nan, math.inf, [], {},
               [1], [[1, 2, 3]], 10**30, "nan"]


@st.composite
def damaged_csv(draw, text: str) -> str:
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        k = draw(st.integers(0, len(lines) - 1))
        parts = lines[k].split(",")
        what = draw(st.sampled_from(["cell", "cell", "cell", "extra", "drop", "dup", "swap",
                                     "delete", "cut", "header"]))
        if what == "cell":
            parts[draw(st.integers(0, len(parts) - 1))] = draw(st.sampled_from(CELLS))
        elif what == "extra":
            parts.append(draw(st.sampled_from(CELLS)))
        elif what == "drop" and len(parts) > 1:
            parts.pop(draw(st.integers(0, len(parts) - 1)))
        elif what == "dup":
            parts = lines[0].split(",") + [draw(st.sampled_from(lines[0].split(",")))]
        elif what == "swap" and len(lines) > 2:
            j = draw(st.integers(1, len(lines) - 1))
            lines[k], lines[j] = lines[j], lines[k]
            continue
        elif what == "delete" and len(lines) > 1:
            del lines[k]
            continue
        elif what == "cut":
            lines = lines[: k + 1]
            continue
        elif what == "header":
            parts = draw(st.permutations(lines[0].split(",")))
            k = 0
        lines[k] = ",".join(parts)
    return "\n".join(lines) + "\n"


def _leaves(doc, path=()):
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _leaves(v, (*path, k))
    elif isinstance(doc, list) and doc:
        for i in sorted({0, len(doc) // 2, len(doc) - 1}):
            yield from _leaves(doc[i], (*path, i))
    yield path


@st.composite
def damaged_json(draw, text: str) -> str:
    doc = json.loads(text)
    if draw(st.integers(0, 7)) == 0:
        return text[: draw(st.integers(0, len(text) - 1))]
    leaves = list(_leaves(doc))
    for _ in range(draw(st.integers(1, 2))):
        path = draw(st.sampled_from(leaves))
        new = draw(st.sampled_from(JSON_VALUES))
        if not path:
            doc = new
            break
        parent = doc
        try:
            for p in path[:-1]:
                parent = parent[p]
            if isinstance(parent, dict) and draw(st.booleans()) and draw(st.booleans()):
                del parent[path[-1]]
            else:
                parent[path[-1]] = new
        except (KeyError, IndexError, TypeError):
            pass
    return json.dumps(doc)


@st.composite
def damaged_npz(draw, path: Path) -> dict:
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    key = draw(st.sampled_from(sorted(arrays)))
    what = draw(st.sampled_from(["delete", "nan", "scalar", "empty", "shape", "negative"]))
    note(f"{path.name}: {what} {key!r}")
    a = arrays[key]
    if what == "delete":
        del arrays[key]
    elif what == "nan" and a.dtype.kind == "f" and a.size:
        a = a.copy()
        v = draw(st.sampled_from([np.nan, np.inf, 1e308]))
        k = draw(st.integers(0, a.size - 1))
        a.flat[k] = v
        note(f"{path.name}: {key!r} at {np.unravel_index(k, a.shape)} = {v}")
        arrays[key] = a
    elif what == "scalar":
        arrays[key] = np.array(draw(st.sampled_from([0.0, -1.0, 1e308, 5e-324, np.nan, 1e12])))
    elif what == "empty":
        arrays[key] = a[..., :0] if a.ndim else np.array([])
    elif what == "shape":
        arrays[key] = a.reshape(-1)[: max(1, a.size // 2)]
    else:
        arrays[key] = -np.abs(a.astype(float))
    return arrays


@st.composite
def damaged_audio(draw, path: Path):
    """Bytes of a damaged audio file: cut, bytes flipped, or valid audio of another shape."""
    data = path.read_bytes()
    what = draw(st.sampled_from(["cut", "flip", "shape"]))
    if what == "cut":
        return data[: draw(st.integers(0, len(data) - 1))]
    if what == "flip":
        b = bytearray(data)
        for _ in range(draw(st.integers(1, 8))):
            b[draw(st.integers(0, len(b) - 1))] = draw(st.integers(0, 255))
        return bytes(b)
    info = sf.info(str(path))
    channels = draw(st.sampled_from([1, 2, info.channels + 1]))
    rate = draw(st.sampled_from([8000, info.samplerate, 1]))
    frames = draw(st.sampled_from([0, 1, 100, info.frames]))
    buf = np.zeros((frames, channels), dtype=np.float32)
    out = path.with_suffix(".tmp" + path.suffix)
    sf.write(str(out), buf, rate)
    try:
        return out.read_bytes()
    finally:
        out.unlink()


def _input_files(argv: list[str], sandbox: Path) -> list[str]:
    """The files of the sandbox's ``in/`` a command line names (also inside a named folder)."""
    found = []
    for word in argv:
        p = sandbox / word
        if word.startswith("in/") and p.is_file():
            found.append(word)
        elif word.startswith("in/") and p.is_dir():
            found += [str(q.relative_to(sandbox)) for q in sorted(p.iterdir()) if q.is_file()
                      and q.suffix in (".csv", ".json", ".flac", ".wav", ".npz")]
    return found


@st.composite
def damage(draw, key: str, sandbox: Path) -> None:
    """Damage one input file of `key`'s valid command line in `sandbox`."""
    name = draw(st.sampled_from(_input_files(list(COMMANDS[key].argv), sandbox)))
    p = sandbox / name
    if p.suffix == ".csv":
        p.write_text(draw(damaged_csv(p.read_text())))
    elif p.suffix == ".json":
        p.write_text(draw(damaged_json(p.read_text())))
    elif p.suffix == ".npz":
        arrays = draw(damaged_npz(p))
        with open(p, "wb") as f:
            np.savez(f, **arrays)
    else:
        p.write_bytes(draw(damaged_audio(p)))


# --------------------------------------------------------------------------------------------
# the properties
# --------------------------------------------------------------------------------------------
class Overtime(BaseException):
    """An example ran longer than FUSION_PROPERTY_TIMEOUT_S (not caught by the command line)."""


@contextlib.contextmanager
def _time_limit():
    limit = float(os.environ.get("FUSION_PROPERTY_TIMEOUT_S", "0"))
    if limit <= 0:
        yield
        return

    def _raise(signum, frame):
        raise Overtime(f"ran longer than {limit:g} s")

    old = signal.signal(signal.SIGALRM, _raise)
    signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@contextlib.contextmanager
def sandbox(inputs: Path):
    """A fresh working folder holding a copy of the inputs as ``in/``."""
    with tempfile.TemporaryDirectory() as d:
        shutil.copytree(inputs, Path(d) / "in", symlinks=True)
        with contextlib.chdir(d):
            yield Path(d)


def _property(key: str, kind: str):
    @settings(max_examples=_examples(key))
    @given(data=st.data())
    def test(data, inputs, check_cli_run):
        with sandbox(inputs) as box:
            if kind == "arguments":
                argv = data.draw(command_lines(key), label="argv")
            else:
                data.draw(damage(key, box), label="damage")
                argv = list(COMMANDS[key].argv)
            with _time_limit():
                code = check_cli_run(box, argv)
            assert code in (0, 2)  # check_cli_run checked what each exit code must leave
            event(f"exit {code}")  # --hypothesis-show-statistics: how many ran to the end

    test.__name__ = f"test_{kind}_{key.replace('-', '_')}"
    return test


for _key in COMMANDS:
    for _kind in ("arguments", "inputs"):
        if _kind == "inputs" and _key in ("simulate", "simulate-clicks", "demo"):
            continue  # no input files
        _t = _property(_key, _kind)
        globals()[_t.__name__] = _t
del _key, _kind, _t


def test_every_command_has_its_properties():
    """A command added to the command line gets its properties here (or the test fails)."""
    from fusion.cli import COMMANDS as CLI_COMMANDS

    assert {c.argv[0] for c in COMMANDS.values()} == set(CLI_COMMANDS)
