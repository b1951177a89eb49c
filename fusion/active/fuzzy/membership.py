"""Membership functions: vectorised fuzzy sets on the real line, as frozen dataclasses.

The sets of "Target tracking using fuzzy logic association" (Section 5, "Membership
functions"): triangles, trapezoids and shoulders (piecewise linear, so the centroid of
:mod:`fusion.active.fuzzy.centroid` is exact), plus smooth Gaussian and sigmoid sets. Each is a
frozen dataclass that acts as a numpy function and round-trips through
:meth:`MembershipFunction.to_dict` / :func:`membership_from_dict`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Gaussian",
    "LeftShoulder",
    "MembershipFunction",
    "RightShoulder",
    "Sigmoid",
    "Trapezoidal",
    "Triangular",
    "membership_from_dict",
]


def _finite(name: str, **values: float) -> dict[str, float]:
    out = {}
    for key, value in values.items():
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
            raise ValueError(f"{name}: parameter {key} must be a number, got {value!r}")
        if not math.isfinite(float(value)):
            raise ValueError(f"{name}: parameter {key} must be finite, got {value!r}")
        out[key] = float(value)
    return out


def _ordered(name: str, **values: float) -> None:
    keys = list(values)
    for left, right in zip(keys[:-1], keys[1:], strict=True):
        if values[left] > values[right]:
            raise ValueError(
                f"{name}: parameters must satisfy {' <= '.join(keys)}, "
                f"got {', '.join(f'{k}={values[k]:g}' for k in keys)}"
            )


def _rise(x: NDArray[np.float64], a: float, b: float) -> NDArray[np.float64]:
    """0 below ``a``, 1 above ``b``, linear between (a step at ``a`` if a == b)."""
    if b > a:
        return np.clip((x - a) / (b - a), 0.0, 1.0)
    return np.where(x >= a, 1.0, np.where(np.isnan(x), np.nan, 0.0))


def _fall(x: NDArray[np.float64], c: float, d: float) -> NDArray[np.float64]:
    """1 below ``c``, 0 above ``d``, linear between (a step at ``d`` if c == d)."""
    if d > c:
        return np.clip((d - x) / (d - c), 0.0, 1.0)
    return np.where(x <= d, 1.0, np.where(np.isnan(x), np.nan, 0.0))


class MembershipFunction(ABC):
    """A fuzzy set on the real line: a vectorised map x -> mu(x) in [0, 1].

    Subclasses are frozen dataclasses; calling one on an array of any shape
    returns an array of the same shape (float64). ``+-inf`` inputs give the
    limit values; NaN propagates.
    """

    kind: ClassVar[str]

    @abstractmethod
    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        """Degree of membership of ``x``, same shape, in [0, 1]."""

    def knots(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float] | None:
        """Piecewise-linear description, or None for a smooth function.

        Returns
        -------
        tuple or None
            ``(xs, ys, left, right)``: knot abscissae (k,) non-decreasing
            (a repeated abscissa is a vertical edge), knot values (k,), and
            the constant values left of ``xs[0]`` and right of ``xs[-1]``.
        """
        return None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description ``{"type": kind, <parameters>}``."""
        return {"type": self.kind, **{f.name: getattr(self, f.name) for f in fields(self)}}


