"""Tests of factors.angles: half-open wrapping and nearest branch."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from factors.angles import nearest_branch, wrap_angle

ANGLES = st.floats(-1e4, 1e4, allow_nan=False)


def test_just_below_minus_pi_is_not_plus_pi():
    """Regression: the angle just below -pi wraps to -pi, not to +pi (mod rounds up to 2 pi)."""
    a = np.nextafter(-np.pi, -4.0)
    assert wrap_angle(a) == -np.pi
    out = wrap_angle(np.array([a, np.pi, -np.pi, 3 * np.pi, -3 * np.pi]))
    assert np.all(out < np.pi)
    assert_allclose(out, -np.pi, atol=1e-12)


def test_known_values_and_types():
    """Known wraps; a scalar gives a float, an array an array of the same shape."""
    assert wrap_angle(0.0) == 0.0
    assert_allclose(wrap_angle(3 * np.pi / 2), -np.pi / 2, atol=1e-15)
    assert_allclose(wrap_angle(-3 * np.pi / 2), np.pi / 2, atol=1e-15)
    assert isinstance(wrap_angle(1.0), float)
    assert wrap_angle(np.zeros((2, 3))).shape == (2, 3)


@given(a=ANGLES)
@settings(max_examples=300, deadline=None)
def test_range_and_same_direction(a):
    """Every wrapped angle lies in [-pi, pi) and points the same way as the input."""
    w = wrap_angle(a)
    assert -np.pi <= w < np.pi
    assert abs(np.sin(w) - np.sin(a)) < 1e-9 and abs(np.cos(w) - np.cos(a)) < 1e-9


@given(a=ANGLES, ref=ANGLES)
@settings(max_examples=200, deadline=None)
def test_nearest_branch_within_pi_of_reference(a, ref):
    """nearest_branch keeps the direction and lands within [-pi, pi) of the reference."""
    b = nearest_branch(a, ref)
    assert -np.pi - 1e-9 <= b - ref < np.pi + 1e-9
    assert abs(np.sin(b) - np.sin(a)) < 1e-8 and abs(np.cos(b) - np.cos(a)) < 1e-8


def test_nearest_branch_across_south():
    """A bearing just east of south moves next to a reference just west of it."""
    assert_allclose(nearest_branch(-np.pi + 0.1, np.pi - 0.1), np.pi + 0.1, atol=1e-12)
    assert_allclose(nearest_branch([0.2, -0.2], [2 * np.pi, -2 * np.pi]),
                    [2 * np.pi + 0.2, -2 * np.pi - 0.2], atol=1e-12)
