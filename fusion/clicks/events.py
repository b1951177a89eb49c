"""Deprecated import path: use :mod:`fusion.localization.events`; this module goes in the next release.

Why: localization (TDOAs to sources and tracks) is its own package, :mod:`fusion.localization`.
"""

from fusion._deprecated import moved_names

# served by __getattr__
__all__ = [  # noqa: F822
    "Event", "EventFix", "EventLocalizer"
]

__getattr__ = moved_names(
    __name__, "fusion.localization.events", __all__, shown="fusion.localization.events"
)
