"""Deprecated import path: use :mod:`fusion.localization.ownership`; this module goes in the next release.

Why: localization (TDOAs to sources and tracks) is its own package, :mod:`fusion.localization`.
"""

from fusion._deprecated import moved_names

# served by __getattr__
__all__ = [  # noqa: F822
    "association_weights", "cap_per_pair", "holds_a_source", "independent_pairs", "pair_ids",
    "same_source", "supported_weights"
]

__getattr__ = moved_names(
    __name__, "fusion.localization.ownership", __all__, shown="fusion.localization.ownership"
)
