"""Tests of the fusion command line: help, errors as one line with exit code 2."""

import subprocess
import sys

from fusion.cli import COMMAND_MODULES, EXIT_BAD_INPUT, build_parser


def test_every_registered_command_has_help(run_cli):
    """`fusion --help` lists every registered subcommand and each has its own help."""
    code, out, _ = run_cli("--help")
    assert code == 0
    names = [m.rsplit(".", 1)[1] for m in COMMAND_MODULES]
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert set(sub.choices) >= {"simulate", "demo"}
    for name in sub.choices:
        assert name in out
        code, sub_out, _ = run_cli(name, "--help")
        assert code == 0 and "usage: fusion" in sub_out
    assert len(sub.choices) >= len(names) - 1  # crossings registers 'crossings', etc.


def test_bad_option_value_is_one_line_exit_2(run_cli):
    """A ValueError inside a command becomes one stderr line and exit code 2."""
    code, out, err = run_cli("demo", "--part", "no-such-part", "--out", "/tmp/unused-demo-dir")
    assert code == EXIT_BAD_INPUT
    assert err.count("\n") == 1 and "unknown demo part" in err and "Traceback" not in err


def test_unknown_simulation_kind_exit_2(run_cli, tmp_path):
    """An unknown scenario kind is rejected by the parser with exit code 2."""
    code, _, err = run_cli("simulate", "no-such-kind", "--out", tmp_path)
    assert code == 2 and "invalid choice" in err


def test_module_entry_point():
    """`python -m fusion --version` runs the same command line."""
    r = subprocess.run([sys.executable, "-m", "fusion", "--version"], capture_output=True, text=True,
                       check=False)
    assert r.returncode == 0 and r.stdout.startswith("fusion ")
