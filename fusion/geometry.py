"""Geometry shared by every pipeline: angles, sensor arrays, delays, cosine-spaced beams.

Conventions (see the file-format notes of the project): local Cartesian metres, x east, y north,
z up; angles are radians inside the library and degrees in files; times are seconds.

Beams of a line array are equally spaced in cosine of the angle from the forward axis. With ``N``
beams, beam 0 looks at forward endfire (0 rad) and beam ``N - 1`` at aft endfire (pi rad)::

    cos(theta) = 1 - 2 b / (N - 1)
    b = (N - 1) (1 - cos(theta)) / 2
    db/dt = (N - 1) / 2 * sin(theta) * dtheta/dt

The main lobe of a line array of aperture ``L`` at wavelength ``lambda`` is about
``0.886 lambda / L`` wide in cosine space, the same for every beam.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.angles import wrap_angle  # the one angle-wrapping rule, re-exported here

__all__ = [
    "SensorArray",
    "beam_from_bearing",
    "beam_rate_from_bearing_rate",
    "beam_tolerance",
    "beamwidth_cos",
    "beamwidth_deg",
    "bearing_from_beam",
    "check_radians",
    "bearing_rate_from_beam_rate",
    "compass_bearing_deg",
    "propagation_delay",
    "surface_image",
    "tdoa",
    "wrap_angle",
    "wrap_deg",
]

#: Relative tolerance below which an array's sensors count as collinear (smallest to largest
#: singular value of the centred positions).
COLLINEAR_RTOL = 1e-6


#: Largest magnitude, rad, of an angle the library takes as radians: one turn either way plus a
#: rounding margin. Beyond it the values are almost surely degrees (a file's ``*_deg`` column
#: passed without :func:`numpy.radians`).
RADIANS_LIMIT = 2.0 * np.pi + 1e-6


def check_radians(angles: ArrayLike, name: str = "bearings") -> NDArray[np.float64]:
    """`angles` as a float array if they look like radians (every ``|value| <= 2 pi``).

    Degrees of a source at more than about 6.3 deg off zero fail; degrees that all lie within
    6.3 deg of zero cannot be told from radians and pass.

    Raises
    ------
    ValueError
        ``"<name> must be in radians: |value| up to 182.5 > 2*pi (degrees? use numpy.radians)"``.
    """
    a = np.asarray(angles, dtype=float)
    finite = a[np.isfinite(a)]
    if finite.size and float(np.max(np.abs(finite))) > RADIANS_LIMIT:
        big = float(np.max(np.abs(finite)))
        raise ValueError(f"{name} must be in radians: |value| up to {big:.6g} > 2*pi "
                         "(degrees? use numpy.radians)")
    return a


def wrap_deg(a: ArrayLike) -> NDArray[np.float64] | float:
    """Wrap angles in degrees to ``[-180, 180)``.

    Parameters
    ----------
    a : float or array_like
        Angle(s), deg.

    Returns
    -------
    float or ndarray
        Same shape as `a`, in ``[-180, 180)``; a float for scalar input.

    Notes
    -----
    The rule of :func:`factors.angles.wrap_angle` in degrees: ``mod(a + 180, 360) - 180``, with
    a result that ``mod`` rounded up to ``+180`` (an `a` just below -180) moved to -180.

    Examples
    --------
    >>> wrap_deg(190.0)
    -170.0
    >>> wrap_deg(180.0), wrap_deg(np.nextafter(-180.0, -360.0))
    (-180.0, -180.0)
    """
    out = np.mod(np.asarray(a, dtype=float) + 180.0, 360.0) - 180.0
    out = np.where(out >= 180.0, out - 360.0, out)  # mod rounded up to 360: -180, not +180
    return _scalar_or_array(out)


def _scalar_or_array(out: NDArray[np.float64] | np.floating) -> NDArray[np.float64] | float:
    """A float for a 0-d result (scalar input), else the array: the functions here return
    what they were given."""
    return float(out) if np.ndim(out) == 0 else out


def _check_n_beams(n_beams: int) -> None:
    if int(n_beams) != n_beams or n_beams < 2:
        raise ValueError(f"n_beams must be an integer >= 2, got {n_beams!r}")


def bearing_from_beam(beam: ArrayLike, n_beams: int) -> NDArray[np.float64] | float:
    """Bearing from the forward axis of a (fractional) beam index.

    Parameters
    ----------
    beam : float or array_like
        Beam index, 0 (forward endfire) to ``n_beams - 1`` (aft endfire); fractional allowed.
    n_beams : int
        Number of beams, equally spaced in cosine.

    Returns
    -------
    float or ndarray
        Bearing, rad, in ``[0, pi]``: ``arccos(1 - 2 b / (N - 1))``.
    """
    _check_n_beams(n_beams)
    c = 1.0 - 2.0 * np.asarray(beam, dtype=float) / (n_beams - 1)
    out = np.arccos(np.clip(c, -1.0, 1.0))
    return _scalar_or_array(out)


def beam_from_bearing(theta: ArrayLike, n_beams: int) -> NDArray[np.float64] | float:
    """Fractional beam index of a bearing from the forward axis.

    Parameters
    ----------
    theta : float or array_like
        Bearing from the forward axis, rad (0 forward endfire, pi aft endfire).
    n_beams : int
        Number of beams, equally spaced in cosine.

    Returns
    -------
    float or ndarray
        ``(N - 1) (1 - cos(theta)) / 2``, in ``[0, N - 1]``.
    """
    _check_n_beams(n_beams)
    out = (n_beams - 1) * (1.0 - np.cos(np.asarray(theta, dtype=float))) / 2.0
    return _scalar_or_array(out)


def beam_rate_from_bearing_rate(
    theta: ArrayLike, theta_dot: ArrayLike, n_beams: int
) -> NDArray[np.float64] | float:
    """Beam rate of a target at bearing `theta` moving at bearing rate `theta_dot`.

    Parameters
    ----------
    theta : float or array_like
        Bearing from the forward axis, rad.
    theta_dot : float or array_like
        Bearing rate, rad/s (or any rate unit; the result carries the same time unit).
    n_beams : int
        Number of beams, equally spaced in cosine.

    Returns
    -------
    float or ndarray
        Beams per unit time: ``(N - 1) / 2 * sin(theta) * theta_dot``.
    """
    _check_n_beams(n_beams)
    out = (n_beams - 1) / 2.0 * np.sin(np.asarray(theta, dtype=float)) * np.asarray(theta_dot)
    return _scalar_or_array(out)


def bearing_rate_from_beam_rate(
    beam: ArrayLike, beam_rate: ArrayLike, n_beams: int
) -> NDArray[np.float64] | float:
    """Bearing rate of a target at a (fractional) beam moving at `beam_rate` beams per unit time.

    Parameters
    ----------
    beam : float or array_like
        Beam index (fractional allowed).
    beam_rate : float or array_like
        Beams per unit time.
    n_beams : int
        Number of beams, equally spaced in cosine.

    Returns
    -------
    float or ndarray
        Bearing rate, rad per the same time unit. At the endfire beams, where ``sin(theta) = 0`` and
        the map is singular, the sine is floored at ``sin`` of half a beam step, so the result stays
        finite.
    """
    _check_n_beams(n_beams)
    theta = np.asarray(bearing_from_beam(beam, n_beams))
    # Half a beam step off endfire: the smallest sine a resolvable target can have.
    sin_floor = np.sin(float(bearing_from_beam(0.5, n_beams)))
    s = np.maximum(np.sin(theta), sin_floor)
    out = 2.0 * np.asarray(beam_rate, dtype=float) / ((n_beams - 1) * s)
    return _scalar_or_array(out)


def beamwidth_cos(wavelength: float, aperture: float) -> float:
    """Approximate main-lobe width of a line array in cosine space, ``0.886 lambda / L``.

    Parameters
    ----------
    wavelength : float
        Acoustic wavelength, m.
    aperture : float
        Array aperture, m.

    Returns
    -------
    float
        Width in cosine units (dimensionless), the same for every beam.
    """
    if not (np.isfinite(wavelength) and np.isfinite(aperture)) or wavelength <= 0 or aperture <= 0:
        raise ValueError(
            f"wavelength and aperture must be positive, got {wavelength!r}, {aperture!r}"
        )
    return 0.886 * wavelength / aperture


def beamwidth_deg(
    bearing_deg: ArrayLike, *, wavelength: float, aperture: float
) -> NDArray[np.float64] | float:
    """Main-lobe width in bearing of a line array steered at `bearing_deg`, deg.

    Parameters
    ----------
    bearing_deg : float or array_like
        Steering bearing from the forward axis, deg in ``[0, 180]``.
    wavelength : float
        Acoustic wavelength, m.
    aperture : float
        Array aperture, m.

    Returns
    -------
    float or ndarray
        Same shape as `bearing_deg`: the width in bearing of the cosine interval
        ``cos(theta) +- 0.443 lambda / L`` (:func:`beamwidth_cos` centred on the steering
        direction), clipped to ``[-1, 1]`` so that it stays finite at endfire, deg.

    Notes
    -----
    The main lobe is ``0.886 lambda / L`` wide in cosine for every beam; mapped to bearing it
    widens away from broadside, about ``0.886 lambda / (L sin theta)`` rad there. This exact
    mapping is used by the acquisition (program segment 40 of the acquisition method text) and
    the bearing tracker alike.

    Examples
    --------
    Broadside, ``2 arcsin(0.443 lambda / L)``:

    >>> round(beamwidth_deg(90.0, wavelength=5.0, aperture=50.0), 4)
    5.0781
    """
    w = beamwidth_cos(wavelength, aperture)
    u = np.cos(np.radians(np.asarray(bearing_deg, dtype=float)))
    lo = np.maximum(-1.0, u - 0.5 * w)
    hi = np.minimum(1.0, u + 0.5 * w)
    out = np.degrees(np.arccos(lo) - np.arccos(hi))
    return _scalar_or_array(out)


def beam_tolerance(wavelength: float, aperture: float, n_beams: int) -> int:
    """Beam tolerance: half a main-lobe width in beams, at least 2.

    Parameters
    ----------
    wavelength : float
        Acoustic wavelength, m.
    aperture : float
        Array aperture, m.
    n_beams : int
        Number of beams, equally spaced in cosine (spacing ``2 / (N - 1)`` in cosine).

    Returns
    -------
    int
        ``max(2, floor(0.443 lambda / L / (2 / (N - 1))))``.
    """
    _check_n_beams(n_beams)
    half_width_beams = 0.5 * beamwidth_cos(wavelength, aperture) / (2.0 / (n_beams - 1))
    return max(2, int(np.floor(half_width_beams)))


def compass_bearing_deg(from_xy: ArrayLike, to_xy: ArrayLike) -> NDArray[np.float64] | float:
    """True bearing, degrees clockwise from north, from `from_xy` to `to_xy` (x east, y north).

    Parameters
    ----------
    from_xy, to_xy : array_like, shape (..., 2)
        Positions, m; broadcast against each other.

    Returns
    -------
    float or ndarray, shape (...)
        Bearing in ``[0, 360)`` deg.
    """
    d = np.asarray(to_xy, dtype=float) - np.asarray(from_xy, dtype=float)
    out = np.mod(np.degrees(np.arctan2(d[..., 0], d[..., 1])), 360.0)
    return _scalar_or_array(out)


@dataclass(frozen=True)
class SensorArray:
    """Positions of the sensors of an array and the sound speed.

    Attributes
    ----------
    positions : ndarray, shape (n, 3)
        Sensor positions, m (x east, y north, z up).
    sound_speed : float
        Sound speed, m/s.
    ids : tuple of str
        Sensor names; defaults to ``H1 .. Hn``.

    Raises
    ------
    ValueError
        Fewer than 3 sensors, non-finite positions, a non-positive sound speed, duplicate ids,
        or all sensors on one line (no 2-D or 3-D fix possible).
    """

    positions: NDArray[np.float64]
    sound_speed: float = 1500.0
    ids: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        pos = np.array(self.positions, dtype=float)
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise ValueError(f"sensor positions must have shape (n, 3), got {pos.shape}")
        if not np.all(np.isfinite(pos)):
            raise ValueError("sensor positions contain NaN or infinite values")
        if pos.shape[0] < 3:
            raise ValueError(f"an array needs at least 3 sensors, got {pos.shape[0]}")
        if not np.isfinite(self.sound_speed) or self.sound_speed <= 0:
            raise ValueError(f"sound_speed must be positive, got {self.sound_speed!r}")
        centred = pos - pos.mean(axis=0)
        sv = np.linalg.svd(centred, compute_uv=False)
        if sv[0] == 0 or sv[1] <= COLLINEAR_RTOL * sv[0]:
            raise ValueError("all sensors are collinear (degenerate geometry)")
        ids = tuple(self.ids) if self.ids else tuple(f"H{i + 1}" for i in range(pos.shape[0]))
        if len(ids) != pos.shape[0]:
            raise ValueError(f"{len(ids)} sensor ids for {pos.shape[0]} sensors")
        if len(set(ids)) != len(ids):
            raise ValueError("sensor ids are not unique")
        pos.setflags(write=False)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "sound_speed", float(self.sound_speed))
        object.__setattr__(self, "ids", ids)

    @property
    def n_sensors(self) -> int:
        """Number of sensors."""
        return int(self.positions.shape[0])

    def pairs(self) -> list[tuple[int, int]]:
        """All sensor pairs ``(i, j)`` with ``i < j``, in lexicographic order."""
        return list(combinations(range(self.n_sensors), 2))


def surface_image(points: ArrayLike, surface_z: float) -> NDArray[np.float64]:
    """Mirror image(s) of point(s) in the sea surface ``z = surface_z`` (z up):
    ``(x, y, 2 z_s - z)``, the image method of a surface-reflected path.

    Examples
    --------
    >>> surface_image([[10.0, 20.0, -1000.0]], 0.0).tolist()
    [[10.0, 20.0, 1000.0]]
    """
    return np.asarray(points, dtype=float) * [1.0, 1.0, -1.0] + [0.0, 0.0, 2.0 * surface_z]


def propagation_delay(source: ArrayLike, sensors: ArrayLike, c: float) -> NDArray[np.float64]:
    """Straight-line travel time from source position(s) to every sensor.

    Parameters
    ----------
    source : array_like, shape (3,) or (m, 3)
        Source position(s), m.
    sensors : array_like, shape (n, 3)
        Sensor positions, m.
    c : float
        Sound speed, m/s.

    Returns
    -------
    ndarray, shape (n,) or (m, n)
        Travel times, s: ``|p - s_i| / c``.
    """
    p = np.asarray(source, dtype=float)
    s = np.asarray(sensors, dtype=float)
    return np.linalg.norm(p[..., None, :] - s, axis=-1) / c


def tdoa(
    source: ArrayLike, sensors: ArrayLike, pairs: ArrayLike, c: float
) -> NDArray[np.float64]:
    """Time differences of arrival ``tau_ij = t_i - t_j`` for straight-line propagation.

    Parameters
    ----------
    source : array_like, shape (3,) or (m, 3)
        Source position(s), m.
    sensors : array_like, shape (n, 3)
        Sensor positions, m.
    pairs : array_like of int, shape (k, 2)
        Sensor index pairs ``(i, j)``.
    c : float
        Sound speed, m/s.

    Returns
    -------
    ndarray, shape (k,) or (m, k)
        Arrival time at sensor i minus arrival time at sensor j, s.
    """
    t = propagation_delay(source, sensors, c)
    pr = np.asarray(pairs, dtype=int).reshape(-1, 2)
    return t[..., pr[:, 0]] - t[..., pr[:, 1]]
