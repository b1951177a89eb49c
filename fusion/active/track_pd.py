"""Each track's own detection probability per receiver (issue 20): the track score with
``P_D`` unknown per target.

The sequential track score (:mod:`fusion.active.track_score`) charges every receiver that
reported on a ping and missed the track ``ln(1 - P_D)``, with ``P_D`` the receiver's hit rate
over all tracks. In a multistatic field the target's ``P_D`` differs from receiver to receiver
(the bistatic sonar equation: range, aspect), so a receiver that hardly ever sees *this* target
charges it ``ln(1 - P_D)`` on every ping. Measured on tuning seed 1004 at ``P_D`` 0.5 / 10
clutter echoes (four receivers, receiver P_D estimates 0.64-0.73): a tentative track on the
target with a hit on 7 of 8 pings stayed between -3.9 and +2.7 for 8 pings, its hits' gains
eaten by the misses of the receivers that did not see it, and was confirmed 8 pings late.

With ``P_D`` of the target at receiver ``r`` unknown and given a Beta prior of mean ``p_r`` (the
receiver's estimate) and weight ``s`` pseudo-pings, the likelihood of the track's hit/miss
sequence at that receiver is the product of the predictive probabilities
``p_hat = (s p_r + h) / (s + n)`` (``h`` hits in ``n`` pings so far): a hit adds ``ln p_hat``, a
miss ``ln(1 - p_hat)`` (the Beta-Bernoulli marginal likelihood, exact in any order). Under the
clutter hypothesis the no-detection term is 1, as before. A receiver that keeps missing the
track soon costs it little (``p_hat`` falls), one that keeps seeing it gains ``ln p_hat`` near 0:
the evidence of a target seen by two receivers in four is no longer drowned by the other two.
:class:`TrackRates` keeps the counts, in the tracker's track order.
"""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np
from numpy.typing import NDArray

__all__ = ["TrackRates"]


class TrackRates:
    """Hits and pings of each track per receiver, and the predictive ``P_D`` (module docstring).

    Parameters
    ----------
    prior_pings : float
        Weight ``s`` of the receiver's ``P_D`` in a track's own estimate, pings (> 0).

    Examples
    --------
    >>> r = TrackRates(prior_pings=2.0)
    >>> r.add(2)
    >>> r.predictive("a", 0.7, np.arange(2)).tolist()
    [0.7, 0.7]
    >>> r.count("a", np.array([0, 1]), np.array([True, False]))
    >>> [round(v, 3) for v in r.predictive("a", 0.7, np.arange(2)).tolist()]
    [0.8, 0.467]
    """

    def __init__(self, *, prior_pings: float) -> None:
        if not (np.isfinite(prior_pings) and prior_pings > 0):
            raise ValueError(f"prior_pings must be positive, got {prior_pings!r}")
        self.prior_pings = float(prior_pings)
        self.reset()

    def reset(self) -> None:
        """Forget all tracks."""
        self._n = 0
        self._counts: dict[Hashable, NDArray[np.float64]] = {}     # receiver -> (t, 2)

    def add(self, new: int) -> None:
        """Append `new` tracks (no pings yet)."""
        self._n += int(new)

    def keep(self, alive: NDArray[np.bool_]) -> None:
        """Keep the tracks flagged alive."""
        alive = np.asarray(alive, dtype=bool)
        self._n = alive.size
        for key in list(self._counts):
            self._counts[key] = self._table(key)[alive]
        self._n = int(np.count_nonzero(alive))

    def _table(self, key: Hashable) -> NDArray[np.float64]:
        c = self._counts.get(key)
        if c is None or c.shape[0] < self._n:
            grown = np.zeros((self._n, 2))
            if c is not None:
                grown[: c.shape[0]] = c
            c = self._counts[key] = grown
        return c

    def predictive(self, key: Hashable, pd: float, tracks: NDArray[np.int64]) -> NDArray[np.float64]:
        """``p_hat`` of these tracks at a receiver whose ``P_D`` is `pd`."""
        c = self._table(key)[tracks]
        return (self.prior_pings * pd + c[:, 0]) / (self.prior_pings + c[:, 1])

    def count(self, key: Hashable, tracks: NDArray[np.int64], hit: NDArray[np.bool_]) -> None:
        """One ping of these tracks at a receiver: a hit or a miss each."""
        c = self._table(key)
        np.add.at(c, (tracks, 0), np.asarray(hit, float))
        np.add.at(c, (tracks, 1), 1.0)
