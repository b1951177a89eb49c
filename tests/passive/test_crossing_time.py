"""Tests of fusion.passive.crossing.timing: equation (2), the one crossing-time equation."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.passive.crossing.pairs import pairs_in_reach
from fusion.passive.crossing.timing import crossing_time, crossing_time_terms


def test_known_answers():
    """t_c = (B0_b - B0_a)/(B'_a - B'_b): converging, diverging (negative) and parallel tracks."""
    assert crossing_time(0.0, 0.01, 0.1, 0.0) == pytest.approx(10.0)
    assert crossing_time(0.0, -0.01, 0.1, 0.0) == pytest.approx(-10.0)
    assert crossing_time(0.3, 0.002, 0.3, -0.002) == 0.0
    assert crossing_time(0.0, 0.01, 0.1, 0.01) == np.inf


def test_bearing_difference_is_wrapped():
    """Tracks either side of +-180 deg meet across the wrap; branches of a bearing do not matter."""
    assert crossing_time(np.pi - 0.05, 0.01, -np.pi + 0.05, 0.0) == pytest.approx(10.0)
    assert crossing_time(0.2 + 4 * np.pi, 0.01, 0.3 - 2 * np.pi, 0.0) == pytest.approx(10.0)
    num, _ = crossing_time_terms(np.pi, 0.0, -np.pi, 0.0)  # difference -2 pi wraps to 0
    assert num == 0.0


def test_broadcasts_and_returns_float_for_scalars():
    """Array inputs broadcast elementwise; scalar inputs give a Python float."""
    tc = crossing_time(np.zeros(3), np.array([0.01, 0.02, 0.0]), 0.1, 0.0)
    assert_allclose(tc, [10.0, 5.0, np.inf])
    assert isinstance(crossing_time(0.0, 0.01, 0.1, 0.0), float)


def test_agrees_with_the_detector_pair_screening():
    """The crossing detector's all-pairs screening gives the same t_c for every pair it keeps."""
    rng = np.random.default_rng(3)
    b = rng.uniform(-3 * np.pi, 3 * np.pi, 40)
    r = rng.normal(0.0, 1e-3, 40)
    ia, ib, tau = pairs_in_reach(b, r, reach_s=1e7, min_rate_diff_rad_per_s=0.0)
    assert ia.size == 40 * 39 // 2
    assert_allclose(tau, crossing_time(b[ia], r[ia], b[ib], r[ib]), rtol=1e-9, atol=1e-6)


def test_smoothing_reexports_the_same_function():
    """fusion.passive.smoothing.crossing_time is this module's function (no second copy)."""
    import fusion.passive.smoothing as smoothing

    assert smoothing.crossing_time is crossing_time
