"""Old import paths kept for one release: a module-level ``__getattr__`` that warns and forwards."""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable
from typing import Any

__all__ = ["moved_names"]


def moved_names(old: str, home: str, names: list[str], *, shown: str) -> Callable[[str], Any]:
    """A module ``__getattr__`` for `old`, whose `names` moved to the module `home`.

    Parameters
    ----------
    old : str
        The deprecated module (its ``__name__``).
    home : str
        The module that now defines the names.
    names : list of str
        The names that moved.
    shown : str
        The import path to show users (a package face, or `home`).

    Returns
    -------
    callable
        ``__getattr__(name)``: the object from `home`, after a DeprecationWarning naming `shown`.
    """

    def __getattr__(name: str) -> Any:
        if name not in names:
            raise AttributeError(f"module {old!r} has no attribute {name!r}")
        warnings.warn(
            f"{old}.{name} moved to {shown}.{name}; the old path goes in the next release",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(importlib.import_module(home), name)

    return __getattr__
