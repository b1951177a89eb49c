"""Bistatic geometry of an active-sonar detection: its position error ellipse and aspect angle.

An active-sonar position comes from a bistatic range sum and a receiver bearing, so its error is
an ellipse whose size and orientation follow the geometry (long across the line of sight of a far
receiver, where the bearing error dominates; long along it when the bistatic angle is wide). The
paper ("Target tracking using fuzzy logic association") is silent on it; here each detection with
source and receiver positions gets the covariance propagated to first order from the sensor
accuracies (:func:`bistatic_covariance`). :class:`MeasurementModel` hands every detection of a
ping its covariance, falling back to an isotropic error where the geometry is absent (e.g.
radar) or undefined (on the source-receiver baseline). The tracker uses it in the Kalman update,
likelihood and gate, as a new track's position covariance, in the clutter map and in the motion
test.

The equivalent aspect angle (:func:`equivalent_aspect_deg`, the fuzzy input ``aspect_deg``,
Section 5 of the paper: 90 deg is specular) is computed from the same geometry when the data give
positions but no angle.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.active.noise import NoiseEstimator
from fusion.active.types import POSITION_CLUES, Ping

__all__ = ["MeasurementModel", "bistatic_covariance", "equivalent_aspect_deg"]


def bistatic_covariance(
    xy: ArrayLike,
    source: ArrayLike,
    receiver: ArrayLike,
    range_sum_sigma_m: float | ArrayLike,
    bearing_sigma_deg: float | ArrayLike,
) -> NDArray[np.float64]:
    """Position covariance of bistatic echoes, by first-order propagation of the sensor errors.

    A bistatic position ``p`` (:func:`fusion.simulate.multistatic.bistatic_position`) is the
    point of the ellipse with foci ``s`` (source) and ``r`` (receiver) and range sum
    ``rho = |p - s| + |p - r|`` on the bearing line ``theta`` from the receiver. With
    ``u = (sin theta, cos theta)`` the unit vector from the receiver to the echo,
    ``u' = du/dtheta = (cos theta, -sin theta)``, ``e`` the unit vector from the source to the
    echo, ``d = |p - r|`` and ``k = 1 + e . u`` (``2 cos^2`` of half the bistatic angle),
    differentiating ``|r + d u - s| + d = rho`` gives the Jacobian columns

    - ``dp/drho = u / k`` (along the receiver's line of sight, long when the bistatic angle is
      wide),
    - ``dp/dtheta = d (u' - u (e . u') / k)`` (across it, growing with the receiver range),

    and the covariance ``J diag(sigma_rho^2, sigma_theta^2) J^T``.

    Parameters
    ----------
    xy : array_like, shape (n, 2)
        Echo positions (x east, y north), m: the Jacobian is evaluated there.
    source, receiver : array_like, shape (n, 2) or (2,)
        Source and receiver positions, m.
    range_sum_sigma_m : float or array_like, shape (n,)
        Standard deviation of the bistatic range sum, m (>= 0), one for all echoes or one each.
    bearing_sigma_deg : float or array_like, shape (n,)
        Standard deviation of the bearing at the receiver, degrees (>= 0), one or one each.

    Returns
    -------
    ndarray, shape (n, 2, 2)
        Covariances, m^2. NaN where the echo lies on the source or on the receiver (no
        direction) or where ``k`` < 1e-6 (on the baseline between source and receiver, where
        the range sum says nothing about the position along the baseline).

    Examples
    --------
    Monostatic, echo 1 km north: ``sigma_rho / 2`` in range, ``d sigma_theta`` across.

    >>> c = bistatic_covariance([[0.0, 1000.0]], [0.0, 0.0], [0.0, 0.0], 30.0, 1.0)
    >>> np.sqrt(np.diag(c[0])).round(2).tolist()
    [17.45, 15.0]
    """
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    s = np.broadcast_to(np.asarray(source, dtype=float), p.shape)
    r = np.broadcast_to(np.asarray(receiver, dtype=float), p.shape)
    sig_rho = np.broadcast_to(np.asarray(range_sum_sigma_m, dtype=float), p.shape[:1])
    sig_th = np.radians(np.broadcast_to(np.asarray(bearing_sigma_deg, dtype=float), p.shape[:1]))
    with np.errstate(invalid="ignore", divide="ignore"):
        rx, ry = p[:, 0] - r[:, 0], p[:, 1] - r[:, 1]
        sx, sy = p[:, 0] - s[:, 0], p[:, 1] - s[:, 1]
        d = np.hypot(rx, ry)
        ux, uy = rx / d, ry / d                                  # u; du/dtheta = (uy, -ux)
        a = np.hypot(sx, sy)
        ex, ey = sx / a, sy / a
        k = 1.0 + ex * ux + ey * uy
        k[~(k >= 1e-6)] = np.nan
        jrx, jry = sig_rho * ux / k, sig_rho * uy / k            # sigma_rho dp/drho
        w = (ex * uy - ey * ux) / k                              # (e . u') / k
        jtx, jty = sig_th * d * (uy - ux * w), sig_th * d * (-ux - uy * w)
    out = np.empty((p.shape[0], 2, 2))
    out[:, 0, 0] = jrx * jrx + jtx * jtx
    out[:, 0, 1] = out[:, 1, 0] = jrx * jry + jtx * jty
    out[:, 1, 1] = jry * jry + jty * jty
    return out



def equivalent_aspect_deg(
    position: ArrayLike, velocity: ArrayLike, source: ArrayLike, receiver: ArrayLike
) -> NDArray[np.float64]:
    """Equivalent (bistatic) aspect angle of an echo, degrees in [0, 180].

    Parameters
    ----------
    position : array_like, shape (..., 2)
        Echo (target) position, m.
    velocity : array_like, shape (..., 2)
        Target velocity, m/s (only its direction matters).
    source, receiver : array_like, shape (..., 2)
        Source and receiver positions, m.

    Returns
    -------
    ndarray, shape (...)
        ``arccos(h . b)`` in degrees, with ``h`` the unit heading and ``b`` the unit bisector of
        the unit vectors from the target to the source and to the receiver: 0 = bow-on,
        90 = beam-on (specular for a hull), 180 = stern-on. NaN where the velocity is zero or the
        bisector vanishes (target on the source-receiver baseline).

    Notes
    -----
    A bistatic echo behaves like a monostatic one seen along the bisector of the angle
    source-target-receiver, so the equivalent aspect is the aspect of that bisector.

    Examples
    --------
    >>> float(equivalent_aspect_deg([0, 0], [0, 3], [5000, 0], [4000, 100]).round(1))
    89.3
    """
    p = np.asarray(position, dtype=float)
    v = np.asarray(velocity, dtype=float)
    us = np.asarray(source, dtype=float) - p
    ur = np.asarray(receiver, dtype=float) - p
    with np.errstate(invalid="ignore", divide="ignore"):
        us = us / np.linalg.norm(us, axis=-1, keepdims=True)
        ur = ur / np.linalg.norm(ur, axis=-1, keepdims=True)
        b = us + ur
        b = b / np.linalg.norm(b, axis=-1, keepdims=True)
        h = v / np.linalg.norm(v, axis=-1, keepdims=True)
        cos = np.clip(np.sum(h * b, axis=-1), -1.0, 1.0)
    return np.degrees(np.arccos(cos))



class MeasurementModel:
    """Position covariance of each detection of a ping.

    Parameters
    ----------
    position_errors : {"geometry", "isotropic"}, optional
        ``geometry`` (default): detections with ``src_x, src_y, rcv_x, rcv_y`` get the bistatic
        error ellipse of :func:`bistatic_covariance`; ``isotropic``: every detection gets
        ``position_sigma_m`` per axis.
    position_sigma_m : float, optional
        Standard deviation of each position coordinate of a detection without a geometric
        covariance, m (> 0, default 100).
    range_sum_sigma_m : float, optional
        Accuracy (standard deviation) of the bistatic range sum, m (>= 0, default 100); the
        prior of `noise` when one is given.
    bearing_sigma_deg : float, optional
        Accuracy of the bearing at the receiver, deg (>= 0, default 1.5); not both 0.
    noise : NoiseEstimator, optional
        Per-receiver accuracies learnt from the data
        (:class:`fusion.active.noise.NoiseEstimator`), used instead of the two fixed values;
        the caller feeds it the pings (:meth:`NoiseEstimator.update`).

    Examples
    --------
    >>> R, geometric = MeasurementModel(position_sigma_m=50.0).covariances(
    ...     Ping(0, 0.0, [[0.0, 1000.0]]))
    >>> R[0].tolist(), geometric
    ([[2500.0, 0.0], [0.0, 2500.0]], False)
    """

    def __init__(
        self,
        *,
        position_errors: Literal["geometry", "isotropic"] = "geometry",
        position_sigma_m: float = 100.0,
        range_sum_sigma_m: float = 100.0,
        bearing_sigma_deg: float = 1.5,
        noise: NoiseEstimator | None = None,
    ) -> None:
        if not np.isfinite(position_sigma_m) or position_sigma_m <= 0:
            raise ValueError(f"position_sigma_m must be positive, got {position_sigma_m!r}")
        if position_errors not in ("geometry", "isotropic"):
            raise ValueError("position_errors must be 'geometry' or 'isotropic', got "
                             f"{position_errors!r}")
        for name, v in (("range_sum_sigma_m", range_sum_sigma_m),
                        ("bearing_sigma_deg", bearing_sigma_deg)):
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name} must be >= 0, got {v!r}")
        if range_sum_sigma_m == 0 and bearing_sigma_deg == 0:
            raise ValueError("range_sum_sigma_m and bearing_sigma_deg cannot both be 0")
        self.position_errors = position_errors
        self.R = np.eye(2) * position_sigma_m**2
        self.range_sum_sigma_m = float(range_sum_sigma_m)
        self.bearing_sigma_deg = float(bearing_sigma_deg)
        self.noise = noise

    def covariances(self, ping: Ping) -> tuple[NDArray[np.float64], bool]:
        """Position covariance of each detection of a ping.

        Parameters
        ----------
        ping : Ping

        Returns
        -------
        R : ndarray, shape (n, 2, 2)
            m^2: :func:`bistatic_covariance` from the range-sum and bearing accuracies (the
            estimator's for the detection's receiver, else the fixed values) for detections with
            finite source and receiver positions (``position_errors="geometry"``);
            ``position_sigma_m^2 I`` for the others (no positions, e.g. radar, an echo on the
            source-receiver baseline, or ``position_errors="isotropic"``).
        geometric : bool
            Whether any detection got a geometry-derived covariance.
        """
        if (self.position_errors != "geometry" or ping.n == 0
                or not all(k in ping.clues for k in POSITION_CLUES)):
            return np.broadcast_to(self.R, (ping.n, 2, 2)).copy(), False
        src = np.column_stack([ping.clues["src_x"], ping.clues["src_y"]])
        rcv = np.column_stack([ping.clues["rcv_x"], ping.clues["rcv_y"]])
        sig = self.noise.sigmas(ping) if self.noise is not None else None
        s_rho, s_th = sig if sig is not None else (self.range_sum_sigma_m, self.bearing_sigma_deg)
        R = bistatic_covariance(ping.xy, src, rcv, s_rho, s_th)
        with np.errstate(invalid="ignore"):
            bad = ~(R[:, 0, 0] * R[:, 1, 1] - R[:, 0, 1] ** 2 > 0)   # NaN or singular
        if bad.all():
            return np.broadcast_to(self.R, (ping.n, 2, 2)).copy(), False
        if bad.any():
            R[bad] = self.R
        return R, True
