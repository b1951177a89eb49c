"""Tests of the fusion command line: the command registry, lazy loading, help, one-line errors."""

import argparse
import subprocess
import sys

import pytest

from fusion.cli import COMMANDS, EXIT_BAD_INPUT, build_parser, chosen_command, load_command

HEAVY = ("numpy", "scipy", "gtsam", "matplotlib", "sklearn", "soundfile", "filterpy")


def _subparsers(parser: argparse.ArgumentParser) -> argparse._SubParsersAction:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))


def _loaded_after(*argv: str) -> set[str]:
    """Top-level modules and fusion modules imported by ``fusion ARGV`` in a fresh interpreter."""
    code = ("import sys\nfrom fusion.cli import main\ntry:\n    main(sys.argv[1:])\nexcept SystemExit:\n"
            "    pass\nprint(' '.join(sorted(sys.modules)), file=sys.stderr)")
    r = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True,
                       check=False, timeout=120)
    return set(r.stderr.strip().splitlines()[-1].split())


def test_every_registered_command_has_help(run_cli):
    """`fusion --help` lists every registered subcommand with its registry help; each has its own."""
    code, out, _ = run_cli("--help")
    assert code == 0
    assert set(_subparsers(build_parser()).choices) == set(COMMANDS)
    for name, (_module, help_text) in COMMANDS.items():
        assert name in out and help_text.split()[0] in out
        code, sub_out, _ = run_cli(name, "--help")
        assert code == 0 and sub_out.startswith(f"usage: fusion {name}")


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_registry_matches_module(name):
    """Each command's module registers exactly the parser named in the registry, with its help."""
    sub = _subparsers(build_parser(name))
    real = sub.choices[name]
    assert real.get_default("handler") is load_command(name).run
    shown = {a.dest: a.help for a in sub._choices_actions}
    assert shown[name] == COMMANDS[name][1]
    others = [n for n in COMMANDS if n != name]
    assert all(sub.choices[n].get_default("handler") is None for n in others)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_commands_declare_their_inputs(name):
    """Every command declares which options are inputs, and each names a real option."""
    real = _subparsers(build_parser(name)).choices[name]
    inputs = real.get_default("inputs")
    assert isinstance(inputs, tuple)
    dests = {a.dest for a in real._actions}
    assert set(inputs) <= dests


@pytest.mark.parametrize(("argv", "expected"), [
    (["--help"], None), (["-v", "tqi", "--help"], "tqi"), (["--help", "tqi"], None),
    (["crossings", "--bearings", "tqi"], "crossings"), (["no-such"], None), ([], None),
    (["--version"], None), (["-vv", "smooth"], "smooth"),
])
def test_chosen_command(argv, expected):
    """The chosen command is the first word that is not a top-level option."""
    assert chosen_command(argv) == expected


def test_help_imports_no_command_and_nothing_heavy():
    """`fusion --help` imports no command module and none of numpy/scipy/gtsam/matplotlib."""
    loaded = _loaded_after("--help")
    assert "fusion.cli" in loaded
    assert not [m for m in loaded if m.startswith("fusion.commands.")]
    assert not [m for m in loaded if m.split(".")[0] in HEAVY]


def test_chosen_command_imports_only_its_module():
    """`fusion tqi --help` imports fusion.commands.tqi and no other command module."""
    loaded = _loaded_after("tqi", "--help")
    commands = {m for m in loaded if m.startswith("fusion.commands.")}
    assert commands == {"fusion.commands.tqi"}


def test_bad_option_value_is_one_line_exit_2(run_cli):
    """A ValueError inside a command becomes one stderr line and exit code 2."""
    code, out, err = run_cli("demo", "--part", "no-such-part", "--out", "/tmp/unused-demo-dir")
    assert code == EXIT_BAD_INPUT
    assert err.count("\n") == 1 and "unknown demo part" in err and "Traceback" not in err


def test_unknown_simulation_kind_exit_2(run_cli, tmp_path):
    """An unknown scenario kind is rejected by the parser with exit code 2."""
    code, _, err = run_cli("simulate", "no-such-kind", "--out", tmp_path)
    assert code == 2 and "invalid choice" in err


def test_unknown_command_lists_choices(run_cli):
    """An unknown command is one line listing the registered commands."""
    code, out, err = run_cli("no-such-command")
    assert code == EXIT_BAD_INPUT and out == "" and len(err.splitlines()) == 1
    assert all(name in err for name in COMMANDS)


def test_module_entry_point():
    """`python -m fusion --version` runs the same command line."""
    r = subprocess.run([sys.executable, "-m", "fusion", "--version"], capture_output=True, text=True,
                       check=False)
    assert r.returncode == 0 and r.stdout.startswith("fusion ")


def test_localize_help_default_drift_is_the_library_default():
    """fusion localize states the drift grid's default without importing the click stages
    (--help stays light): the two constants must agree."""
    from fusion.clicks.scm import MAX_TDOA_RATE
    from fusion.commands import localize

    assert localize.MAX_TDOA_RATE == MAX_TDOA_RATE


def test_localize_help_states_the_validation_threshold_in_use(run_cli):
    """The --llr-threshold help names the library's LLR_THRESHOLD (the value the command uses)."""
    import re

    from fusion.pipelines.clicks import LLR_THRESHOLD

    code, out, _ = run_cli("localize", "--help")
    text = " ".join(out.split())
    assert code == 0
    assert re.search(r"--llr-threshold LLR_THRESHOLD validation threshold on the log-likelihood "
                     rf"ratio \(default: {LLR_THRESHOLD:g},", text)