@dataclass(frozen=True)
class Triangular(MembershipFunction):
    """Triangle: 0 at ``a``, 1 at ``b``, 0 at ``c``; 0 outside [a, c].

    Parameters
    ----------
    a, b, c : float
        Feet and peak, ``a <= b <= c``, ``a < c``. ``a == b`` (or
        ``b == c``) gives a vertical left (right) edge, as in
        ``skfuzzy.trimf``.

    Examples
    --------
    >>> float(Triangular(0.0, 1.0, 3.0)(2.0))
    0.5
    """

    a: float
    b: float
    c: float
    kind: ClassVar[str] = "triangular"

    def __post_init__(self) -> None:
        values = _finite("triangular", a=self.a, b=self.b, c=self.c)
        _ordered("triangular", **values)
        if values["a"] == values["c"]:
            raise ValueError("triangular: needs a < c (zero width)")
        for key, value in values.items():
            object.__setattr__(self, key, value)

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        x = np.asarray(x, dtype=float)
        return np.minimum(_rise(x, self.a, self.b), _fall(x, self.b, self.c))

    def knots(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
        return np.array([self.a, self.b, self.c]), np.array([0.0, 1.0, 0.0]), 0.0, 0.0


@dataclass(frozen=True)
class Trapezoidal(MembershipFunction):
    """Trapezoid: 0 below ``a``, up to 1 at ``b``, 1 until ``c``, 0 from ``d``.

    Parameters
    ----------
    a, b, c, d : float
        ``a <= b <= c <= d`` and ``a < d``. The paper's "specular" aspect set
        is ``Trapezoidal(60, 80, 100, 120)`` in degrees (Section 5, Figure 3).

    Examples
    --------
    >>> float(Trapezoidal(60.0, 80.0, 100.0, 120.0)(70.0))
    0.5
    """

    a: float
    b: float
    c: float
    d: float
    kind: ClassVar[str] = "trapezoidal"

    def __post_init__(self) -> None:
        values = _finite("trapezoidal", a=self.a, b=self.b, c=self.c, d=self.d)
        _ordered("trapezoidal", **values)
        if values["a"] == values["d"]:
            raise ValueError("trapezoidal: needs a < d (zero width)")
        for key, value in values.items():
            object.__setattr__(self, key, value)

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        x = np.asarray(x, dtype=float)
        return np.minimum(_rise(x, self.a, self.b), _fall(x, self.c, self.d))

    def knots(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
        xs = np.array([self.a, self.b, self.c, self.d])
        return xs, np.array([0.0, 1.0, 1.0, 0.0]), 0.0, 0.0


@dataclass(frozen=True)
class LeftShoulder(MembershipFunction):
    """Left shoulder: 1 at and below ``a``, falling linearly to 0 at ``b``.

    Parameters
    ----------
    a, b : float
        ``a <= b`` (``a == b`` is a step down at ``a``).

    Examples
    --------
    >>> float(LeftShoulder(100.0, 500.0)(300.0))
    0.5
    """

    a: float
    b: float
    kind: ClassVar[str] = "left_shoulder"

    def __post_init__(self) -> None:
        values = _finite("left_shoulder", a=self.a, b=self.b)
        _ordered("left_shoulder", **values)
        for key, value in values.items():
            object.__setattr__(self, key, value)

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        return _fall(np.asarray(x, dtype=float), self.a, self.b)

    def knots(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
        return np.array([self.a, self.b]), np.array([1.0, 0.0]), 1.0, 0.0


@dataclass(frozen=True)
class RightShoulder(MembershipFunction):
    """Right shoulder: 0 at and below ``a``, rising linearly to 1 at ``b``.

    Parameters
    ----------
    a, b : float
        ``a <= b`` (``a == b`` is a step up at ``a``).

    Examples
    --------
    >>> float(RightShoulder(12.0, 20.0)(16.0))
    0.5
    """

    a: float
    b: float
    kind: ClassVar[str] = "right_shoulder"

    def __post_init__(self) -> None:
        values = _finite("right_shoulder", a=self.a, b=self.b)
        _ordered("right_shoulder", **values)
        for key, value in values.items():
            object.__setattr__(self, key, value)

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        return _rise(np.asarray(x, dtype=float), self.a, self.b)

    def knots(self) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
        return np.array([self.a, self.b]), np.array([0.0, 1.0]), 0.0, 1.0


@dataclass(frozen=True)
class Gaussian(MembershipFunction):
    """Gaussian bell ``exp(-(x - mean)^2 / (2 sigma^2))``.

    Parameters
    ----------
    mean : float
        Centre (value 1).
    sigma : float
        Width, > 0.

    Examples
    --------
    >>> round(float(Gaussian(0.0, 1.0)(1.0)), 4)
    0.6065
    """

    mean: float
    sigma: float
    kind: ClassVar[str] = "gaussian"

    def __post_init__(self) -> None:
        values = _finite("gaussian", mean=self.mean, sigma=self.sigma)
        if values["sigma"] <= 0.0:
            raise ValueError(f"gaussian: sigma must be > 0, got {values['sigma']:g}")
        for key, value in values.items():
            object.__setattr__(self, key, value)

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        z = (np.asarray(x, dtype=float) - self.mean) / self.sigma
        return np.exp(-0.5 * z * z)


@dataclass(frozen=True)
class Sigmoid(MembershipFunction):
    """Logistic ``1 / (1 + exp(-slope (x - center)))``.

    Parameters
    ----------
    center : float
        Value 0.5 here.
    slope : float
        Non-zero; positive rises with x, negative falls (1/units of x).

    Examples
    --------
    >>> float(Sigmoid(2.0, 3.0)(2.0))
    0.5
    """

    center: float
    slope: float
    kind: ClassVar[str] = "sigmoid"

    def __post_init__(self) -> None:
        values = _finite("sigmoid", center=self.center, slope=self.slope)
        if values["slope"] == 0.0:
            raise ValueError("sigmoid: slope must be non-zero")
        for key, value in values.items():
            object.__setattr__(self, key, value)

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        z = self.slope * (np.asarray(x, dtype=float) - self.center)
        # 0.5 * (1 + tanh(z / 2)) == 1 / (1 + exp(-z)), without overflow.
        return 0.5 * (1.0 + np.tanh(0.5 * z))


_MEMBERSHIP_TYPES: dict[str, type[MembershipFunction]] = {
    cls.kind: cls
    for cls in (Triangular, Trapezoidal, LeftShoulder, RightShoulder, Gaussian, Sigmoid)
}


def membership_from_dict(data: Mapping[str, Any]) -> MembershipFunction:
    """Build a membership function from ``{"type": kind, <parameters>}``.

    Parameters
    ----------
    data : mapping
        ``type`` one of triangular, trapezoidal, left_shoulder,
        right_shoulder, gaussian, sigmoid, and exactly that type's parameters.

    Returns
    -------
    MembershipFunction

    Raises
    ------
    ValueError
        Unknown type, missing or extra parameters, invalid values.
    """
    if not isinstance(data, Mapping):
        raise ValueError(f"membership function must be an object, got {data!r}")
    kind = data.get("type")
    if kind not in _MEMBERSHIP_TYPES:
        raise ValueError(
            f"unknown membership function type {kind!r} "
            f"(expected one of {', '.join(sorted(_MEMBERSHIP_TYPES))})"
        )
    cls = _MEMBERSHIP_TYPES[kind]
    expected = {f.name for f in fields(cls)}
    given = set(data) - {"type"}
    if given != expected:
        raise ValueError(
            f"{kind}: expected parameters {sorted(expected)}, got {sorted(given)}"
        )
    return cls(**{key: data[key] for key in expected})
