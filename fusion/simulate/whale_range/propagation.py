"""Propagation physics of the bottom-mounted click range: sound-speed profiles, straight-ray
travel times through them, and the surface and sea-floor reflected paths (image geometry).

Used by :func:`fusion.simulate.clicks.simulate_clicks` when the new physics is switched on.
The localizer models none of this: it assumes straight rays at the one nominal speed written
into ``array.json``.

Conventions: positions in local Cartesian metres, z up (z = 0 at the surface, z < 0 in the
water); a profile is a function of depth ``d = -z >= 0``.

Travel time of a straight segment from depth ``d1`` to ``d2`` of length ``L``::

    T = L / (d2 - d1) * integral_{d1}^{d2} dd / c(d)     (= L / c(d1) when d1 = d2)

i.e. the length times the mean slowness over the depths the segment crosses. The integral comes
from a table of the cumulative slowness ``F(d)`` on a 1 m grid, interpolated by cubic Hermite
polynomials with the exact derivative ``1 / c(d)`` (error far below a nanosecond); segments whose
depth change is under :data:`_SHORT_DZ_M` use Gauss-Legendre quadrature of ``1 / c`` directly.
A reflected path is two straight segments joined at the reflection point, found from the image of
the source across the reflecting plane (surface ``z = 0`` or the sea-floor plane). Its delay
after the direct path is the image-geometry path difference ``|p' - s| - |p - s|`` at the
reflected path's own mean slowness (the straight-ray integral of ``1/c`` over its two segments
divided by its length): timing the two paths independently would let the small slowness
differences of straight rays that nearly coincide (grazing bottom echoes) put an echo before
its direct arrival, which real (refracted) rays never do.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["PROFILE_KINDS", "FloorPlane", "SoundSpeedProfile", "path_times", "segment_time"]

#: Profile kinds and their parameters (all speeds m/s, depths and scales m, gradients 1/s).
PROFILE_KINDS: dict[str, tuple[str, ...]] = {
    "constant": ("c0",),
    "linear": ("c0", "gradient"),  # c = c0 + gradient * d
    "munk": ("c_axis", "axis_depth_m", "scale_m", "epsilon"),
    # deep linear gradient plus a smooth (tanh) warm layer of excess speed over the thermocline
    "thermocline": ("c0", "gradient", "excess", "thermocline_depth_m", "thermocline_width_m"),
}

_SHORT_DZ_M = 2.0
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_TABLE_STEP_M = 1.0


@dataclass(frozen=True)
class SoundSpeedProfile:
    """A depth-dependent sound speed ``c(d)``, ``d = -z`` the depth in metres.

    Attributes
    ----------
    kind : str
        One of :data:`PROFILE_KINDS`.
    params : dict
        The kind's parameters::

            constant     c = c0
            linear       c = c0 + gradient d
            munk         c = c_axis (1 + epsilon (eta + exp(-eta) - 1)),
                         eta = 2 (d - axis_depth_m) / scale_m
            thermocline  c = c0 + gradient d
                             + excess (1 - tanh((d - thermocline_depth_m) / thermocline_width_m)) / 2
    max_depth_m : float
        Deepest depth the travel-time table covers (the sea floor or below), m.
    """

    kind: str
    params: dict[str, float]
    max_depth_m: float = 6000.0
    _table: tuple[NDArray[np.float64], NDArray[np.float64]] = field(
        init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        if self.kind not in PROFILE_KINDS:
            raise ValueError(f"profile kind must be one of {sorted(PROFILE_KINDS)}, got {self.kind!r}")
        need = set(PROFILE_KINDS[self.kind])
        if set(self.params) != need:
            raise ValueError(f"{self.kind} profile needs parameters {sorted(need)}, "
                             f"got {sorted(self.params)}")
        p = {k: float(v) for k, v in self.params.items()}
        if not all(np.isfinite(v) for v in p.values()):
            raise ValueError(f"profile parameters must be finite, got {p}")
        for name in ("scale_m", "thermocline_width_m", "c0", "c_axis"):
            if name in p and p[name] <= 0:
                raise ValueError(f"profile {name} must be positive, got {p[name]}")
        if not (np.isfinite(self.max_depth_m) and self.max_depth_m > 0):
            raise ValueError(f"max_depth_m must be positive, got {self.max_depth_m!r}")
        object.__setattr__(self, "params", p)
        d = np.arange(0.0, self.max_depth_m + 2 * _TABLE_STEP_M, _TABLE_STEP_M)
        c = self.speed(d)
        if np.any(c < 1300.0) or np.any(c > 1800.0):
            raise ValueError(f"{self.kind} profile leaves 1300-1800 m/s within "
                             f"0-{self.max_depth_m:g} m (min {c.min():.1f}, max {c.max():.1f})")
        # cumulative slowness F(d) = int_0^d dd'/c: 8-point Gauss-Legendre per 1 m cell
        mid, half = d[:-1] + 0.5 * _TABLE_STEP_M, 0.5 * _TABLE_STEP_M
        cells = half * (_GL_W[None, :] / self.speed(mid[:, None] + half * _GL_X[None, :])).sum(1)
        object.__setattr__(self, "_table", (d, np.concatenate([[0.0], np.cumsum(cells)])))

    def speed(self, depth: ArrayLike) -> NDArray[np.float64]:
        """Sound speed at depths `depth` (m, positive down), m/s."""
        d = np.asarray(depth, dtype=float)
        p = self.params
        if self.kind == "constant":
            return np.full_like(d, p["c0"])
        if self.kind == "linear":
            return p["c0"] + p["gradient"] * d
        if self.kind == "munk":
            eta = 2.0 * (d - p["axis_depth_m"]) / p["scale_m"]
            return p["c_axis"] * (1.0 + p["epsilon"] * (eta + np.exp(-eta) - 1.0))
        warm = 0.5 * (1.0 - np.tanh((d - p["thermocline_depth_m"]) / p["thermocline_width_m"]))
        return p["c0"] + p["gradient"] * d + p["excess"] * warm

    def slowness_integral(self, depth: ArrayLike) -> NDArray[np.float64]:
        """``F(d) = integral_0^d dd' / c(d')`` (s/m * m = s per unit ``L/dz``)."""
        d = np.asarray(depth, dtype=float)
        grid, f = self._table
        if np.any(d < -1e-9) or np.any(d > grid[-2]):
            raise ValueError(f"depth outside the profile table 0-{grid[-2]:g} m")
        d = np.clip(d, 0.0, grid[-2])
        i = np.minimum((d / _TABLE_STEP_M).astype(np.int64), grid.size - 2)
        h = _TABLE_STEP_M
        s = (d - grid[i]) / h
        m0, m1 = h / self.speed(grid[i]), h / self.speed(grid[i + 1])
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * f[i] + h10 * m0 + h01 * f[i + 1] + h11 * m1

    def mean_speed(self, depth_m: float) -> float:
        """Depth average of ``c`` over the water column ``0 .. depth_m``, m/s."""
        d = np.linspace(0.0, float(depth_m), 4001)
        c = self.speed(d)
        return float(np.sum(0.5 * (c[1:] + c[:-1])) / (d.size - 1))

    def to_dict(self) -> dict[str, Any]:
        """``{"kind": ..., **params}`` (the truth.json form)."""
        return {"kind": self.kind, **self.params}


def segment_time(
    p1: NDArray[np.float64], p2: NDArray[np.float64], profile: SoundSpeedProfile
) -> NDArray[np.float64]:
    """Straight-ray travel time between points (broadcast over leading axes), s.

    Parameters
    ----------
    p1, p2 : ndarray, shape (..., 3)
        End points, m (z <= 0).
    profile : SoundSpeedProfile
        Sound speed versus depth.

    Returns
    -------
    ndarray, shape (...)
        ``L / (d2 - d1) * (F(d2) - F(d1))``, or Gauss-Legendre quadrature of ``1/c`` over the
        segment when ``|d2 - d1|`` is under 2 m.
    """
    p1, p2 = np.broadcast_arrays(np.asarray(p1, float), np.asarray(p2, float))
    length = np.linalg.norm(p2 - p1, axis=-1)
    d1, d2 = -p1[..., 2], -p2[..., 2]
    dz = d2 - d1
    short = np.abs(dz) < _SHORT_DZ_M
    safe = np.where(short, 1.0, dz)
    mean_slow = (profile.slowness_integral(d2) - profile.slowness_integral(d1)) / safe
    if np.any(short):
        mid, half = 0.5 * (d1 + d2), 0.5 * dz
        nodes = mid[..., None] + half[..., None] * _GL_X
        gl = 0.5 * (_GL_W / profile.speed(nodes)).sum(-1)
        mean_slow = np.where(short, gl, mean_slow)
    return length * mean_slow


@dataclass(frozen=True)
class FloorPlane:
    """A plane sea floor: depth ``depth_m`` under the point ``(x0, y0)``, sloping down at
    ``slope_deg`` towards the azimuth ``azimuth_deg`` (counter-clockwise from +x).

    Attributes
    ----------
    depth_m, slope_deg, azimuth_deg, x0, y0 : float
    """

    depth_m: float
    slope_deg: float = 0.0
    azimuth_deg: float = 0.0
    x0: float = 0.0
    y0: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.depth_m) and self.depth_m > 0):
            raise ValueError(f"floor depth must be positive, got {self.depth_m!r}")
        if not (np.isfinite(self.slope_deg) and 0.0 <= self.slope_deg < 45.0):
            raise ValueError(f"floor slope must be in [0, 45) deg, got {self.slope_deg!r}")
        if not all(np.isfinite(v) for v in (self.azimuth_deg, self.x0, self.y0)):
            raise ValueError("floor azimuth and origin must be finite")

    @property
    def _grad(self) -> NDArray[np.float64]:
        """d(depth)/d(x, y): the downslope direction times tan(slope)."""
        a = np.radians(self.azimuth_deg)
        return np.tan(np.radians(self.slope_deg)) * np.array([np.cos(a), np.sin(a)])

    @property
    def normal(self) -> NDArray[np.float64]:
        """Unit normal pointing up into the water."""
        g = self._grad
        n = np.array([g[0], g[1], 1.0])  # z_floor = -(depth + g.(xy - xy0)); n = grad(z - z_floor)
        return n / np.linalg.norm(n)

    @property
    def offset(self) -> float:
        """``n . p`` for points ``p`` on the plane."""
        return float(self.normal @ np.array([self.x0, self.y0, -self.depth_m]))

    def depth_at(self, x: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
        """Floor depth under ``(x, y)``, m (positive)."""
        g = self._grad
        return self.depth_m + g[0] * (np.asarray(x, float) - self.x0) + g[1] * (
            np.asarray(y, float) - self.y0)

    def height_above(self, p: ArrayLike) -> NDArray[np.float64]:
        """Perpendicular distance of points above the plane, m (negative: below)."""
        return np.asarray(p, float) @ self.normal - self.offset

    def mirror(self, p: ArrayLike) -> NDArray[np.float64]:
        """Image of points across the plane."""
        p = np.asarray(p, float)
        return p - 2.0 * self.height_above(p)[..., None] * self.normal

    def to_dict(self) -> dict[str, float]:
        """The truth.json form."""
        return {"depth_m": self.depth_m, "slope_deg": self.slope_deg,
                "azimuth_deg": self.azimuth_deg, "x0": self.x0, "y0": self.y0,
                "normal": self.normal.tolist()}


def _reflection_point(image: NDArray[np.float64], rcv: NDArray[np.float64],
                      normal: NDArray[np.float64], offset: float) -> NDArray[np.float64]:
    """Where the line from an image source to a receiver crosses the plane ``n.p = offset``."""
    den = (rcv - image) @ normal
    t = (offset - image @ normal) / den
    return image + t[..., None] * (rcv - image)


def path_times(
    src: NDArray[np.float64],
    rcv: NDArray[np.float64],
    *,
    profile: SoundSpeedProfile | None,
    sound_speed: float,
    floor: FloorPlane | None,
) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Travel times and lengths of the direct, surface- and floor-reflected paths.

    Parameters
    ----------
    src : ndarray, shape (n, 3)
        Source positions, m.
    rcv : ndarray, shape (m, 3)
        Receiver positions, m.
    profile : SoundSpeedProfile or None
        None: straight rays at the constant `sound_speed` (time = length / c, the
        localizer's own model).
    sound_speed : float
        The constant speed used when `profile` is None, m/s.
    floor : FloorPlane or None
        The sea floor (no ``"bottom"`` path when None).

    Returns
    -------
    dict
        ``{"direct": (time, length), "surface": (...), "bottom": (...)}``, each array of
        shape (n, m). The effective speed of a path is ``length / time``. With a profile, a
        reflected path's time is the direct time plus the path difference times the reflected
        path's mean slowness (module notes).
    """
    s, r = src[:, None, :], rcv[None, :, :]
    out = {}
    mirrors = [("surface", np.array([0.0, 0.0, 1.0]), 0.0)]
    if floor is not None:
        mirrors.append(("bottom", floor.normal, floor.offset))
    direct_len = np.linalg.norm(s - r, axis=2)
    if profile is None:
        out["direct"] = (direct_len / sound_speed, direct_len)
    else:
        out["direct"] = (segment_time(s, r, profile), direct_len)
    for name, n, off in mirrors:
        image = s - 2.0 * ((s @ n) - off)[..., None] * n
        length = np.linalg.norm(image - r, axis=2)
        if profile is None:
            out[name] = (length / sound_speed, length)
        else:
            bounce = _reflection_point(np.broadcast_to(image, length.shape + (3,)),
                                       np.broadcast_to(r, length.shape + (3,)), n, off)
            if name == "surface":
                bounce[..., 2] = 0.0  # exactly on the surface (no round-off above it)
            slow = (segment_time(s, bounce, profile) + segment_time(bounce, r, profile)) / length
            out[name] = (out["direct"][0] + (length - direct_len) * slow, length)
    return out
