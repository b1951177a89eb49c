"""A drifting TDOA moved to the time of one emission of the source that owns it.

A refined TDOA is measured at the window centre on the clock of its pair's first sensor, and a
moving source drifts it (its ``rate``, up to ~2.7 ms/s at 2 m/s). The TDOAs of one window
therefore refer to different emissions of a source, up to the array's travel-time spread apart.
:func:`emission_shift` gives the change of each delay when it is moved along its drift to the
arrival at its first sensor of the one emission whose mean direct arrival is at the window
centre -- the emission a fix of that window stands for.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["emission_shift"]


def emission_shift(rates: ArrayLike, first_sensors: ArrayLike, reflected: ArrayLike,
                   position: ArrayLike, sensors: ArrayLike, c: float,
                   surface_z: float | None = None) -> NDArray[np.float64]:
    """Change of each delay moved to one emission of the source at `position`, s.

    Parameters
    ----------
    rates : array_like, shape (m,)
        Drift of each delay, s/s.
    first_sensors : array_like of int, shape (m,)
        The first sensor ``i`` of each pair.
    reflected : array_like of bool, shape (m,)
        Whether the delay is read with a surface echo at sensor ``i``.
    position : array_like, shape (3,)
        The source, m.
    sensors : array_like, shape (n, 3)
        Sensor positions, m.
    c : float
        Sound speed, m/s.
    surface_z : float, optional
        Height of the reflecting surface, m (needed when any delay is `reflected`).

    Returns
    -------
    ndarray, shape (m,)
        ``rate * (t_i - t_mid)``, with ``t_i - t_mid`` the arrival at sensor ``i`` (along its
        path) minus the mean direct arrival.
    """
    s = np.asarray(sensors, dtype=float)
    p = np.asarray(position, dtype=float)
    r = np.linalg.norm(s - p, axis=1) / c
    i = np.asarray(first_sensors, dtype=np.intp)
    first = r[i]
    refl = np.asarray(reflected, dtype=bool)
    if np.any(refl):
        if surface_z is None:
            raise ValueError("a reflected delay needs the surface height")
        image = s[i[refl]] * [1.0, 1.0, -1.0] + [0.0, 0.0, 2.0 * surface_z]
        first = first.copy()
        first[refl] = np.linalg.norm(image - p, axis=1) / c
    return np.asarray(rates, dtype=float) * (first - r.mean())
