"""Shared fixtures of the test suite."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

DATA = Path(__file__).parent / "data"


@pytest.fixture
def data_dir() -> Path:
    """Folder of the recorded-data copies the tests use."""
    return DATA


@pytest.fixture
def run_cli(capsys):
    """Run ``fusion`` in-process: returns (exit code, stdout, stderr)."""
    from fusion.cli import main

    def _run(*argv: str) -> tuple[int, str, str]:
        try:
            code = main([str(a) for a in argv])
        except SystemExit as e:  # argparse errors
            code = int(e.code or 0)
        out = capsys.readouterr()
        return code, out.out, out.err

    return _run


# Hypothesis: deterministic in CI (derandomize), a few hundred examples per property by default
# (tests/test_cli_properties_commands.py: its own small counts unless the variable is set);
# FUSION_HYPOTHESIS_EXAMPLES=2000 for a long run, HYPOTHESIS_PROFILE=random for fresh examples.
from hypothesis import HealthCheck, settings  # noqa: E402

_EXAMPLES = int(os.environ.get("FUSION_HYPOTHESIS_EXAMPLES", "200"))
_COMMON = {"max_examples": _EXAMPLES, "deadline": None,
           "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large]}
settings.register_profile("ci", derandomize=True, database=None, **_COMMON)
settings.register_profile("random", **_COMMON)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


# --------------------------------------------------------------------------------------------
# the bad-input contract, checked on one run (the Hypothesis properties of tests/test_cli_*)
# --------------------------------------------------------------------------------------------
#: Output options whose value a run writes (besides --out; ``-`` is standard output).
_MORE_OUTPUTS = ("--replica-out",)
#: Parts of names no finished run leaves behind: temporaries, locks, resume parts.
_LEFTOVERS = ("fusion-tmp", "fusion-lock", ".parts")


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every file (its bytes) and folder (None) under `folder`, by relative path."""
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None)
            for p in sorted(folder.rglob("*")) if p.is_file() or p.is_dir()}


def _option_value(argv: list[str], option: str) -> str | None:
    """The last value given to `option` in `argv` (``--opt V`` or ``--opt=V``)."""
    found = None
    for k, word in enumerate(argv):
        if word == option and k + 1 < len(argv):
            found = argv[k + 1]
        elif word.startswith(option + "="):
            found = word.split("=", 1)[1]
    return found


def check_run(folder: Path, argv: list[str], out: Path | None = None) -> int:
    """Run ``fusion ARGV`` in-process on files under `folder` and check the bad-input contract.

    Exit 0 with the output written (``--out``, or stdout for ``--out -`` and commands that print
    their result) and every file that existed before, but those under an output, unchanged; or
    exit 2, exactly one stderr line ``...: error: ...``, no traceback, and nothing under `folder`
    written, changed or removed. No temporaries, locks or resume parts left either way. `out`:
    the output, when not given by ``--out`` in `argv`. Returns the exit code.
    """
    import contextlib
    import io

    from fusion.cli import EXIT_BAD_INPUT, main

    argv = [str(a) for a in argv]
    before = snapshot(folder)
    err, std = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
        try:
            code = main(argv)
        except SystemExit as e:
            code = int(e.code or 0)
    text = err.getvalue()
    assert "Traceback" not in text, text
    after = snapshot(folder)
    left = [n for n in after if n not in before and any(s in n for s in _LEFTOVERS)]
    assert not left, f"left behind: {left}"
    if code == 0:
        written = [_option_value(argv, o) for o in ("--out", *_MORE_OUTPUTS)]
        if out is None and written[0] is None and argv and argv[0] == "demo":
            written[0] = "fusion-demo"
        targets = [os.path.abspath(w) for w in written if w not in (None, "-")]
        if out is not None:
            targets.append(os.path.abspath(out))
        to_stdout = written[0] == "-" or not targets
        if to_stdout:
            assert std.getvalue().strip(), f"exit 0 and nothing on stdout: {text}"
        for t in targets:
            assert os.path.exists(t), f"exit 0 and no {t}: {text}"

        def under_an_output(name: str) -> bool:
            p = os.path.abspath(folder / name)
            return any(p == t or p.startswith(t + os.sep) for t in targets)

        changed = [n for n, v in before.items() if not under_an_output(n) and after.get(n, 0) != v]
        assert not changed, f"a successful run changed or removed {changed}"
    else:
        assert code == EXIT_BAD_INPUT, (code, text)
        lines = [ln for ln in text.splitlines() if ln.strip()]
        assert len(lines) == 1 and ": error: " in lines[0], text
        diff = sorted(set(before) ^ set(after) | {n for n in before if after.get(n, 0) != before[n]})
        assert not diff, f"a failed run wrote, changed or removed {diff}: {text}"
    return code


@pytest.fixture(scope="session")
def check_cli_run():
    """:func:`check_run`: one run of ``fusion`` checked against the bad-input contract."""
    return check_run


# --------------------------------------------------------------------------------------------
# a test oracle: the wrapped bearing-track model as plain CustomFactors
# --------------------------------------------------------------------------------------------
class _WrappedTrackModel:
    """The bearing-track model of ``factors.bearing`` and ``factors.motion`` written directly,
    wrap at every evaluation, one Python callback per factor: the reference the built-in
    (re-centred, linear) forms are checked against. Not library code: nothing estimates with it.
    """

    @staticmethod
    def bearing(noise, key, z):
        """``e = wrap(x[0] - z)`` on a ``Vector`` state (rad)."""
        import gtsam
        import numpy as np

        def error(this, values, jacobians):
            x = values.atVector(this.keys()[0])
            if jacobians is not None:
                jacobians[0] = np.eye(1, x.shape[0])
            return np.array([np.mod(x[0] - z + np.pi, 2 * np.pi) - np.pi])

        return gtsam.CustomFactor(noise, [int(key)], error)

    @staticmethod
    def motion(noise, key_prev, key_next, dt):
        """``e = x_next - F(dt) x_prev`` (``d = dim / 2``), the bearing wrapped when ``d = 1``."""
        import gtsam
        import numpy as np

        d = int(noise.dim()) // 2
        F = np.block([[np.eye(d), dt * np.eye(d)], [np.zeros((d, d)), np.eye(d)]])

        def error(this, values, jacobians):
            x0, x1 = (values.atVector(k) for k in this.keys())
            e = x1 - F @ x0
            if d == 1:
                e[0] = np.mod(e[0] + np.pi, 2 * np.pi) - np.pi
            if jacobians is not None:
                jacobians[0], jacobians[1] = -F, np.eye(2 * d)
            return e

        return gtsam.CustomFactor(noise, [int(key_prev), int(key_next)], error)


@pytest.fixture
def wrapped_track():
    """The wrapped bearing-track model as CustomFactors (``.bearing``, ``.motion``)."""
    return _WrappedTrackModel
