"""Checks of numeric options shared by the library's components."""

from __future__ import annotations

import math


def check_positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    """Return `value` as a float if it is finite and > 0 (>= 0 with `allow_zero`).

    Raises
    ------
    ValueError
        Naming the option: ``"<name> must be finite and > 0, got <value>"``.
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    ok = v >= 0 if allow_zero else v > 0
    if not (math.isfinite(v) and ok):
        raise ValueError(f"{name} must be finite and {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return v


#: Most points of a grid laid over the input data (time steps of a track, rate blocks, pings
#: numbered by event id): 10**7, about 80 MB per float64 array. A grid sized by the data beyond
#: it (a row at time -1e12 among 10-s steps, event id 100000000 after event 199) is a unit or
#: export error in the input, not data; it would take terabytes or days.
MAX_GRID_POINTS = 10_000_000
#: Most consecutive pings without detections (event ids missing from a detections file): each is
#: a tracker step (about 0.5 ms), so 100,000 take about a minute.
MAX_EMPTY_PINGS = 100_000


class GridTooLarge(ValueError):
    """A grid sized by the input data exceeds :data:`MAX_GRID_POINTS` (the command line names
    the input file in front of the message)."""


def check_grid(n_points: float, what: str, *, limit: int = MAX_GRID_POINTS) -> int:
    """`n_points` as an int if a grid over the data may have that many points.

    Raises
    ------
    GridTooLarge
        More than `limit` (:data:`MAX_GRID_POINTS`): ``"<what>: N points, more than
        10,000,000: an implausible value in the input (check its times, ids and units)"``.
    """
    if n_points > limit:
        raise GridTooLarge(f"{what}: {n_points:.3g} points, more than {limit:,}: an "
                           "implausible value in the input (check its times, ids and units)")
    return int(n_points)
