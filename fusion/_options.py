"""Number options of the commands: :func:`number` (finite, bounded) and the shared bounds.

Standard library only (the command line parses options before importing numerical libraries);
:mod:`fusion.cli` re-exports every name.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

__all__ = ["DB_RANGE", "MAX_OPTION_ABS", "MAX_SCANS_OPTION", "MIN_POSITIVE_OPTION", "OLD_SPELLINGS",
           "add_old_spellings", "number", "old_spelling_warnings"]

#: Largest magnitude of any number option without a tighter bound (as of CSV values): beyond
#: it a value is a unit error, and 1e300 overflows whatever it is multiplied with.
MAX_OPTION_ABS = 1e12
#: Smallest value of a positive number option (``gt=0``: a noise sigma, a PSD, a period, a
#: tolerance): below it a value is a unit error, and its square underflows (``--bearing-sigma-deg
#: 4e-268`` divided by zero).
MIN_POSITIVE_OPTION = 1e-12
#: Bounds of decibel options (SNRs): 10**(100/10) = 1e10 is as strong as a signal gets.
DB_RANGE = (-100.0, 100.0)
#: Largest count of scans, pings or windows an option may set (a track rule, a window, a map
#: memory): each sizes arrays or loops over the data.
MAX_SCANS_OPTION = 100_000


def number(
    kind: type = float,
    *,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
) -> Callable[[str], float]:
    """An argparse ``type`` for a finite number with bounds (``gt``: >, ``ge``: >=, ``le``: <=).

    ``number(float, gt=0)`` accepts positive floats; ``number(int, ge=1)`` positive integers. A
    bad value becomes the one-line usage error ``argument --opt: must be > 0, got '-1'``. Every
    number is at most :data:`MAX_OPTION_ABS` in magnitude (``le`` and ``ge`` tighten it):
    ``--snr0-db 1e300`` is refused, not overflowed; a positive float (``gt=0``) is at least
    :data:`MIN_POSITIVE_OPTION`: ``--bearing-sigma-deg 5e-324`` is refused, not squared to 0.
    """
    ge = -MAX_OPTION_ABS if ge is None and gt is None else ge
    le = MAX_OPTION_ABS if le is None else le
    if kind is float and gt == 0 and ge is None:
        ge = MIN_POSITIVE_OPTION

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


# --------------------------------------------------------------------------------------------
# one option vocabulary: old spellings kept for one release (docs/options.md)
# --------------------------------------------------------------------------------------------
#: Old spellings of renamed options, per command: old -> new. Each old spelling still works for
#: one release, hidden from ``--help``, with a one-line deprecation warning (held with the run's
#: notes, :mod:`fusion._notes`). The dests are unchanged: nothing downstream sees the rename.
#: docs/options.md has the table of the ideas, their one spelling and unit.
OLD_SPELLINGS: dict[str, dict[str, str]] = {
    "simulate": {"--duration": "--duration-s"},
    "acquire": {"--freq": "--freq-hz", "--ibw": "--ibw-hz", "--lag": "--display-lag-s",
                "--freq-tolerance": "--freq-tolerance-bins"},
    "report": {"--freq": "--freq-hz", "--lag": "--display-lag-s"},
    "crossings": {
        "--horizon": "--horizon-s",
        "--period": "--period-s",
        "--window": "--window-samples",
        "--merge-window": "--merge-window-s",
        "--max-gap": "--max-gap-s",
    },
    "passive": {
        "--lag": "--graph-lag-s",
        "--accel-sigma": "--accel-sigma-deg-per-min2",
        "--beam-sigma": "--beam-sigma-beams",
        "--window": "--window-samples",
        "--period": "--period-s",
    },
    "tma": {"--q": "--accel-psd-m2-per-s3"},
    "smooth": {
        "--sigma-bearing-deg": "--bearing-sigma-deg",
        "--q-deg2-per-s3": "--accel-psd-deg2-per-s3",
        "--p-detect": "--detection-probability",
        "--init-sigma-rate-deg-per-s": "--init-rate-sigma-deg-per-s",
    },
    "track": {
        "--position-sigma": "--position-sigma-m",
        "--accel-psd": "--accel-psd-m2-per-s3",
        "--hotspot-near": "--hotspot-near-m",
        "--feature-sigma": "--feature-sigma-m",
        "--intensity-bandwidth": "--intensity-bandwidth-m",
        "--max-speed": "--max-speed-mps",
        "--min-speed": "--min-speed-mps",
        "--range-sum-sigma": "--range-sum-sigma-m",
        "--bearing-sigma": "--bearing-sigma-deg",
        "--hotspot-cell": "--hotspot-cell-m",
    },
    "localize": {
        "--window": "--window-s",
        "--hop": "--hop-s",
        "--band": "--band-hz",
        "--min-centre-freq": "--min-centre-freq-hz",
        "--chunk": "--chunk-s",
        "--event-band-floor": "--event-band-floor-hz",
        "--event-default-band": "--event-default-band-hz",
        "--sea-floor-z": "--sea-floor-z-m",
        "--event-region": "--event-region-apertures",
    },
    "train-validator": {"--window": "--window-s", "--hop": "--hop-s", "--tolerance": "--tolerance-s"},
    "tqi": {"--omega": "--omega-per-deg"},
}

#: The namespace attribute listing the old spellings a command line used: (old, new) pairs.
USED_OLD_SPELLINGS = "old_spellings_used"


class _OldSpelling(argparse.Action):
    """A hidden old spelling of an option: stores into the new option's dest, notes its use."""

    def __init__(self, option_strings, dest, *, new: argparse.Action, **kwargs) -> None:
        super().__init__(option_strings, dest, nargs=new.nargs, type=new.type,
                         choices=new.choices, metavar=new.metavar, default=argparse.SUPPRESS,
                         help=argparse.SUPPRESS, **kwargs)
        self.new = new

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)
        used = list(getattr(namespace, USED_OLD_SPELLINGS, ()))
        used.append((option_string, max(self.new.option_strings, key=len)))
        setattr(namespace, USED_OLD_SPELLINGS, used)


def add_old_spellings(parser: argparse.ArgumentParser, command: str) -> None:
    """Register the hidden old spellings of `command`'s renamed options (:data:`OLD_SPELLINGS`).

    A required option becomes optional to argparse (its old spelling may give it) and is marked
    ``required_any``: :class:`fusion.cli.Parser` then requires one of its spellings, and shows it
    required in the usage.
    """
    for old, new in OLD_SPELLINGS.get(command, {}).items():
        action = parser._option_string_actions[new]
        parser.add_argument(old, dest=action.dest, action=_OldSpelling, new=action)
        if action.required:
            action.required = False
            action.required_any = True  # type: ignore[attr-defined]


def old_spelling_warnings(namespace: argparse.Namespace) -> list[str]:
    """One deprecation line per old spelling used on the command line (see :data:`OLD_SPELLINGS`)."""
    return [f"{old} is deprecated, use {new} (the old spelling goes in the next release)"
            for old, new in dict.fromkeys(getattr(namespace, USED_OLD_SPELLINGS, ()))]
