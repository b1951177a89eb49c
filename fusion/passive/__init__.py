"""Passive narrowband processing: acquisition, bearing tracking, track quality, crossings."""

# The package imports none of its modules (each loads only its own dependencies when
# imported); `from fusion.passive import *` imports them all.
__all__ = [
    "acquisition",
    "bearing_grid",
    "crossing",
    "line_fit",
    "quality",
    "smoothing",
    "tma",
    "tracker",
]
