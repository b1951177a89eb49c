"""Deprecated import path: use :mod:`fusion.localization.surface_paths`; this module goes in the next release.

Why: localization (TDOAs to sources and tracks) is its own package, :mod:`fusion.localization`.
"""

from fusion._deprecated import moved_names

# served by __getattr__
__all__ = [  # noqa: F822
    "PATHS", "PathTdoas", "surface_paths"
]

__getattr__ = moved_names(
    __name__, "fusion.localization.surface_paths", __all__, shown="fusion.localization.surface_paths"
)
