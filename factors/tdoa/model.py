"""The TDOA measurement model of a click source and sensor pairs, with its input checks.

For a source at ``p`` (m), sensors at ``s_i`` (m), sound speed ``c`` (m/s) and optional sensor
clock offsets ``b_i`` (s; a measured arrival is the true arrival plus ``b_i``), the delay of the
pair ``(i, j)``, arrival at ``i`` minus arrival at ``j``, is::

    tau_ij(p) = (|p - s_i| - |p - s_j|) / c + b_i - b_j

:func:`predicted_tdoas` evaluates it for many positions at once (simulation, grid searches);
:class:`TdoaModel` holds one source's measured TDOAs and gives the residual and its Jacobians
that the factors of :mod:`factors.tdoa` wrap.

Notes
-----
Eq. (14) of the localization text (*Localization of short periodic signals*): the model
propagation-time difference ``d_m = T_i(m) - T_j(m)`` with straight-line propagation at speed
``c``; a measurement satisfies eq. (15), ``d_m = tau_m``, on its hyperboloid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["MIN_RANGE", "TdoaModel", "predicted_tdoas"]

#: Smallest sensor-to-source range (m) used for a unit vector: a source exactly on a sensor gets
#: a zero unit vector (a subgradient of the range) instead of a division by zero.
MIN_RANGE = 1e-12


def _sensors(sensors: ArrayLike) -> NDArray[np.float64]:
    s = np.array(sensors, dtype=float)
    if s.ndim != 2 or s.shape[1] != 3 or s.shape[0] < 2:
        raise ValueError(f"sensors must have shape (n, 3) with n >= 2, got {s.shape}")
    if not np.all(np.isfinite(s)):
        raise ValueError("sensor positions must be finite")
    return s


def _pairs(pairs: ArrayLike, n: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    q = np.asarray(pairs)
    if q.ndim != 2 or q.shape[1] != 2 or q.shape[0] < 1:
        raise ValueError(f"pairs must have shape (m, 2) with m >= 1, got {q.shape}")
    if not np.issubdtype(q.dtype, np.integer):
        raise ValueError(f"pairs must hold integer sensor indices, got dtype {q.dtype}")
    if np.any(q < 0) or np.any(q >= n):
        raise ValueError(f"pair indices must lie in [0, {n}) for {n} sensors")
    if np.any(q[:, 0] == q[:, 1]):
        raise ValueError("a pair must join two different sensors")
    return q[:, 0].astype(np.intp), q[:, 1].astype(np.intp)


def _taus(taus: ArrayLike, m: int) -> NDArray[np.float64]:
    t = np.array(taus, dtype=float).reshape(-1)
    if t.shape != (m,):
        raise ValueError(f"taus must have shape ({m},) to match the pairs, got {np.shape(taus)}")
    if not np.all(np.isfinite(t)):
        raise ValueError("taus must be finite")
    return t


def check_speed(c: float) -> float:
    """`c` as a float, or ValueError unless it is a positive finite sound speed (m/s)."""
    if isinstance(c, bool) or not isinstance(c, int | float | np.floating | np.integer):
        raise ValueError(f"sound speed c must be a number, got {c!r}")
    if not (np.isfinite(c) and c > 0):
        raise ValueError(f"sound speed c must be positive and finite, got {c!r}")
    return float(c)


def predicted_tdoas(
    positions: ArrayLike,
    sensors: ArrayLike,
    pairs: ArrayLike,
    *,
    c: float,
    clock_offsets: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Model TDOAs of sources at `positions` (vectorised over positions).

    Parameters
    ----------
    positions : array_like, shape (..., 3)
        Source positions, m.
    sensors : array_like, shape (n, 3)
        Sensor positions, m.
    pairs : array_like of int, shape (m, 2)
        Sensor pairs ``(i, j)``.
    c : float, keyword-only
        Sound speed, m/s.
    clock_offsets : array_like, shape (n,), optional, keyword-only
        Clock offset of each sensor, s (measured arrival = true arrival + offset).

    Returns
    -------
    ndarray, shape (..., m)
        Arrival time at ``i`` minus arrival time at ``j``, s.

    Examples
    --------
    >>> s = np.array([[0.0, 0, 0], [1500.0, 0, 0]])
    >>> predicted_tdoas([0.0, 0, 0], s, [[0, 1], [1, 0]], c=1500.0)
    array([-1.,  1.])
    """
    s = _sensors(sensors)
    first, second = _pairs(pairs, s.shape[0])
    c = check_speed(c)
    p = np.asarray(positions, dtype=float)
    if p.shape[-1:] != (3,):
        raise ValueError(f"positions must have shape (..., 3), got {p.shape}")
    d = np.linalg.norm(p[..., None, :] - s, axis=-1)  # d_i = |p - s_i|, (..., n)
    tau = (d[..., first] - d[..., second]) / c  # eq. (14): T_i - T_j
    if clock_offsets is not None:
        b = np.asarray(clock_offsets, dtype=float)
        if b.shape != (s.shape[0],):
            raise ValueError(f"clock_offsets must have shape ({s.shape[0]},), got {b.shape}")
        tau = tau + (b[first] - b[second])  # + b_i - b_j
    return tau


