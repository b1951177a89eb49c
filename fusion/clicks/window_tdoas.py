"""Deprecated import path: use :mod:`fusion.localization.window_tdoas`; this module goes in the next release.

Why: localization (TDOAs to sources and tracks) is its own package, :mod:`fusion.localization`.
"""

from fusion._deprecated import moved_names

# served by __getattr__
__all__ = [  # noqa: F822
    "WindowTdoas"
]

__getattr__ = moved_names(
    __name__, "fusion.localization.window_tdoas", __all__, shown="fusion.localization.window_tdoas"
)
