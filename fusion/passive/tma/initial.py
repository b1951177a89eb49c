"""Closed-form starting states of bearings-only TMA (no optimisation, no truth).

The pseudo-linear estimate and states along the first bearing at given ranges; the estimator
(:meth:`~fusion.passive.tma.estimator.BearingsOnlyTMA.initial_state`) scores them by the cost of
its bearing factor and seeds its graph with the best.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__: list[str] = []


def _transitions(dt: NDArray[np.float64]) -> NDArray[np.float64]:
    """Constant-velocity transition matrices ``F(dt)`` of a ``[x, y, vx, vy]`` state, (n, 4, 4)."""
    F = np.broadcast_to(np.eye(4), (dt.size, 4, 4)).copy()
    F[:, 0, 2] = F[:, 1, 3] = dt  # x += vx dt, y += vy dt
    return F


def _pseudo_linear(
    dt: NDArray[np.float64], z: NDArray[np.float64], o: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Pseudo-linear estimate of the single state at the first bearing time.

    From ``(x + vx dt - x_o) cos z - (y + vy dt - y_o) sin z = 0`` for every bearing ``z``.
    """
    c, s = np.cos(z), np.sin(z)
    A = np.column_stack([c, -s, c * dt, -s * dt])
    b = c * o[:, 0] - s * o[:, 1]
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    return sol


def _range_candidates(
    dt: NDArray[np.float64], z: NDArray[np.float64], o: NDArray[np.float64],
    ranges: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Closed-form states along the first bearing, shape (r + r^2, 4).

    For each range ``r_0`` of `ranges` on the first bearing: the state whose velocity best
    satisfies the pseudo-linear equations with that position held,
    ``vx dt cos z - vy dt sin z = -(x - x_o) cos z + (y - y_o) sin z`` (least squares, all ranges
    at once); and for each pair ``(r_0, r_1)`` the straight track from range ``r_0`` on the first
    bearing to range ``r_1`` on the last (it fits both bearings exactly).
    """
    c, s = np.cos(z), np.sin(z)
    u0 = np.array([np.sin(z[0]), np.cos(z[0])])
    u1 = np.array([np.sin(z[-1]), np.cos(z[-1])])
    pos = o[0] + np.outer(ranges, u0)  # (r, 2)
    A = np.column_stack([c * dt, -s * dt])
    B = -np.outer(c, pos[:, 0]) + np.outer(s, pos[:, 1]) + (c * o[:, 0] - s * o[:, 1])[:, None]
    vel, *_ = np.linalg.lstsq(A, B, rcond=None)  # (2, r)
    held = np.column_stack([pos, vel.T])
    end = o[-1] + np.outer(ranges, u1)  # (r, 2)
    p0 = np.repeat(pos, ranges.size, axis=0)
    p1 = np.tile(end, (ranges.size, 1))
    span = dt[-1] if dt[-1] > 0 else 1.0
    two = np.column_stack([p0, (p1 - p0) / span])  # straight track between the two ranges
    return np.vstack([held, two])
