"""Deprecated import path: use :mod:`fusion.localization.competition`; this module goes in the next release.

Why: localization (TDOAs to sources and tracks) is its own package, :mod:`fusion.localization`.
"""

from fusion._deprecated import moved_names

# served by __getattr__
__all__ = [  # noqa: F822
    "CompetitionResult", "CompetitionSettings", "association_weights", "compete", "holds_a_source",
    "independent_pairs", "supported_weights", "vertical_starts"
]

__getattr__ = moved_names(
    __name__, "fusion.localization.competition", __all__, shown="fusion.localization.competition"
)
