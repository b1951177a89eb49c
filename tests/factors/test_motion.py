"""Tests of factors.motion: WNA covariance, constant-velocity factor."""

import gtsam
import numpy as np
import pytest
from filterpy.common import Q_continuous_white_noise
from numpy.testing import assert_allclose

from factors.motion import constant_velocity_factor, transition_matrix, wna_covariance
from factors.testing import assert_jacobians


def _values(*xs):
    v = gtsam.Values()
    for k, x in enumerate(xs):
        v.insert(k, np.asarray(x, float))
    return v


@pytest.mark.parametrize("dt,q", [(0.5, 2.0), (10.0, 1e-9), (3.0, 0.1)])
def test_wna_matches_filterpy(dt, q):
    """The d=1 covariance equals filterpy's continuous white-noise model."""
    assert_allclose(wna_covariance(dt, q, 1), Q_continuous_white_noise(2, dt, q), rtol=1e-12)


def test_wna_blocks_per_axis():
    """For d=2 each axis carries the d=1 block; axes are independent."""
    Q2, Q1 = wna_covariance(2.0, 0.3, 2), wna_covariance(2.0, 0.3, 1)
    assert_allclose(Q2[np.ix_([0, 2], [0, 2])], Q1)
    assert_allclose(Q2[np.ix_([1, 3], [1, 3])], Q1)
    assert Q2[0, 1] == 0.0 and Q2[0, 3] == 0.0
    assert np.all(np.linalg.eigvalsh(Q2) > 0)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_jacobians_many_states(d):
    """Analytic Jacobians equal central differences at seeded states, bearings near +-pi."""
    rng = np.random.default_rng(10 + d)
    for _ in range(25):
        dt = rng.uniform(0.1, 20.0)
        noise = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, rng.uniform(1e-6, 1.0), d))
        f = constant_velocity_factor(noise, 0, 1, dt)
        x0 = rng.normal(size=2 * d)
        x0[:d] = rng.choice([-1, 1]) * np.pi * rng.uniform(0.97, 1.0, d)
        x1 = rng.normal(size=2 * d)
        assert_jacobians(f, _values(x0, x1))


def test_error_and_wrap():
    """Zero error on the CV prediction; the bearing part wraps across +-180 deg for d=1."""
    dt = 4.0
    f = constant_velocity_factor(gtsam.noiseModel.Unit.Create(2), 0, 1, dt)
    x0 = np.array([np.pi - 0.01, 0.005])
    x1 = transition_matrix(dt, 1) @ x0
    assert_allclose(f.unwhitenedError(_values(x0, x1)), 0.0, atol=1e-15)
    x1w = x1 - np.array([2 * np.pi, 0.0])  # same bearing on the other branch
    assert_allclose(f.unwhitenedError(_values(x0, x1w)), 0.0, atol=1e-12)
    f2 = constant_velocity_factor(gtsam.noiseModel.Unit.Create(4), 0, 1, dt)
    err = f2.unwhitenedError(_values(np.zeros(4), np.array([7.0, 0, 0, 0])))
    assert_allclose(err, [7.0, 0, 0, 0])  # no wrapping for positions


def test_graph_converges_to_truth():
    """Prior + CV chain + noise-free position priors recover the true 2-D trajectory."""
    dt, n = 2.0, 8
    truth = [np.array([1.0, -2.0, 0.3, 0.7])]
    F = transition_matrix(dt, 2)
    for _ in range(n - 1):
        truth.append(F @ truth[-1])
    g = gtsam.NonlinearFactorGraph()
    noise = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, 0.01, 2))
    for k in range(n - 1):
        g.add(constant_velocity_factor(noise, k, k + 1, dt))
    for k in (0, n - 1):
        g.add(gtsam.PriorFactorVector(k, truth[k], gtsam.noiseModel.Isotropic.Sigma(4, 1e-3)))
    init = gtsam.Values()
    for k in range(n):
        init.insert(k, np.zeros(4))
    res = gtsam.LevenbergMarquardtOptimizer(g, init).optimize()
    for k in range(n):
        assert_allclose(res.atVector(k), truth[k], atol=1e-6)


def test_bad_input():
    """Bad dt, q, d or noise dimension raise ValueError."""
    with pytest.raises(ValueError, match="dt"):
        wna_covariance(0.0, 1.0, 1)
    with pytest.raises(ValueError, match="q"):
        wna_covariance(1.0, -1.0, 1)
    with pytest.raises(ValueError, match="d "):
        wna_covariance(1.0, 1.0, 0)
    with pytest.raises(ValueError, match="even"):
        constant_velocity_factor(gtsam.noiseModel.Unit.Create(3), 0, 1, 1.0)
    with pytest.raises(ValueError, match="dt"):
        constant_velocity_factor(gtsam.noiseModel.Unit.Create(2), 0, 1, np.nan)
