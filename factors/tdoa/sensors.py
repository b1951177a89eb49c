"""TDOA factor whose sensor positions are variables: an array's self-calibration.

A hydrophone range's array file holds surveyed positions, metres off the true ones; a delay
between two sensors then differs from the model's by the survey error over the speed (2 m:
1.3 ms), and every fix of a recording moves by the same error. Here each real sensor ``q``
has an offset ``delta_q`` (``Point3``, m) from its surveyed position ``s_q``, a variable of
the graph shared by every fix's factor; a sensor's surface image (``z -> -z``,
:func:`fusion.localization.sound_speed.path_sensors`) moves by the mirrored offset.

The travel times are those of :func:`factors.tdoa.gradient.travel_times` (straight rays, a
speed linear in depth, ``g = 0`` one speed). Their derivative by a sensor's position comes from
their symmetry: the time from ``p`` to sensor ``s`` equals the time from ``s`` to ``p``
(``ln(c(b)/c(a)) / (g (b - a))`` is symmetric in the two depths), and the time from ``p`` to the
image of ``s`` equals the time from ``s`` to the image of ``p``; so ``dT/ds`` is the source
Jacobian of ``travel_times`` with the sensor as source.

The residual of pair ``(i, j)`` is ``T_i - T_j - tau`` (s), scaled by ``sqrt(w)``.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (14): the model delay
``d_m = T_i(m) - T_j(m)``, here with ``s_i`` and ``s_j`` unknowns of the graph beside ``p`` and
``c``. Decisions and measurements: docs/localization.md, "Sensor positions from the fixes".
"""

from __future__ import annotations

import gtsam
import numpy as np
from numpy.typing import ArrayLike

from factors.tdoa.gradient import travel_times
from factors.tdoa.model import TdoaModel

__all__ = ["sensor_offset_tdoa_factor", "sensor_times"]

_MIRROR = np.array([1.0, 1.0, -1.0])


def sensor_times(p: ArrayLike, sensors: ArrayLike, speed: ArrayLike, d_ref: float,
                 *, jacobian: bool = False) -> tuple:
    """Travel times from `p` to `sensors` (z > 0: surface images) under ``speed`` (``[c]`` or
    ``[c_ref, g]``): ``(T (n,), dT/dp (n, 3), dT/dspeed (n, k), dT/d(real sensor) (n, 3))``,
    the derivatives None unless `jacobian`; the last is by the position of the real sensor a
    row stands for (its image's mirror)."""
    sp = np.asarray(speed, dtype=float).reshape(-1)
    c, g = float(sp[0]), float(sp[1]) if sp.size > 1 else 0.0
    d = float(d_ref) if sp.size > 1 else 0.0
    s = np.asarray(sensors, dtype=float)
    t, h_p, h_s = travel_times(p, s, c, g, d, jacobian=jacobian)
    if not jacobian:
        return t, None, None, None
    p = np.asarray(p, dtype=float)
    image = (s[:, 2] > 0.0)[:, None]
    real = np.where(image, s * _MIRROR, s)
    other = np.where(image, p * _MIRROR, p)  # the image of p stands for the reflected path
    _, h_q, _ = travel_times(real, other, c, g, d, jacobian=True)
    return t, h_p, h_s[:, :sp.size], h_q


def sensor_offset_tdoa_factor(
    noise: gtsam.noiseModel.Base,
    key: int,
    speed_key: int,
    offset_keys: ArrayLike,
    sensors: ArrayLike,
    pairs: ArrayLike,
    taus: ArrayLike,
    *,
    n_real: int,
    d_ref: float = 0.0,
    weights: ArrayLike | None = None,
    robust: gtsam.noiseModel.mEstimator.Base | None = None,
) -> gtsam.CustomFactor:
    """A source's TDOAs with its position, the speed and the sensors' offsets as variables.

    Parameters
    ----------
    noise : gtsam.noiseModel.Base
        Gaussian noise of the ``m`` TDOAs (s).
    key : int
        The source position (``Point3``, m).
    speed_key : int
        The speed: a ``Vector(1)`` ``[c]`` (m/s) or a ``Vector(2)`` ``[c_ref, g]`` about `d_ref`.
    offset_keys : array_like of int, shape (n_real,)
        Key of each real sensor's offset from its surveyed position (``Point3``, m).
    sensors : array_like, shape (n', 3)
        Surveyed sensors, the real ones (rows ``0..n_real-1``) then images (row ``q + n_real``
        the image of ``q``), m.
    pairs, taus : array_like
        Pairs of `sensors` (m, 2) and delays (m,), s.
    n_real : int, keyword-only
        Number of real sensors.
    d_ref : float, keyword-only
        Reference depth of ``c_ref`` (a ``Vector(2)`` speed), m.
    weights : array_like, shape (m,), optional, keyword-only
        Weight of each TDOA (negative counts as 0).
    robust : mEstimator, optional, keyword-only
        Robust loss per TDOA.
    """
    model = TdoaModel.build(sensors, pairs, taus)
    s0, m = model.sensors, int(model.first.shape[0])
    if int(noise.dim()) != m:
        raise ValueError(f"noise model dimension {noise.dim()} differs from the {m} TDOAs")
    okeys = [int(k) for k in np.asarray(offset_keys).reshape(-1)]
    if len(okeys) != n_real or s0.shape[0] > 2 * n_real:
        raise ValueError("one offset key per real sensor; rows beyond the real ones are images")
    owner = np.arange(s0.shape[0]) % n_real
    mirror = np.where((np.arange(s0.shape[0]) >= n_real)[:, None], _MIRROR, 1.0)
    used = sorted(set(owner[np.union1d(model.first, model.second)].tolist()))
    w = np.ones(m) if weights is None else np.array(weights, dtype=float).reshape(-1)
    if w.shape != (m,) or not np.all(np.isfinite(w)):
        raise ValueError(f"weights must be {m} finite numbers")
    sw = np.sqrt(np.maximum(w, 0.0))
    keys = [int(key), int(speed_key), *(okeys[q] for q in used)]
    if len(set(keys)) != len(keys):
        raise ValueError("position, speed and offset keys must differ")
    if robust is not None:
        noise = gtsam.noiseModel.Robust.Create(robust, noise)
    sign = model.incidence  # +1 at a pair's first sensor, -1 at its second

    def error_func(this: gtsam.CustomFactor, values: gtsam.Values,
                   jacobians: list[np.ndarray] | None) -> np.ndarray:
        ks = this.keys()
        p = values.atPoint3(ks[0])
        sp = values.atVector(ks[1])
        delta = np.zeros((n_real, 3))
        for j, q in enumerate(used):
            delta[q] = values.atPoint3(ks[2 + j])
        s = s0 + mirror * delta[owner]
        t, h_p, h_s, h_q = sensor_times(p, s, sp, d_ref, jacobian=jacobians is not None)
        r = t[model.first] - t[model.second] - model.taus
        if jacobians is not None:
            jacobians[0] = sw[:, None] * (h_p[model.first] - h_p[model.second])
            jacobians[1] = sw[:, None] * (h_s[model.first] - h_s[model.second])
            for j, q in enumerate(used):
                jacobians[2 + j] = sw[:, None] * (sign[:, owner == q] @ h_q[owner == q])
        return sw * r

    return gtsam.CustomFactor(noise, keys, error_func)
