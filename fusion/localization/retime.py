"""A drifting TDOA moved to the time of one emission of the source that owns it.

A refined TDOA is measured at the window centre on the clock of its pair's first sensor, and a
moving source drifts it (its ``rate``, up to ~2.7 ms/s at 2 m/s). The TDOAs of one window
therefore refer to different emissions of a source, up to the array's travel-time spread apart.
:func:`emission_shift` gives the change of each delay when it is moved along its drift to the
arrival at its first sensor of the one emission whose mean direct arrival is at the window
centre -- the emission a fix of that window stands for; :func:`retime_owned` moves each TDOA of
a window to the emission of the source that owns it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import surface_image
from fusion.localization.source_fix import LocalizationOutput

__all__ = ["emission_shift", "retime_owned"]


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
        image = surface_image(s[i[refl]], surface_z)
        first = first.copy()
        first[refl] = np.linalg.norm(image - p, axis=1) / c
    return np.asarray(rates, dtype=float) * (first - r.mean())


def retime_owned(out: LocalizationOutput, taus: NDArray[np.float64], rate: NDArray[np.float64],
                 pairs: NDArray[np.int_], pos: NDArray[np.float64], c: float,
                 surface_z: float | None) -> NDArray[np.float64]:
    """Each TDOA moved along its drift to the arrival at its first sensor of one emission.

    The emission is that of the source owning the TDOA (largest weight) whose mean direct
    arrival is at the window centre (:func:`emission_shift`); the arrival at the first sensor
    is along the path the source reads the TDOA on (direct, or reflected at the surface
    ``z = surface_z``).

    Parameters
    ----------
    out : LocalizationOutput
        A window's fixes, with each TDOA's weights and paths.
    taus, rate : ndarray, shape (m,)
        The window's TDOAs, s, and their drifts, s/s.
    pairs : ndarray of int, shape (m, 2)
        Sensor pairs of the TDOAs.
    pos : ndarray, shape (n, 3)
        Sensor positions, m.
    c : float
        Sound speed, m/s.
    surface_z : float or None
        Height of the reflecting surface, m (None: every path direct).

    Returns
    -------
    ndarray, shape (m,)
        The retimed TDOAs, s.
    """
    w = np.stack([s.weights for s in out.sources])  # (K, M)
    owner = np.argmax(w, axis=0)
    retimed = taus.copy()
    for k, fix in enumerate(out.sources):
        m = np.flatnonzero(owner == k)
        if m.size:
            reflected = np.isin(fix.paths[m], (1, 3)) if surface_z is not None else False
            retimed[m] = taus[m] + emission_shift(rate[m], pairs[m, 0],
                                                  np.broadcast_to(reflected, m.shape),
                                                  fix.position, pos, c, surface_z)
    return retimed
