"""Data passed between the click-localization stages (frozen dataclasses, SI units).

Times are seconds from the start of the audio; a TDOA ``tau`` of pair ``(i, j)`` is the arrival
time at sensor ``i`` minus the arrival time at sensor ``j`` (``../formats`` section 2 of the
project's file formats).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from fusion.types import frozen_array

__all__ = ["ChannelClicks", "frozen_array"]  # frozen_array: fusion.types's, re-exported


@dataclass(frozen=True)
class ChannelClicks:
    """Clicks detected on one channel.

    Attributes
    ----------
    channel : int
        0-based channel (sensor) index.
    times_s : ndarray, shape (n,)
        Click times (peak of the detection statistic, parabolic-interpolated), s from the start
        of the audio, increasing.
    power : ndarray, shape (n,)
        Detection statistic at each click: band power over the background (1 = noise level).
    centre_freq_hz : ndarray, shape (n,)
        Power-weighted mean frequency of each click (eq. 2), Hz.
    """

    channel: int
    times_s: NDArray[np.float64] = field(default_factory=lambda: frozen_array([]))
    power: NDArray[np.float64] = field(default_factory=lambda: frozen_array([]))
    centre_freq_hz: NDArray[np.float64] = field(default_factory=lambda: frozen_array([]))

    def __post_init__(self) -> None:
        for name in ("times_s", "power", "centre_freq_hz"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        n = self.times_s.shape
        if self.times_s.ndim != 1 or self.power.shape != n or self.centre_freq_hz.shape != n:
            raise ValueError("ChannelClicks arrays must be 1-D and of one length")
        if n[0] > 1 and np.any(np.diff(self.times_s) < 0):
            raise ValueError("ChannelClicks.times_s must be increasing")

    @property
    def n_clicks(self) -> int:
        """Number of clicks."""
        return int(self.times_s.shape[0])

    def between(self, t0: float, t1: float) -> ChannelClicks:
        """The clicks with ``t0 <= time < t1``."""
        a, b = np.searchsorted(self.times_s, [t0, t1], side="left")
        return ChannelClicks(self.channel, self.times_s[a:b], self.power[a:b],
                             self.centre_freq_hz[a:b])
