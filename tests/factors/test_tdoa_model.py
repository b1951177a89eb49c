"""Tests of factors.tdoa.model: the TDOA measurement model and its checks."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from factors.tdoa.model import TdoaModel, predicted_tdoas

_coord = st.floats(-2000.0, 2000.0, allow_nan=False)
_point = st.tuples(_coord, _coord, _coord)


def test_known_answer_on_a_line():
    """A source 300 m from sensor 0 and 700 m from sensor 1 on a line: tau = -400 m / c."""
    s = np.array([[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0]])
    assert_allclose(predicted_tdoas([300.0, 0.0, 0.0], s, [[0, 1]], c=1600.0), [-0.25], rtol=1e-15)
    b = np.array([1e-3, -2e-3])  # arrival_i + b_i - (arrival_j + b_j)
    assert_allclose(predicted_tdoas([300.0, 0.0, 0.0], s, [[0, 1]], c=1600.0, clock_offsets=b),
                    [-0.25 + 3e-3], rtol=1e-14)


def test_vectorised_over_positions_matches_loop():
    """Positions of shape (4, 5, 3) give (4, 5, m) equal to one-at-a-time evaluation."""
    rng = np.random.default_rng(3)
    s = rng.uniform(-500, 500, size=(5, 3))
    pairs = np.array([(i, j) for i in range(5) for j in range(i + 1, 5)])
    p = rng.uniform(-1000, 1000, size=(4, 5, 3))
    grid = predicted_tdoas(p, s, pairs, c=1490.0)
    assert grid.shape == (4, 5, 10)
    for a in range(4):
        for k in range(5):
            d = np.linalg.norm(p[a, k] - s, axis=1)
            assert_allclose(grid[a, k], (d[pairs[:, 0]] - d[pairs[:, 1]]) / 1490.0, rtol=1e-13)


@settings(max_examples=50, deadline=None)
@given(_point, _point, _point, st.floats(1400.0, 1600.0))
def test_swapping_a_pair_negates_its_tdoa(p, s0, s1, c):
    """TDOA(i, j) = -TDOA(j, i), and the residual of the swapped pair with -tau is -r."""
    s = np.array([s0, s1])
    tau = predicted_tdoas(p, s, [[0, 1], [1, 0]], c=c)
    assert tau[0] == -tau[1]
    model = TdoaModel.build(s, [[0, 1], [1, 0]], [1e-3, -1e-3])
    r, _, _ = model.residual(np.asarray(p), c)
    assert r[0] == -r[1]


def test_residual_and_jacobian_at_a_known_point():
    """p = (300, 400, 0), sensors at 0 and (600, 0, 0): equal ranges, u = (0.6, 0.8, 0), (-0.6, 0.8, 0)."""
    model = TdoaModel.build([[0, 0, 0], [600, 0, 0]], [[0, 1]], [2e-4])
    r, h_p, h_c = model.residual(np.array([300.0, 400.0, 0.0]), 1500.0, jacobian=True)
    assert_allclose(r, [-2e-4], atol=1e-18)
    assert_allclose(h_p, [[1.2 / 1500.0, 0.0, 0.0]], atol=1e-18)
    assert_allclose(h_c, [[0.0]], atol=1e-18)
    assert_allclose(model.incidence, [[1.0, -1.0]])


def test_source_on_a_sensor_has_finite_jacobian():
    """Exactly on a sensor the unit vector is taken as zero: no NaN."""
    model = TdoaModel.build([[0, 0, 0], [100, 0, 0]], [[0, 1]], [0.0])
    _, h_p, _ = model.residual(np.zeros(3), 1500.0, jacobian=True)
    assert_allclose(h_p, [[1.0 / 1500.0, 0.0, 0.0]], rtol=1e-15)


def test_bad_input():
    """Malformed sensors, pairs, taus, speed and positions raise ValueError naming the problem."""
    s = np.zeros((3, 3))
    s[1, 0] = s[2, 1] = 1.0
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        TdoaModel.build(np.zeros((3, 2)), [[0, 1]], [0.0])
    with pytest.raises(ValueError, match="finite"):
        TdoaModel.build(np.full((2, 3), np.nan), [[0, 1]], [0.0])
    with pytest.raises(ValueError, match="integer"):
        TdoaModel.build(s, [[0.0, 1.0]], [0.0])
    with pytest.raises(ValueError, match=r"\[0, 3\)"):
        TdoaModel.build(s, [[0, 3]], [0.0])
    with pytest.raises(ValueError, match="different sensors"):
        TdoaModel.build(s, [[1, 1]], [0.0])
    with pytest.raises(ValueError, match="match the pairs"):
        TdoaModel.build(s, [[0, 1], [0, 2]], [0.0])
    with pytest.raises(ValueError, match="taus must be finite"):
        TdoaModel.build(s, [[0, 1]], [np.inf])
    with pytest.raises(ValueError, match="positive"):
        predicted_tdoas([0, 0, 0], s, [[0, 1]], c=-1.0)
    with pytest.raises(ValueError, match="number"):
        predicted_tdoas([0, 0, 0], s, [[0, 1]], c=None)
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        predicted_tdoas([0, 0], s, [[0, 1]], c=1500.0)
    with pytest.raises(ValueError, match="clock_offsets"):
        predicted_tdoas([0, 0, 0], s, [[0, 1]], c=1500.0, clock_offsets=[0.0])
