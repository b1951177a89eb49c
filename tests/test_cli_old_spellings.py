"""Renamed options (docs/options.md): every old spelling still works for one release, hidden, warned."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from fusion._options import OLD_SPELLINGS, old_spelling_warnings
from fusion.cli import build_parser

#: The required arguments of each command (any values: only parsed).
REQUIRED = {
    "simulate": ["clicks", "--out", "o"],
    "acquire": ["--cube", "c.npz", "--beam", "1", "--freq-hz", "100"],
    "report": ["r.csv", "--out", "o"],
    "crossings": ["--bearings", "b.csv", "--out", "o.csv"],
    "passive": ["--cube", "c.npz", "--auto", "--out", "o"],
    "tma": ["--bearings", "b.csv", "--ownship", "s.csv", "--out", "o.csv"],
    "smooth": ["--bearings", "b.csv", "--out", "o.csv"],
    "track": ["--detections", "d.csv", "--out", "o.csv"],
    "localize": ["--audio", "a.wav", "--array", "a.json", "--out", "o.json"],
    "train-validator": ["--out", "v.npz"],
    "tqi": ["--amplitudes", "a.csv", "--out", "o.csv"],
}
RENAMED = [(cmd, old, new) for cmd, names in OLD_SPELLINGS.items() for old, new in names.items()]


def _subparser(cmd: str) -> argparse.ArgumentParser:
    parser = build_parser(cmd)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[cmd]


def _value(action: argparse.Action) -> list[str]:
    one = "7" if getattr(action.type, "__name__", "") == "int" else "0.625"
    return [one, "0.875"] if action.nargs == 2 else [one]


@pytest.mark.parametrize(("cmd", "old", "new"), RENAMED, ids=[f"{c}{o}" for c, o, _ in RENAMED])
def test_old_spelling_still_works_hidden_and_warns(cmd, old, new):
    sub = _subparser(cmd)
    action = sub._option_string_actions[new]
    required = list(REQUIRED[cmd])
    if new in required:  # the required option itself renamed: given by its old spelling only
        i = required.index(new)
        del required[i:i + 2]
    value = _value(action)
    with_new = sub.parse_args([*REQUIRED[cmd], new, *value] if new not in REQUIRED[cmd]
                              else [*required, new, *value])
    with_old = sub.parse_args([*required, old, *value])
    assert getattr(with_old, action.dest) == getattr(with_new, action.dest)
    assert getattr(with_old, action.dest) not in (None, action.default)
    assert old_spelling_warnings(with_old) == [
        f"{old} is deprecated, use {new} (the old spelling goes in the next release)"]
    assert old_spelling_warnings(with_new) == []
    help_text = sub.format_help()
    assert re.search(rf"(?<![\w-]){re.escape(new)}(?![\w-])", help_text)
    assert not re.search(rf"(?<![\w-]){re.escape(old)}(?![\w-])", help_text), old


def test_every_renamed_option_is_in_the_options_table():
    table = (Path(__file__).parents[1] / "docs" / "options.md").read_text()
    for _cmd, old, new in RENAMED:
        assert f"`{new}`" in table and f"`{old}`" in table, (old, new)


def test_old_spelling_warns_once_and_gives_the_same_output(run_cli, tmp_path):
    src = tmp_path / "a.csv"
    src.write_text("track_id,time,amplitude,residual\n1,0,5,0.1\n1,1,6,0.2\n1,2,5,0.1\n")
    code, _, err = run_cli("tqi", "--amplitudes", src, "--out", tmp_path / "new.csv",
                           "--omega-per-deg", "0.3")
    assert code == 0 and "deprecated" not in err, err
    code, _, err = run_cli("tqi", "--amplitudes", src, "--out", tmp_path / "old.csv",
                           "--omega", "0.3", "--omega", "0.3")
    assert code == 0, err
    assert err.splitlines() == ["fusion tqi: warning: --omega is deprecated, use --omega-per-deg "
                                "(the old spelling goes in the next release) (DeprecationWarning)"]
    assert (tmp_path / "old.csv").read_bytes() == (tmp_path / "new.csv").read_bytes()


def test_required_option_given_by_no_spelling_is_a_usage_error(run_cli):
    code, _, err = run_cli("acquire", "--cube", "c.npz", "--beam", "1")
    assert code == 2 and "required: --freq-hz" in err
    assert "[--freq-hz" not in _subparser("acquire").format_usage()
