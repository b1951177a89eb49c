"""Deprecated import path: the names moved to the passive stages; this module goes in the next release.

Why: measuring a track and proposing starts are algorithms, so they live in their stage
(:mod:`fusion.passive.measurement`, :mod:`fusion.passive.acquisition`).
"""

from fusion._deprecated import moved_names

__all__ = ["BearingMeasurement", "LineStarter", "PeakMeasurer", "StartCandidate"]  # noqa: F822 (served by __getattr__)

_MEASUREMENT = ["BearingMeasurement", "PeakMeasurer"]
_measurement = moved_names(__name__, "fusion.passive.measurement", _MEASUREMENT,
                           shown="fusion.passive.measurement")
_starts = moved_names(__name__, "fusion.passive.acquisition.starts",
                      ["LineStarter", "StartCandidate"], shown="fusion.passive.acquisition")


def __getattr__(name: str):
    return (_measurement if name in _MEASUREMENT else _starts)(name)
