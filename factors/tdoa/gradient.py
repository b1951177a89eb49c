"""TDOA factor with a depth-dependent sound speed: a linear profile along straight rays.

The sound speed grows linearly with depth ``d = -z`` (m, z up) around a reference depth
``d_ref`` (a constant the caller picks, e.g. the sensors' mean depth)::

    c(d) = c_ref + g (d - d_ref)

with ``c_ref`` (m/s) and ``g`` (1/s) the unknown ``Vector(2)`` ``[c_ref, g]`` of the graph (or
fixed). The travel time along the straight ray from a sensor at depth ``a`` to a source at depth
``b`` is the ray's length times its mean slowness, the integral of ``1/c`` over depth divided
by ``b - a`` -- the log-mean speed::

    T = L ln(c(b)/c(a)) / (g (b - a)) = L h(u) / c(a),   u = g (b - a) / c(a),
    h(u) = ln(1 + u) / u   (h -> 1 - u/2 + u^2/3 ... as u -> 0: T -> L / c(a))

A surface image of a sensor (depth ``a < 0``, :func:`fusion.localization.sound_speed.
path_sensors`) stands for the reflected path: the profile is mirrored about the surface
(``c(|d|)``), so the ray from depth ``a < 0`` to ``b > 0`` crosses two layers and
``T = L (G(|a|) + G(b)) / (b - a)`` with ``G(d) = integral_0^d dd'/c = d h(g d / c_0) / c_0``,
``c_0 = c_ref - g d_ref`` the speed at the surface.

The residual of pair ``(i, j)`` is ``T_i - T_j - tau`` (s), optionally weighted by
``sqrt(w_k)`` like :func:`factors.tdoa.factors.weighted_tdoa_vector_factor`. Derivatives
(``dT/dL = h / c(a)`` etc.) are in :meth:`GradientTdoaModel.residual`; ``h'(u) = (1/(1+u) - h)/u``.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (14): the model delay
``d_m = T_i(m) - T_j(m)`` with the travel time of a depth-dependent speed instead of ``L / c``
(a straight ray: refraction bends rays of a 1 % profile by far less than the array's metres).
Decisions and measurements: docs/localization.md, "A depth-dependent sound speed".
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.tdoa.model import MIN_RANGE, TdoaModel

__all__ = ["GradientTdoaModel", "gradient_tdoa_factor", "travel_times"]

#: Below this |u| the series of h(u) and h'(u) are used (their error is ~u^4 relative).
_SERIES_U = 1e-3


def _h(u: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``h(u) = ln(1 + u)/u`` and ``h'(u)``, stable at ``u -> 0``."""
    small = np.abs(u) < _SERIES_U
    us = np.where(small, 1.0, u)
    h_big = np.log1p(us) / us
    h_series = 1.0 - u / 2.0 + u * u / 3.0 - u**3 / 4.0 + u**4 / 5.0
    h = np.where(small, h_series, h_big)
    dh_big = (1.0 / (1.0 + us) - h_big) / us
    dh_series = -0.5 + 2.0 * u / 3.0 - 0.75 * u * u + 0.8 * u**3
    return h, np.where(small, dh_series, dh_big)


def _layer(d: NDArray[np.float64], c0: float, g: float) -> tuple:
    """``G(d)`` from the surface down to depth ``d >= 0`` and its derivatives by ``d``, ``c0``
    and ``g`` (``c0`` held): ``G = d h(v)/c0``, ``v = g d / c0``."""
    v = g * d / c0
    h, dh = _h(v)
    val = d * h / c0
    by_d = 1.0 / (c0 + g * d)  # dG/dd = 1/c(d)
    by_c0 = -d / (c0 * (c0 + g * d))
    by_g = d * d * dh / (c0 * c0)
    return val, by_d, by_c0, by_g


def travel_times(p: ArrayLike, sensors: ArrayLike, c_ref: float, g: float, d_ref: float,
                 *, jacobian: bool = False) -> tuple:
    """Straight-ray travel times from a source `p` (3,) to each sensor (n, 3), s; or with
    `p` of shape (n, 3), from each ``p[k]`` to ``sensors[k]``.

    Returns ``(T (n,), dT/dp (n, 3), dT/d[c_ref, g] (n, 2))``; the derivatives are None
    unless `jacobian`. A sensor above the surface (``z > 0``) is a surface image.
    """
    p = np.asarray(p, dtype=float)
    s = np.asarray(sensors, dtype=float)
    diff = p - s
    length = np.sqrt(np.einsum("ij,ij->i", diff, diff))
    b = np.maximum(-p[..., 2], 0.0)  # source depth (a source above the surface: at it)
    a = -s[:, 2]
    image = a < 0.0
    # direct rays: T = L h(u)/c(a)
    ca = c_ref + g * (a - d_ref)
    u = g * (b - a) / ca
    h, dh = _h(u)
    t_dir = length * h / ca
    # surface images: T = L (G(|a|) + G(b)) / (b + |a|)
    c0 = c_ref - g * d_ref
    ga, _, ga_c0, ga_g = _layer(np.abs(a), c0, g)
    gb, gb_d, gb_c0, gb_g = _layer(np.asarray(b), c0, g)
    span = np.where(image, b - a, 1.0)
    t_img = length * (ga + gb) / span
    t = np.where(image, t_img, t_dir)
    if not jacobian:
        return t, None, None
    unit = diff / np.maximum(length, MIN_RANGE)[:, None]
    below = np.where(-p[..., 2] >= 0.0, 1.0, 0.0)  # db/dz = -1 under the surface
    # direct: dT/db = L h'(u) g / c(a)^2; dT/dc_ref, dT/dg through c(a) and u
    dir_b = length * dh * g / (ca * ca)
    dir_c = -length * h / ca**2 + length * dh / ca * (-u / ca)
    du_g = (b - a) / ca - u * (a - d_ref) / ca
    dir_g = -length * h * (a - d_ref) / ca**2 + length * dh / ca * du_g
    # images: c0 = c_ref - g d_ref
    img_b = length * (gb_d / span - (ga + gb) / span**2)
    img_c = length * (ga_c0 + gb_c0) / span
    img_g = length * ((ga_g + gb_g) - d_ref * (ga_c0 + gb_c0)) / span
    by_len = np.where(image, (ga + gb) / span, h / ca)
    by_b = np.where(image, img_b, dir_b)
    h_p = by_len[:, None] * unit
    h_p[:, 2] -= below * by_b
    h_s = np.column_stack([np.where(image, img_c, dir_c), np.where(image, img_g, dir_g)])
    return t, h_p, h_s


