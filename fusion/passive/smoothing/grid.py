"""Smoothed tracks resampled on a regular time grid, through short gaps, with their sigmas.

Between two smoothed states ``x_k`` (time ``t_k``) and ``x_{k+1}`` a track has no measurement,
so under the constant-rate model with white-noise acceleration (PSD ``q``) its mean at ``tau``
is the Gaussian-process interpolation of the two neighbours,

.. math::

    x(\\tau) = \\Lambda x_k + \\Psi x_{k+1}, \\quad
    \\Psi = Q_\\tau F_2^T Q_{k+1}^{-1}, \\quad \\Lambda = F_1 - \\Psi F_{k+1},

``F_1 = F(tau - t_k)``, ``F_2 = F(t_{k+1} - tau)``, ``F_{k+1} = F(t_{k+1} - t_k)``,
``Q_tau = Q(tau - t_k)``, ``Q_{k+1} = Q(t_{k+1} - t_k)`` (:func:`factors.motion.
transition_matrix`, :func:`factors.motion.wna_covariance`): exact for the smoother's posterior
mean. The covariance adds the interpolation's own ``Q_tau - Psi F_2 Q_tau`` to
``Lambda P_k Lambda^T + Psi P_{k+1} Psi^T`` with the neighbours' marginal covariances taken
diagonal (the smoothers keep sigmas, not cross-covariances), so the sigmas are approximate.
"""

from __future__ import annotations

import numpy as np

from factors.motion import transition_matrix, wna_covariance
from fusion.geometry import wrap_angle
from fusion.passive.smoothing.types import SmoothedTrack

__all__ = ["on_grid"]


def on_grid(track: SmoothedTrack, *, period: float, q: float, max_gap_s: float,
            origin: float = 0.0) -> SmoothedTrack:
    """The track at the grid times ``origin + k * period`` within its span.

    Parameters
    ----------
    track : SmoothedTrack
        Smoothed states at the track's own times.
    period : float, keyword-only
        Grid period, s.
    q : float, keyword-only
        Bearing acceleration PSD of the smoother, rad^2/s^3.
    max_gap_s : float, keyword-only
        Grid times inside a gap between states longer than this are left out, s.
    origin : float, keyword-only
        A grid time, s (one grid for every track of a file).

    Returns
    -------
    SmoothedTrack
        Same id; times on the grid, bearings (wrapped), rates and sigmas interpolated.

    Examples
    --------
    >>> tr = SmoothedTrack(0, np.array([0.0, 10.0]), np.array([0.0, 1.0]), np.array([0.1, 0.1]),
    ...                    np.array([0.01, 0.01]), np.array([0.001, 0.001]))
    >>> g = on_grid(tr, period=2.5, q=1e-8, max_gap_s=20.0)
    >>> g.times.tolist(), np.round(g.bearing, 6).tolist()
    ([0.0, 2.5, 5.0, 7.5, 10.0], [0.0, 0.25, 0.5, 0.75, 1.0])
    """
    ts = np.asarray(track.times, float)
    k0 = np.ceil((ts[0] - origin) / period - 1e-9)
    k1 = np.floor((ts[-1] - origin) / period + 1e-9)
    grid = origin + period * np.arange(k0, k1 + 1)
    if grid.size == 0:
        return track
    theta = np.unwrap(np.asarray(track.bearing, float))
    x = np.column_stack([theta, track.rate])
    var = np.column_stack([np.asarray(track.sigma_bearing) ** 2,
                           np.asarray(track.sigma_rate) ** 2])
    seg = np.clip(np.searchsorted(ts, grid, side="right") - 1, 0, max(ts.size - 2, 0))
    keep = np.ones(grid.size, bool)
    out_x = np.zeros((grid.size, 2))
    out_v = np.zeros((grid.size, 2))
    for i, (tau, k) in enumerate(zip(grid, seg, strict=True)):
        if ts.size == 1 or abs(tau - ts[k]) < 1e-9:
            out_x[i], out_v[i] = x[k], var[k]
            continue
        if abs(tau - ts[k + 1]) < 1e-9:
            out_x[i], out_v[i] = x[k + 1], var[k + 1]
            continue
        dt = ts[k + 1] - ts[k]
        if dt > max_gap_s:
            keep[i] = False
            continue
        f1, f2 = transition_matrix(tau - ts[k], 1), transition_matrix(ts[k + 1] - tau, 1)
        q_tau = wna_covariance(tau - ts[k], q, 1)
        psi = q_tau @ f2.T @ np.linalg.inv(wna_covariance(dt, q, 1))
        lam = f1 - psi @ transition_matrix(dt, 1)
        out_x[i] = lam @ x[k] + psi @ x[k + 1]
        cov = (lam @ np.diag(var[k]) @ lam.T + psi @ np.diag(var[k + 1]) @ psi.T
               + q_tau - psi @ f2 @ q_tau)
        out_v[i] = np.maximum(np.diag(cov), 0.0)
    return SmoothedTrack(track.track_id, grid[keep], np.asarray(wrap_angle(out_x[keep, 0])),
                         out_x[keep, 1], np.sqrt(out_v[keep, 0]), np.sqrt(out_v[keep, 1]))
