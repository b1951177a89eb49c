"""Deprecated import path: use :mod:`fusion.localization.event_tdoa`; this module goes in the next release.

Why: localization (TDOAs to sources and tracks) is its own package, :mod:`fusion.localization`.
"""

from fusion._deprecated import moved_names

# served by __getattr__
__all__ = [  # noqa: F822
    "MAX_EDGE_FRACTION", "PairTdoas", "bandpass", "closure_screen", "estimate_band", "pair_tdoas"
]

__getattr__ = moved_names(
    __name__, "fusion.localization.event_tdoa", __all__, shown="fusion.localization.event_tdoa"
)