@dataclass(frozen=True)
class GradientTdoaModel:
    """One source's TDOAs under the linear profile (see the module docstring).

    Attributes
    ----------
    base : TdoaModel
        Sensors, pairs and measured delays (checked).
    d_ref : float
        Reference depth of ``c_ref``, m (positive down).
    """

    base: TdoaModel
    d_ref: float

    @classmethod
    def build(cls, sensors: ArrayLike, pairs: ArrayLike, taus: ArrayLike,
              d_ref: float) -> GradientTdoaModel:
        if not np.isfinite(d_ref):
            raise ValueError(f"reference depth must be finite, got {d_ref!r}")
        return cls(TdoaModel.build(sensors, pairs, taus), float(d_ref))

    def residual(self, p: NDArray[np.float64], speed: NDArray[np.float64], *,
                 jacobian: bool = False) -> tuple:
        """``(r (m,), dr/dp (m, 3), dr/d[c_ref, g] (m, 2))``, r = T_i - T_j - tau (s)."""
        c_ref, g = float(speed[0]), float(speed[1])
        m = self.base
        t, h_p, h_s = travel_times(p, m.sensors, c_ref, g, self.d_ref, jacobian=jacobian)
        r = t[m.first] - t[m.second] - m.taus
        if not jacobian:
            return r, None, None
        return r, h_p[m.first] - h_p[m.second], h_s[m.first] - h_s[m.second]


def _check_speed(speed: ArrayLike) -> NDArray[np.float64]:
    v = np.array(speed, dtype=float).reshape(-1)
    if v.shape != (2,) or not np.all(np.isfinite(v)) or v[0] <= 0:
        raise ValueError(f"speed must be [c_ref > 0 (m/s), g (1/s)], got {speed!r}")
    return v


def gradient_tdoa_factor(
    noise: gtsam.noiseModel.Base,
    key: int,
    sensors: ArrayLike,
    pairs: ArrayLike,
    taus: ArrayLike,
    *,
    d_ref: float,
    weights: ArrayLike | None = None,
    speed: ArrayLike | None = None,
    speed_key: int | None = None,
    robust: gtsam.noiseModel.mEstimator.Base | None = None,
) -> gtsam.CustomFactor:
    """All of a source's TDOAs under the linear profile, in one factor.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        Gaussian noise of the ``m`` TDOAs (s), e.g. ``Diagonal.Sigmas``.
    key : int
        The source position (``Point3``, m).
    sensors, pairs, taus : array_like
        Sensors (n, 3) m (z > 0: surface images), pairs (m, 2), delays (m,) s.
    d_ref : float, keyword-only
        Reference depth of ``c_ref``, m.
    weights : array_like, shape (m,), optional, keyword-only
        Weight of each TDOA (negative counts as 0): residual and Jacobians scaled by sqrt(w).
    speed : array_like ``[c_ref, g]``, optional, keyword-only
        Fixed profile; or `speed_key`, the key of a ``Vector(2)`` ``[c_ref, g]`` unknown.
    robust : mEstimator, optional, keyword-only
        Robust loss applied per TDOA (the noise model becomes ``Robust``).
    """
    if (speed is None) == (speed_key is None):
        raise ValueError("give exactly one of speed ([c_ref, g], fixed) and speed_key")
    model = GradientTdoaModel.build(sensors, pairs, taus, d_ref)
    if int(noise.dim()) != model.base.m:
        raise ValueError(f"noise model dimension {noise.dim()} differs from the "
                         f"{model.base.m} TDOAs")
    w = np.ones(model.base.m) if weights is None else np.array(weights, dtype=float).reshape(-1)
    if w.shape != (model.base.m,) or not np.all(np.isfinite(w)):
        raise ValueError(f"weights must be {model.base.m} finite numbers")
    sw = np.sqrt(np.maximum(w, 0.0))
    fixed = None if speed is None else _check_speed(speed)
    keys = [int(key)] if speed_key is None else [int(key), int(speed_key)]
    if len(set(keys)) != len(keys):
        raise ValueError("position and speed keys must differ")
    if robust is not None:
        noise = gtsam.noiseModel.Robust.Create(robust, noise)

    def error_func(this: gtsam.CustomFactor, values: gtsam.Values,
                   jacobians: list[np.ndarray] | None) -> np.ndarray:
        ks = this.keys()
        p = values.atPoint3(ks[0])
        sp = fixed if fixed is not None else values.atVector(ks[1])
        r, h_p, h_s = model.residual(p, sp, jacobian=jacobians is not None)
        if jacobians is not None:
            jacobians[0] = sw[:, None] * h_p
            if fixed is None:
                jacobians[1] = sw[:, None] * h_s
        return sw * r

    return gtsam.CustomFactor(noise, keys, error_func)
