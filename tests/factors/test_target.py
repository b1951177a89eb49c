"""Tests of the bearing factor on a constant-velocity target state (factors.target)."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from factors.target import target_bearing, target_bearing_factor, target_bearing_jacobian
from factors.testing import assert_jacobians
from fusion.geometry import compass_bearing_deg

SIGMA = np.radians(1.0)


def _noise(sigma: float = SIGMA) -> gtsam.noiseModel.Base:
    return gtsam.noiseModel.Isotropic.Sigma(1, sigma)


def _values(key: int, state: np.ndarray) -> gtsam.Values:
    v = gtsam.Values()
    v.insert(key, np.asarray(state, dtype=float))
    return v


def _random_geometry(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float]:
    own = rng.uniform(-5000, 5000, 2)
    rng_m = rng.uniform(50.0, 20000.0)
    theta = rng.uniform(-np.pi, np.pi)
    dt = float(rng.choice([0.0, rng.uniform(-600, 600)]))
    vel = rng.uniform(-10, 10, 2)
    # position at the bearing time = own + range * (sin, cos); state epoch is dt earlier
    pos = own + rng_m * np.array([np.sin(theta), np.cos(theta)]) - vel * dt
    return np.concatenate([pos, vel]), own, dt


def test_jacobian_matches_central_differences_random_geometries():
    """Analytic Jacobian equals central differences at 60 seeded geometries (with and without dt)."""
    rng = np.random.default_rng(11)
    for _ in range(60):
        state, own, dt = _random_geometry(rng)
        z = float(target_bearing(state, own, dt=dt)) + rng.normal(0, 0.05)
        f = target_bearing_factor(_noise(), 7, own, z, dt=dt)
        assert_jacobians(f, _values(7, state), delta=1e-4, rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_jacobian_and_error_target_due_south(side):
    """Target due south (bearing near ±180 deg): wrapped error is small, Jacobian still exact."""
    own = np.array([100.0, 200.0])
    state = np.array([100.0 + side * 1e-3, 200.0 - 3000.0, 1.0, -2.0])
    beta = float(target_bearing(state, own))
    assert abs(abs(beta) - np.pi) < 1e-5
    z = -side * (np.pi - 1e-4)  # measured on the other side of the ±180 deg cut
    f = target_bearing_factor(_noise(), 1, own, z)
    err = f.unwhitenedError(_values(1, state))
    assert abs(err[0]) < 2e-4
    assert_jacobians(f, _values(1, state), delta=1e-4, rtol=1e-5, atol=1e-9)


def test_zero_error_at_truth():
    """The factor's error vanishes when the bearing is the true one (also due south, dt != 0)."""
    rng = np.random.default_rng(3)
    for _ in range(40):
        state, own, dt = _random_geometry(rng)
        z = float(target_bearing(state, own, dt=dt))
        f = target_bearing_factor(_noise(), 2, own, z, dt=dt)
        assert_allclose(f.unwhitenedError(_values(2, state)), [0.0], atol=1e-12)


def test_bearing_agrees_with_compass_bearing():
    """target_bearing equals geometry.compass_bearing_deg (an independent implementation)."""
    rng = np.random.default_rng(5)
    states = np.column_stack([rng.uniform(-1e4, 1e4, (50, 2)), rng.uniform(-5, 5, (50, 2))])
    own = rng.uniform(-1e4, 1e4, (50, 2))
    ours = np.degrees(target_bearing(states, own))
    ref = np.array([compass_bearing_deg(o, s[:2]) for o, s in zip(own, states, strict=True)])
    diff = (ours - ref + 180.0) % 360.0 - 180.0
    assert_allclose(diff, 0.0, atol=1e-9)


def test_vectorised_jacobian_matches_factor_jacobian():
    """target_bearing_jacobian equals the (unwhitened) Jacobian the factor hands to GTSAM."""
    rng = np.random.default_rng(8)
    for _ in range(10):
        state, own, dt = _random_geometry(rng)
        f = target_bearing_factor(_noise(1.0), 0, own, 0.3, dt=dt)
        A = f.linearize(_values(0, state)).jacobian()[0]
        assert_allclose(A[0], target_bearing_jacobian(state, own, dt=dt), rtol=1e-12)


def test_small_graph_converges_to_truth():
    """One CV state seen from a manoeuvring platform converges from a poor guess to the truth."""
    truth = np.array([3000.0, 4000.0, -4.0, 1.5])
    t = np.arange(0.0, 1200.0, 30.0)
    own = np.column_stack([np.where(t < 600, 0.0, 5.0 * (t - 600)), 5.0 * np.minimum(t, 600)])
    z = target_bearing(truth, own, dt=t)
    key = gtsam.symbol("s", 0)
    graph = gtsam.NonlinearFactorGraph()
    for k in range(t.size):
        graph.add(target_bearing_factor(_noise(), key, own[k], float(z[k]), dt=float(t[k])))
    init = _values(key, [2000.0, 2000.0, 0.0, 0.0])
    sol = gtsam.LevenbergMarquardtOptimizer(graph, init).optimize()
    assert_allclose(sol.atVector(key), truth, rtol=1e-6, atol=1e-5)
    assert graph.error(sol) < 1e-12


@given(
    x=st.floats(-1e5, 1e5), y=st.floats(-1e5, 1e5), z=st.floats(-20.0, 20.0),
)
@settings(max_examples=60, deadline=None)
def test_error_is_wrapped(x, y, z):
    """Whatever the state and measurement, the error lies in [-pi, pi)."""
    f = target_bearing_factor(_noise(), 0, [0.0, 0.0], z)
    e = f.unwhitenedError(_values(0, [x, y, 0.0, 0.0]))[0]
    assert -np.pi <= e < np.pi


def test_bad_input_raises():
    """Wrong noise dimension, bad platform position and non-finite bearing are ValueErrors."""
    with pytest.raises(ValueError, match="dimension must be 1"):
        target_bearing_factor(gtsam.noiseModel.Isotropic.Sigma(2, 0.1), 0, [0, 0], 0.0)
    with pytest.raises(ValueError, match="platform_xy"):
        target_bearing_factor(_noise(), 0, [0.0, 0.0, 1.0], 0.0)
    with pytest.raises(ValueError, match="bearing must be finite"):
        target_bearing_factor(_noise(), 0, [0.0, 0.0], float("nan"))
    with pytest.raises(ValueError, match="dt must be finite"):
        target_bearing_factor(_noise(), 0, [0.0, 0.0], 0.1, dt=float("inf"))
