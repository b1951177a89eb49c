"""Tests of factors.bearing: wrapped bearing measurement factor."""

import gtsam
import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.bearing import bearing_factor
from factors.motion import constant_velocity_factor, wna_covariance
from factors.testing import assert_jacobians


def _v(x):
    v = gtsam.Values()
    v.insert(0, np.asarray(x, float))
    return v


def test_jacobians_many_states():
    """Jacobian equals central differences at seeded states, many near +-180 deg."""
    rng = np.random.default_rng(5)
    noise = gtsam.noiseModel.Isotropic.Sigma(1, 0.01)
    for i in range(40):
        n = 1 + i % 3
        x = rng.normal(size=n)
        z = rng.uniform(-np.pi, np.pi)
        if i % 2:
            x[0] = np.pi - rng.uniform(0.0, 0.05)
            z = -np.pi + rng.uniform(0.0, 0.05)
        assert_jacobians(bearing_factor(noise, 0, z), _v(x))


def test_error_wrapped_and_zero_at_truth():
    """Zero error at the true bearing (any branch); a 0.02 rad gap across +-pi stays 0.02."""
    f = bearing_factor(gtsam.noiseModel.Unit.Create(1), 0, 0.4)
    assert_allclose(f.unwhitenedError(_v([0.4, 1.0])), [0.0], atol=1e-15)
    assert_allclose(f.unwhitenedError(_v([0.4 + 2 * np.pi, 1.0])), [0.0], atol=1e-12)
    g = bearing_factor(gtsam.noiseModel.Unit.Create(1), 0, np.pi - 0.01)
    assert_allclose(g.unwhitenedError(_v([-np.pi + 0.01])), [0.02], atol=1e-12)


def test_graph_converges_across_south():
    """A constant-rate track crossing +-180 deg is recovered from noise-free bearings."""
    dt, rate, n = 5.0, 0.004, 20
    theta = np.pi - 0.03 + rate * dt * np.arange(n)
    g = gtsam.NonlinearFactorGraph()
    motion = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, 1e-8, 1))
    meas = gtsam.noiseModel.Isotropic.Sigma(1, 0.01)
    init = gtsam.Values()
    for k in range(n):
        g.add(bearing_factor(meas, k, float(np.mod(theta[k] + np.pi, 2 * np.pi) - np.pi)))
        if k:
            g.add(constant_velocity_factor(motion, k - 1, k, dt))
        init.insert(k, np.array([theta[0], 0.0]))
    res = gtsam.LevenbergMarquardtOptimizer(g, init).optimize()
    est = np.array([res.atVector(k) for k in range(n)])
    assert_allclose(np.angle(np.exp(1j * (est[:, 0] - theta))), 0.0, atol=1e-6)
    assert_allclose(est[:, 1], rate, atol=1e-7)


def test_bad_input():
    """Wrong noise dimension or a non-finite bearing raise ValueError."""
    with pytest.raises(ValueError, match="1-dimensional"):
        bearing_factor(gtsam.noiseModel.Unit.Create(2), 0, 0.1)
    with pytest.raises(ValueError, match="finite"):
        bearing_factor(gtsam.noiseModel.Unit.Create(1), 0, np.inf)
