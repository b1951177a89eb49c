"""Number options of the commands: :func:`number` (finite, bounded) and the shared bounds.

Standard library only (the command line parses options before importing numerical libraries);
:mod:`fusion.cli` re-exports every name.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

__all__ = ["DB_RANGE", "MAX_OPTION_ABS", "MAX_SCANS_OPTION", "number"]

#: Largest magnitude of any number option without a tighter bound (as of CSV values): beyond
#: it a value is a unit error, and 1e300 overflows whatever it is multiplied with.
MAX_OPTION_ABS = 1e12
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
    ``--snr0-db 1e300`` is refused, not overflowed.
    """
    ge = -MAX_OPTION_ABS if ge is None and gt is None else ge
    le = MAX_OPTION_ABS if le is None else le

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
