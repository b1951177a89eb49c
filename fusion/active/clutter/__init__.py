"""Clutter maps (Section 2.4 of "Target tracking using fuzzy logic association").

:mod:`~fusion.active.clutter.grid`: :class:`ClutterMap`, recurrence counted in fixed cells.
"""

from fusion.active.clutter.grid import ClutterMap, Hotspots

__all__ = ["ClutterMap", "Hotspots"]
