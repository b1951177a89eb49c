"""Clutter maps (Section 2.4 of "Target tracking using fuzzy logic association").

- :mod:`~fusion.active.clutter.base`: :class:`Hotspots` and the base class every map follows;
- :mod:`~fusion.active.clutter.grid`: :class:`ClutterMap`, recurrence counted in fixed cells;
- :mod:`~fusion.active.clutter.density`: :class:`DensityClutterMap`, recurrence judged with each
  detection's own error ellipse, across pings and receivers (the tracker's default);
- :mod:`~fusion.active.clutter.intensity`: :class:`ClutterIntensity`, false returns per ping and
  square metre over the field (the track score's clutter density).
"""

from fusion.active.clutter.base import ClutterMapBase, Hotspots, floor_covariance
from fusion.active.clutter.density import DensityClutterMap
from fusion.active.clutter.grid import ClutterMap
from fusion.active.clutter.intensity import ClutterIntensity

__all__ = [
    "ClutterIntensity",
    "ClutterMap",
    "ClutterMapBase",
    "DensityClutterMap",
    "Hotspots",
    "floor_covariance",
]
