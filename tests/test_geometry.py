"""Tests of fusion.geometry: angles, cosine-spaced beams, arrays, delays."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from fusion.geometry import (
    SensorArray,
    beam_from_bearing,
    beam_rate_from_bearing_rate,
    beam_tolerance,
    beamwidth_cos,
    bearing_from_beam,
    bearing_rate_from_beam_rate,
    compass_bearing_deg,
    propagation_delay,
    tdoa,
    wrap_angle,
    wrap_deg,
)

finite = st.floats(-1e4, 1e4, allow_nan=False)


@given(finite)
def test_wrap_angle_range_and_equivalence(a):
    """Wrapped angles lie in [-pi, pi) and differ from the input by a multiple of 2 pi."""
    w = wrap_angle(a)
    assert -np.pi <= w < np.pi
    k = (a - w) / (2 * np.pi)
    assert abs(k - round(k)) < 1e-6


@given(finite)
def test_wrap_deg_range(a):
    """Wrapped degrees lie in [-180, 180) and keep sine and cosine."""
    w = wrap_deg(a)
    assert -180.0 <= w < 180.0
    assert_allclose([np.sin(np.radians(w)), np.cos(np.radians(w))],
                    [np.sin(np.radians(a)), np.cos(np.radians(a))], atol=1e-7)


def test_wrap_known_values():
    """Known answers, including the half-open end."""
    assert_allclose(wrap_angle(np.array([np.pi, -np.pi, 3 * np.pi / 2, 0.1])),
                    [-np.pi, -np.pi, -np.pi / 2, 0.1])
    assert wrap_deg(190.0) == -170.0
    assert wrap_deg(180.0) == -180.0


def test_wrap_angle_just_below_minus_pi_regression():
    """Regression: an angle one ulp below -pi wraps to -pi, not to +pi outside [-pi, pi)."""
    a = np.nextafter(-np.pi, -4.0)
    assert wrap_angle(a) == -np.pi
    many = np.nextafter(-np.pi, -4.0) - np.arange(8) * np.spacing(np.pi)  # a few ulps below
    w = wrap_angle(many)
    assert np.all((w >= -np.pi) & (w < np.pi))
    assert_allclose(np.exp(1j * w), np.exp(1j * many), atol=1e-14)  # same angle


def test_wrap_deg_just_below_minus_180_regression():
    """Regression: a degree angle one ulp below -180 wraps to -180, not to +180."""
    assert wrap_deg(np.nextafter(-180.0, -360.0)) == -180.0
    many = np.nextafter(-180.0, -360.0) - np.arange(8) * np.spacing(180.0)
    w = wrap_deg(many)
    assert np.all((w >= -180.0) & (w < 180.0))
    assert_allclose(np.exp(1j * np.radians(w)), np.exp(1j * np.radians(many)), atol=1e-14)


@given(st.floats(-1e4, 1e4, allow_nan=False).map(lambda x: np.nextafter(x, -np.inf)))
def test_wrap_angle_and_deg_half_open_everywhere(a):
    """Both wraps stay half-open for values one ulp below any float (the rounding edge)."""
    assert -np.pi <= wrap_angle(a) < np.pi
    assert -180.0 <= wrap_deg(a) < 180.0


def test_wrap_angle_is_the_factors_rule():
    """fusion.geometry and factors.angles share one wrap_angle (one rule for every residual)."""
    import factors.angles

    assert wrap_angle is factors.angles.wrap_angle


def test_beams_endfire_and_broadside():
    """Beam 0 is forward endfire, beam N-1 aft endfire, the middle beam broadside."""
    n = 65
    assert_allclose(bearing_from_beam(np.array([0, 32, 64]), n), [0, np.pi / 2, np.pi], atol=1e-12)
    assert_allclose(beam_from_bearing(np.array([0, np.pi / 2, np.pi]), n), [0, 32, 64])


def test_beam_spacing_equal_in_cosine():
    """Consecutive beams differ by 2/(N-1) in cosine."""
    n = 64
    c = np.cos(bearing_from_beam(np.arange(n), n))
    assert_allclose(np.diff(c), -2 / (n - 1), atol=1e-12)


@given(st.floats(0.2, np.pi - 0.2), st.floats(-1e-2, 1e-2))
def test_beam_rate_round_trip(theta, rate):
    """Bearing rate -> beam rate -> bearing rate is the identity beyond half a beam from endfire."""
    n = 64
    b = beam_from_bearing(theta, n)
    br = beam_rate_from_bearing_rate(theta, rate, n)
    assert_allclose(bearing_rate_from_beam_rate(b, br, n), rate, rtol=1e-9, atol=1e-15)


def test_beam_rate_matches_numerical_derivative():
    """db/dt equals the numerical derivative of b(theta(t))."""
    n, theta, rate, dt = 48, 1.1, 0.003, 1e-3
    num = (beam_from_bearing(theta + rate * dt, n) - beam_from_bearing(theta - rate * dt, n)) / (2 * dt)
    assert_allclose(beam_rate_from_bearing_rate(theta, rate, n), num, rtol=1e-6)


def test_bearing_rate_finite_at_endfire():
    """At the endfire beams the singular map stays finite."""
    assert np.isfinite(bearing_rate_from_beam_rate(0.0, 0.1, 64))
    assert np.isfinite(bearing_rate_from_beam_rate(63.0, 0.1, 64))


def test_beamwidth_and_tolerance():
    """Main lobe 0.886 lambda/L; tolerance is half of it in beams, at least 2."""
    assert_allclose(beamwidth_cos(1.5, 30.0), 0.886 * 0.05)
    # lambda/L = 0.5: half width 0.2215 in cosine = 0.2215 / (2/63) = 6.98 beams -> 6
    assert beam_tolerance(15.0, 30.0, 64) == 6
    assert beam_tolerance(1.5, 300.0, 64) == 2
    with pytest.raises(ValueError, match="positive"):
        beamwidth_cos(-1.0, 3.0)
    with pytest.raises(ValueError, match="n_beams"):
        bearing_from_beam(0, 1)


def test_compass_bearing():
    """North is 0, east 90, south 180, west 270 degrees."""
    to = np.array([[0, 1], [1, 0], [0, -1], [-1, 0]], dtype=float)
    assert_allclose(compass_bearing_deg(np.zeros(2), to), [0, 90, 180, 270])


def test_array_validation():
    """Too few sensors, NaN, collinear sensors and bad sound speeds are rejected."""
    good = np.array([[0, 0, 0], [1000, 0, 0], [0, 1000, -10.0]])
    a = SensorArray(good, 1500.0)
    assert a.n_sensors == 3 and a.ids == ("H1", "H2", "H3")
    assert a.pairs() == [(0, 1), (0, 2), (1, 2)]
    with pytest.raises(ValueError, match="at least 3"):
        SensorArray(good[:2])
    with pytest.raises(ValueError, match="NaN"):
        SensorArray(np.where(np.eye(3, dtype=bool), np.nan, good))
    with pytest.raises(ValueError, match="collinear"):
        SensorArray(np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2.0]]))
    with pytest.raises(ValueError, match="sound_speed"):
        SensorArray(good, -1.0)
    with pytest.raises(ValueError, match="unique"):
        SensorArray(good, 1500.0, ("a", "a", "b"))


def test_tdoa_known_answer_and_antisymmetry():
    """TDOAs equal range differences over c, and tau_ij = -tau_ji."""
    rng = np.random.default_rng(3)
    sensors = rng.uniform(-3000, 3000, (5, 3))
    src = rng.uniform(-2000, 2000, (7, 3))
    c = 1490.0
    pairs = [(0, 1), (1, 0), (2, 4)]
    t = tdoa(src, sensors, pairs, c)
    r = np.linalg.norm(src[:, None, :] - sensors[None], axis=-1)
    assert_allclose(t[:, 0], (r[:, 0] - r[:, 1]) / c)
    assert_allclose(t[:, 1], -t[:, 0])
    assert_allclose(t[:, 2], (r[:, 2] - r[:, 4]) / c)
    assert_allclose(propagation_delay(src[0], sensors, c), r[0] / c)
