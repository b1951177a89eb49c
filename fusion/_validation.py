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
