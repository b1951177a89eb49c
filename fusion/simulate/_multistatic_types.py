"""The record of a simulated multistatic run, and the knot.

Shared by the fixed scenario (:mod:`fusion.simulate.multistatic`) and the varied one
(:mod:`fusion.simulate.multistatic_varied`); importable from :mod:`fusion.simulate.multistatic`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from fusion.io import Table

__all__ = ["KNOT", "MultistaticScenario"]

#: One knot, m/s.
KNOT = 1852.0 / 3600.0


@dataclass(frozen=True)
class MultistaticScenario:
    """A simulated multistatic run.

    Attributes
    ----------
    detections : Table
        ``event,time,x,y,snr_db,score,aspect_deg,src_x,src_y,rcv_x,rcv_y`` plus ``origin``
        (``target``, ``hotspot`` or ``clutter``, str) and ``receiver`` (int index).
    truth : Table
        Target state per ping: ``event,time,x,y,vx,vy``.
    source : ndarray, shape (2,)
        Source position, m.
    receivers : ndarray, shape (n_receivers, 2)
        Receiver positions, m.
    hotspots : ndarray, shape (n_hotspots, 2)
        True hotspot positions, m.
    ping_interval_s : float
        s.
    seed : int
    parameters : dict
        Scenario parameters drawn from the seed (varied scenarios,
        :mod:`fusion.simulate.multistatic_varied`; empty for the fixed scenario). Truth, for
        diagnosis only.
    """

    detections: Table
    truth: Table
    source: NDArray[np.float64]
    receivers: NDArray[np.float64]
    hotspots: NDArray[np.float64]
    ping_interval_s: float
    seed: int
    parameters: dict = field(default_factory=dict)
