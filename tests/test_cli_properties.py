"""Hypothesis: any CSV content or option set gives output, or exit 2 with one line and nothing.

For every CSV reader through a command that reads it (``tqi``, ``crossings``, ``smooth``,
``tma``, ``track``, ``passive --clicks``, ``localize --events``) and for argument sets of a few
commands: success with the output written, or exit code 2 with exactly one stderr line, no
traceback, no output and no temporaries written, the inputs unchanged (``check_cli_run``
of ``tests/conftest.py``). Every command's options and other inputs:
``tests/test_cli_properties_commands.py``. Examples: the ``ci``
profile of ``tests/conftest.py`` (deterministic, ``FUSION_HYPOTHESIS_EXAMPLES``, default 200,
shared here among the readers: a tenth each).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

_EACH = max(10, settings().max_examples // 10)

#: command, input option, its columns and a valid row maker (row index -> cells)
READERS = {
    "amplitudes": (["tqi"], "--amplitudes", "track_id,time,amplitude,residual",
                   lambda i: f"{i % 2},{i // 2},{1 + i % 3},0.{i % 7}"),
    "bearings": (["crossings"], "--bearings", "track_id,time,bearing_deg",
                 lambda i: f"{i % 2},{10 * (i // 2)},{40 + 30 * (i % 2) + (i // 2) * (1 - 2 * (i % 2))}"),
    "smooth": (["smooth"], "--bearings", "track_id,time,bearing_deg",
               lambda i: f"{i % 2},{10 * (i // 2)},{40 + 30 * (i % 2) + i // 2}"),
    "detections": (["track", "--fit-pings", "4"], "--detections", "event,time,x,y",
                   lambda i: f"{i // 2},{30 * (i // 2)},{100 * (i % 2) + 5 * i},{50 * (i // 2)}"),
    "tma": (["tma", "--ownship", "OWN"], "--bearings", "time,bearing_deg",
            lambda i: f"{10 * i},{30 + 0.5 * i}"),
}

cells = st.one_of(st.sampled_from(["", "nan", "inf", "1e308", "-1e12", "9e11", "1e12", "abc",
                                   "0.5", "-1", "1,2", "\"", "\x00", "100000000"]),
                  st.integers(-3, 50).map(str), st.floats(-1e6, 1e6).map(repr))


@st.composite
def mutated(draw, header: str, row) -> str:
    n = draw(st.integers(1, 24))
    lines = [header] + [row(i) for i in range(n)]
    for _ in range(draw(st.integers(0, 3))):
        k = draw(st.integers(0, len(lines) - 1))
        parts = lines[k].split(",")
        what = draw(st.sampled_from(["cell", "cell", "extra", "drop", "dup", "swap"]))
        if what == "cell":
            parts[draw(st.integers(0, len(parts) - 1))] = draw(cells)
        elif what == "extra":
            parts.append(draw(cells))
        elif what == "drop" and len(parts) > 1:
            parts.pop()
        elif what == "dup":
            parts = lines[0].split(",") + [draw(st.sampled_from(lines[0].split(",")))]
        elif what == "swap" and len(lines) > 2:
            j = draw(st.integers(1, len(lines) - 1))
            lines[k], lines[j] = lines[j], lines[k]
            continue
        lines[k] = ",".join(parts)
    return "\n".join(lines) + "\n"


def _ownship(folder: Path) -> Path:
    p = folder / "own.csv"
    rows = [f"{10 * i},{5.0 * i if i < 15 else 75 + 5 * (i - 15)},{0 if i < 15 else 5 * (i - 15)}"
            for i in range(40)]
    p.write_text("time,x,y\n" + "\n".join(rows) + "\n")
    return p


def _reader_case(kind: str):
    command, option, header, row = READERS[kind]

    @settings(max_examples=_EACH)
    @given(text=mutated(header, row))
    def test(text, check_cli_run):
        with tempfile.TemporaryDirectory() as d:
            folder = Path(d)
            src = folder / f"{kind}.csv"
            src.write_text(text)
            args = [str(_ownship(folder)) if a == "OWN" else a for a in command]
            out = folder / "o.csv"
            assert check_cli_run(folder, [*args, option, str(src), "--out", str(out)]) in (0, 2)

    test.__name__ = f"test_reader_{kind}"
    return test


test_reader_amplitudes = _reader_case("amplitudes")
test_reader_bearings = _reader_case("bearings")
test_reader_smooth = _reader_case("smooth")
test_reader_detections = _reader_case("detections")
test_reader_tma = _reader_case("tma")

option_values = st.one_of(st.sampled_from(["0", "-1", "1e308", "1e-300", "nan", "abc", "", "2",
                                           "0.5", "1e9", "-0"]), st.floats(-100, 100).map(repr))


@settings(max_examples=_EACH)
@given(opts=st.dictionaries(st.sampled_from(["--snr0-db", "--snr1-db", "--n-looks", "--tl", "--tu",
                                             "--ts", "--lh", "--sh", "--omega-per-deg", "--t-err",
                                             "--residual-smoothing", "--sllr0-max"]),
                            option_values, max_size=4))
def test_tqi_options(opts, check_cli_run):
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        src = folder / "a.csv"
        src.write_text("track_id,time,amplitude,residual\n" + "".join(
            f"{i % 2},{i // 2},{1 + i % 5},0.{i % 7}\n" for i in range(40)))
        out = folder / "o.csv"
        argv = ["tqi", "--amplitudes", str(src), "--out", str(out)]
        for k, v in opts.items():
            argv += [f"{k}={v}"]
        assert check_cli_run(folder, argv) in (0, 2)


@settings(max_examples=_EACH)
@given(opts=st.dictionaries(st.sampled_from(["--window-s", "--horizon-s", "--windows", "--lead",
                                             "--confirm", "--level", "--period-s", "--window-samples",
                                             "--merge-window-s", "--max-gap-s"]),
                            option_values, max_size=3))
def test_crossings_options(opts, check_cli_run):
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        src = folder / "b.csv"
        row = READERS["bearings"][3]
        src.write_text("track_id,time,bearing_deg\n" + "".join(f"{row(i)}\n" for i in range(60)))
        out = folder / "o.csv"
        argv = ["crossings", "--bearings", str(src), "--out", str(out)]
        for k, v in opts.items():
            argv += [f"{k}={v}"]
        assert check_cli_run(folder, argv) in (0, 2)


def test_examples_setting_is_read_from_the_environment():
    assert settings().derandomize == (os.environ.get("HYPOTHESIS_PROFILE", "ci") == "ci")
