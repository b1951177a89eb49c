"""The validated TDOAs of one processing window with their array, checked once.

:class:`WindowTdoas` is the data every stage of the multi-source localization reads: the
intensity surfaces (:mod:`fusion.localization.intensity`), the candidates, the competition and the
localizer.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (13)-(14): the delays, their sensor
pairs and the cross-pair association ``alpha``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.tdoa.model import TdoaModel, check_speed
from fusion.types import frozen_array

__all__ = ["WindowTdoas"]



@dataclass(frozen=True)
class WindowTdoas:
    """The validated TDOAs of one processing window, with their array (checked, read-only).

    Attributes
    ----------
    sensors : ndarray, shape (n, 3)
        Sensor positions, m.
    pairs : ndarray of int, shape (M, 2)
        Sensor pair ``(i, j)`` of each TDOA.
    taus : ndarray, shape (M,)
        Delays, arrival at ``i`` minus arrival at ``j``, s.
    sigmas : ndarray, shape (M,)
        Standard deviation of each delay, s (> 0).
    c : float
        Sound speed, m/s.
    alpha : ndarray, shape (M, M), optional
        Cross-pair association of eq. (13): symmetric, non-negative, finite; None when the
        window has no association measure.
    """

    sensors: NDArray[np.float64]
    pairs: NDArray[np.intp]
    taus: NDArray[np.float64]
    sigmas: NDArray[np.float64]
    c: float
    alpha: NDArray[np.float64] | None = None
    _model: TdoaModel = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        model = TdoaModel.build(self.sensors, self.pairs, self.taus)  # checks shapes and values
        m = model.m
        sig = np.broadcast_to(np.asarray(self.sigmas, dtype=float), (m,))
        if not np.all(np.isfinite(sig) & (sig > 0)):
            raise ValueError("sigmas must be positive and finite (one per TDOA, s)")
        object.__setattr__(self, "c", check_speed(self.c))
        object.__setattr__(self, "sensors", frozen_array(model.sensors))
        object.__setattr__(self, "pairs", frozen_array(model.pairs, np.intp))
        object.__setattr__(self, "taus", frozen_array(model.taus))
        object.__setattr__(self, "sigmas", frozen_array(sig))
        object.__setattr__(self, "_model", model)
        if self.alpha is not None:
            a = np.array(self.alpha, dtype=float)
            if a.shape != (m, m):
                raise ValueError(f"alpha must have shape ({m}, {m}) to match the TDOAs, got {a.shape}")
            if not np.all(np.isfinite(a)) or np.any(a < 0):
                raise ValueError("alpha must be finite and non-negative")
            if not np.allclose(a, a.T, rtol=1e-9, atol=1e-12):
                raise ValueError("alpha must be symmetric (alpha[l, m] == alpha[m, l])")
            object.__setattr__(self, "alpha", frozen_array(0.5 * (a + a.T)))

    @property
    def m(self) -> int:
        """Number of TDOAs."""
        return int(self.taus.shape[0])

    @property
    def model(self) -> TdoaModel:
        """The measurement model of all TDOAs (:class:`factors.tdoa.model.TdoaModel`)."""
        return self._model

    @property
    def max_delay_s(self) -> NDArray[np.float64]:
        """Largest physically possible ``|tau|`` of each TDOA, ``|s_i - s_j|/c``, s, shape (M,)."""
        s = self.sensors
        return np.linalg.norm(s[self.pairs[:, 0]] - s[self.pairs[:, 1]], axis=1) / self.c

    def subset(self, index: ArrayLike) -> WindowTdoas:
        """The TDOAs at `index` (int array or boolean mask), with their part of ``alpha``."""
        idx = np.arange(self.m)[np.asarray(index)]
        alpha = None if self.alpha is None else self.alpha[np.ix_(idx, idx)]
        return WindowTdoas(self.sensors, self.pairs[idx], self.taus[idx], self.sigmas[idx],
                           c=self.c, alpha=alpha)

    def predicted(self, positions: ArrayLike) -> NDArray[np.float64]:
        """Model delays ``d_m`` (eq. 14) at positions (..., 3) m: shape (..., M), s."""
        p = np.asarray(positions, dtype=float)
        d = np.sqrt(((p[..., None, :] - self.sensors) ** 2).sum(-1))  # |p - s_i|, (..., n)
        return (d[..., self.pairs[:, 0]] - d[..., self.pairs[:, 1]]) / self.c  # eq. (14)
