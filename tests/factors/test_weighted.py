"""Tests of factors.weighted: association-weighted factor."""

import gtsam
import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.bearing import bearing_factor
from factors.motion import constant_velocity_factor, wna_covariance
from factors.testing import assert_jacobians
from factors.weighted import weighted_factor


def test_jacobians_many_states_and_weights():
    """Jacobians of weighted bearing and motion factors equal central differences."""
    rng = np.random.default_rng(7)
    w = np.zeros(1)
    for _ in range(25):
        w[0] = rng.uniform(0.0, 1.0)
        x0 = np.array([rng.choice([-1, 1]) * np.pi * rng.uniform(0.95, 1.0), rng.normal()])
        x1 = rng.normal(size=2)
        v = gtsam.Values()
        v.insert(0, x0)
        v.insert(1, x1)
        inner_b = bearing_factor(gtsam.noiseModel.Isotropic.Sigma(1, 0.02), 0, rng.normal())
        dt = rng.uniform(0.5, 5.0)
        inner_m = constant_velocity_factor(
            gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, 0.1, 1)), 0, 1, dt)
        assert_jacobians(weighted_factor(inner_b, w, 0), v)
        assert_jacobians(weighted_factor(inner_m, w, 0), v)


def test_error_is_weight_times_inner_and_zero_at_truth():
    """Cost = w * inner cost; read live from the array; zero at truth."""
    w = np.array([0.3, 0.9])
    inner = bearing_factor(gtsam.noiseModel.Isotropic.Sigma(1, 0.1), 0, 0.5)
    f = weighted_factor(inner, w, 1)
    v = gtsam.Values()
    v.insert(0, np.array([0.8, 0.0]))
    assert_allclose(f.error(v), 0.9 * inner.error(v), rtol=1e-12)
    w[1] = 0.25
    assert_allclose(f.error(v), 0.25 * inner.error(v), rtol=1e-12)
    v.update(0, np.array([0.5, 0.0]))
    assert_allclose(f.unwhitenedError(v), [0.0], atol=1e-15)


def test_graph_converges_to_weighted_mean_and_follows_updates():
    """Two bearings with weights w1, w2 pull a state to their weighted mean; updating the
    weights between solves moves the solution without rebuilding the graph."""
    w = np.array([0.5, 0.5])
    noise = gtsam.noiseModel.Isotropic.Sigma(1, 0.05)
    g = gtsam.NonlinearFactorGraph()
    for i, z in enumerate((0.2, 0.6)):
        g.add(weighted_factor(bearing_factor(noise, 0, z), w, i))
    g.add(gtsam.PriorFactorVector(0, np.zeros(2), gtsam.noiseModel.Diagonal.Sigmas([1e6, 1e-3])))
    init = gtsam.Values()
    init.insert(0, np.array([0.0, 0.0]))
    for w_new in ([0.5, 0.5], [0.9, 0.1], [0.0, 1.0]):
        w[:] = w_new
        res = gtsam.LevenbergMarquardtOptimizer(g, init).optimize()
        expect = (w[0] * 0.2 + w[1] * 0.6) / w.sum()
        assert_allclose(res.atVector(0)[0], expect, atol=1e-6)


def test_bad_input():
    """Non-array weights, bad index, robust inner noise and wrong wrapper noise raise."""
    inner = bearing_factor(gtsam.noiseModel.Unit.Create(1), 0, 0.1)
    with pytest.raises(ValueError, match="float64"):
        weighted_factor(inner, [1.0], 0)
    with pytest.raises(ValueError, match="out of range"):
        weighted_factor(inner, np.ones(2), 2)
    robust = gtsam.noiseModel.Robust.Create(
        gtsam.noiseModel.mEstimator.Huber.Create(1.0), gtsam.noiseModel.Unit.Create(1))
    with pytest.raises(ValueError, match="Gaussian"):
        weighted_factor(bearing_factor(robust, 0, 0.1), np.ones(1), 0)
    with pytest.raises(ValueError, match="dimension"):
        weighted_factor(inner, np.ones(1), 0, noise=gtsam.noiseModel.Unit.Create(2))