@dataclass(frozen=True)
class TdoaModel:
    """The measured TDOAs of one source, checked, with their residual model.

    Build with :meth:`build`; the arrays are private copies.

    Attributes
    ----------
    sensors : ndarray, shape (n, 3)
        Sensor positions, m.
    first, second : ndarray of int, shape (m,)
        Sensors ``i`` and ``j`` of each pair.
    taus : ndarray, shape (m,)
        Measured delays, arrival at ``i`` minus arrival at ``j``, s.
    incidence : ndarray, shape (m, n)
        +1 at ``(k, i)``, -1 at ``(k, j)``: the derivative of the residuals by the clock
        offsets; its rank is the number of independent TDOAs.
    """

    sensors: NDArray[np.float64]
    first: NDArray[np.intp]
    second: NDArray[np.intp]
    taus: NDArray[np.float64]
    incidence: NDArray[np.float64]

    @classmethod
    def build(cls, sensors: ArrayLike, pairs: ArrayLike, taus: ArrayLike) -> TdoaModel:
        """Check and copy sensors (n, 3) m, pairs (m, 2) int and taus (m,) s."""
        s = _sensors(sensors)
        first, second = _pairs(pairs, s.shape[0])
        t = _taus(taus, first.shape[0])
        inc = np.zeros((first.shape[0], s.shape[0]))
        rows = np.arange(first.shape[0])
        inc[rows, first] = 1.0
        inc[rows, second] = -1.0
        return cls(s, first, second, t, inc)

    @property
    def m(self) -> int:
        """Number of TDOAs."""
        return int(self.first.shape[0])

    @property
    def n(self) -> int:
        """Number of sensors."""
        return int(self.sensors.shape[0])

    @property
    def pairs(self) -> NDArray[np.intp]:
        """The pairs, shape (m, 2)."""
        return np.column_stack([self.first, self.second])

    def residual(
        self,
        p: NDArray[np.float64],
        c: float,
        b: NDArray[np.float64] | None = None,
        *,
        jacobian: bool = False,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64] | None]:
        """Residuals (predicted minus measured) at one source position.

        Parameters
        ----------
        p : ndarray, shape (3,)
            Source position, m.
        c : float
            Sound speed, m/s.
        b : ndarray, shape (n,), optional
            Clock offsets, s.
        jacobian : bool, keyword-only
            Also return the derivatives.

        Returns
        -------
        r : ndarray, shape (m,)
            ``(d_i - d_j)/c + b_i - b_j - tau``, s.
        h_p : ndarray, shape (m, 3) or None
            ``dr/dp = (u_i - u_j)/c``, s/m, with ``u_i`` the unit vector from sensor i to p.
        h_c : ndarray, shape (m, 1) or None
            ``dr/dc = -(d_i - d_j)/c^2``, s^2/m. (``dr/db`` is :attr:`incidence`.)
        """
        diff = p - self.sensors  # p - s_i, (n, 3)
        d = np.sqrt(np.einsum("ij,ij->i", diff, diff))  # d_i = |p - s_i|
        dd = d[self.first] - d[self.second]  # d_i - d_j
        r = dd / c - self.taus  # r = (d_i - d_j)/c - tau
        if b is not None:
            r = r + (b[self.first] - b[self.second])  # + b_i - b_j
        if not jacobian:
            return r, None, None
        u = diff / np.maximum(d, MIN_RANGE)[:, None]  # u_i = (p - s_i)/d_i
        h_p = (u[self.first] - u[self.second]) / c  # dr/dp = (u_i - u_j)/c
        h_c = (-dd / (c * c))[:, None]  # dr/dc = -(d_i - d_j)/c^2
        return r, h_p, h_c
