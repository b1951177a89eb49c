"""Tests of factors.weighted: association-weighted factor."""

import time

import gtsam
import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.bearing import linear_bearing_factor, linear_bearing_factors
from factors.motion import linear_constant_velocity_factor, wna_covariance
from factors.target import target_bearing_batch_factor
from factors.testing import assert_jacobians
from factors.weighted import weighted_factor


def test_jacobians_many_states_and_weights(wrapped_track):
    """Jacobians of weighted bearing and motion factors (the tests' wrapped-model
    CustomFactors) equal central differences."""
    rng = np.random.default_rng(7)
    w = np.zeros(1)
    for _ in range(25):
        w[0] = rng.uniform(0.0, 1.0)
        x0 = np.array([rng.choice([-1, 1]) * np.pi * rng.uniform(0.95, 1.0), rng.normal()])
        x1 = rng.normal(size=2)
        v = gtsam.Values()
        v.insert(0, x0)
        v.insert(1, x1)
        inner_b = wrapped_track.bearing(gtsam.noiseModel.Isotropic.Sigma(1, 0.02), 0, rng.normal())
        dt = rng.uniform(0.5, 5.0)
        inner_m = wrapped_track.motion(
            gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, 0.1, 1)), 0, 1, dt)
        assert_jacobians(weighted_factor(inner_b, w, 0), v)
        assert_jacobians(weighted_factor(inner_m, w, 0), v)


def test_error_is_weight_times_inner_and_zero_at_truth(wrapped_track):
    """Cost = w * inner cost; read live from the array; zero at truth."""
    w = np.array([0.3, 0.9])
    inner = wrapped_track.bearing(gtsam.noiseModel.Isotropic.Sigma(1, 0.1), 0, 0.5)
    f = weighted_factor(inner, w, 1)
    v = gtsam.Values()
    v.insert(0, np.array([0.8, 0.0]))
    assert_allclose(f.error(v), 0.9 * inner.error(v), rtol=1e-12)
    w[1] = 0.25
    assert_allclose(f.error(v), 0.25 * inner.error(v), rtol=1e-12)
    v.update(0, np.array([0.5, 0.0]))
    assert_allclose(f.unwhitenedError(v), [0.0], atol=1e-15)


def test_graph_converges_to_weighted_mean_and_follows_updates(wrapped_track):
    """Two bearings with weights w1, w2 pull a state to their weighted mean; updating the
    weights between solves moves the solution without rebuilding the graph."""
    w = np.array([0.5, 0.5])
    noise = gtsam.noiseModel.Isotropic.Sigma(1, 0.05)
    g = gtsam.NonlinearFactorGraph()
    for i, z in enumerate((0.2, 0.6)):
        g.add(weighted_factor(wrapped_track.bearing(noise, 0, z), w, i))
    g.add(gtsam.PriorFactorVector(0, np.zeros(2), gtsam.noiseModel.Diagonal.Sigmas([1e6, 1e-3])))
    init = gtsam.Values()
    init.insert(0, np.array([0.0, 0.0]))
    for w_new in ([0.5, 0.5], [0.9, 0.1], [0.0, 1.0]):
        w[:] = w_new
        res = gtsam.LevenbergMarquardtOptimizer(g, init).optimize()
        expect = (w[0] * 0.2 + w[1] * 0.6) / w.sum()
        assert_allclose(res.atVector(0)[0], expect, atol=1e-6)


def test_bad_input(wrapped_track):
    """Non-array weights, bad index, robust inner noise and wrong wrapper noise raise."""
    inner = wrapped_track.bearing(gtsam.noiseModel.Unit.Create(1), 0, 0.1)
    with pytest.raises(ValueError, match="float64"):
        weighted_factor(inner, [1.0], 0)
    with pytest.raises(ValueError, match="out of range"):
        weighted_factor(inner, np.ones(2), 2)
    robust = gtsam.noiseModel.Robust.Create(
        gtsam.noiseModel.mEstimator.Huber.Create(1.0), gtsam.noiseModel.Unit.Create(1))
    with pytest.raises(ValueError, match="Gaussian"):
        weighted_factor(wrapped_track.bearing(robust, 0, 0.1), np.ones(1), 0)
    with pytest.raises(ValueError, match="dimension"):
        weighted_factor(inner, np.ones(1), 0, noise=gtsam.noiseModel.Unit.Create(2))


# -- fast inner factors, per-row weights, dimensions from the inner factor ------------------


def test_vector_form_weights_each_row():
    """One weight per row of a vector factor (target bearings of two states): cost =
    sum_i w_i e_i^2 / 2; Jacobians match; equal to one-row factors weighted one by one."""
    rng = np.random.default_rng(17)
    own = np.array([[0.0, 0.0], [50.0, 0.0], [100.0, 20.0], [150.0, 0.0]])
    for _ in range(15):
        x = np.column_stack([rng.uniform(-2000, 2000, (2, 2)), rng.normal(0, 3, (2, 2))])
        v = gtsam.Values()
        for k in range(2):
            v.insert(k, x[k])
        keys = [0, 0, 1, 1]
        z = rng.uniform(-np.pi, np.pi, 4)
        w = rng.uniform(0.0, 1.0, 6)
        rows = [5, 0, 3, 2]
        inner = target_bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(4, 0.02), keys, own, z)
        f = weighted_factor(inner, w, rows)
        e_w = inner.whitenedError(v)
        assert_allclose(f.error(v), 0.5 * np.sum(w[rows] * e_w**2), rtol=1e-12)
        assert_jacobians(f, v, delta=1e-4, rtol=1e-5, atol=1e-9)
        single = [weighted_factor(target_bearing_batch_factor(
                      gtsam.noiseModel.Isotropic.Sigma(1, 0.02), k, own[j:j + 1], z[j:j + 1]), w, r)
                  for j, (k, r) in enumerate(zip(keys, rows, strict=True))]
        assert_allclose(f.error(v), sum(s.error(v) for s in single), rtol=1e-12)


def test_builtin_inner_factors_and_mixed_dimensions():
    """Built-in inner factors (linear bearing, linear CV in a LinearContainerFactor) and one on a
    Pose2 and a 1-vector are wrapped with the right per-key Jacobian widths."""
    w = np.array([0.4])
    x0, x1 = np.array([np.pi - 0.01, 0.002]), np.array([-np.pi + 0.02, 0.003])
    v = gtsam.Values()
    v.insert(0, x0)
    v.insert(1, x1)
    v.insert(2, gtsam.Pose2(1.0, 2.0, 0.3))
    v.insert(3, np.array([0.5]))
    noise = gtsam.noiseModel.Isotropic.Sigma(1, 0.01)
    lin_b = linear_bearing_factor(noise, 0, -np.pi + 0.005, estimate=x0)
    cv = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(4.0, 1e-6, 1))
    lin_m = linear_constant_velocity_factor(cv, 0, 1, 4.0, estimate_prev=x0, estimate_next=x1)
    mixed = gtsam.CustomFactor(
        gtsam.noiseModel.Unit.Create(1), [2, 3],
        lambda this, vals, jac: _mixed_error(vals, jac))
    for inner in (lin_b, lin_m, mixed):
        f = weighted_factor(inner, w, 0)
        assert_allclose(f.error(v), 0.4 * inner.error(v), rtol=1e-12)
        assert_jacobians(f, v)


def _mixed_error(vals, jac):
    """x of a Pose2 plus a 1-vector; Jacobians (1, 3) and (1, 1)."""
    p, s = vals.atPose2(2), vals.atVector(3)
    if jac is not None:
        jac[0] = np.array([[np.cos(p.theta()), -np.sin(p.theta()), 0.0]])
        jac[1] = np.array([[1.0]])
    return np.array([p.x() + s[0]])


def test_first_linearisation_costs_no_more_than_later_ones():
    """Regression: the first linearisation of many weighted factors used to read the whole
    graph's zero vectors once per factor (quadratic); now it costs about a later one."""
    n = 1000
    rng = np.random.default_rng(3)
    x = np.column_stack([rng.uniform(-3, 3, n), np.zeros(n)])
    v = gtsam.Values()
    for k in range(n):
        v.insert(k, x[k])
    w = rng.uniform(0.1, 1.0, n)
    noise = gtsam.noiseModel.Isotropic.Sigma(1, 0.01)
    first, later = [], []
    for _ in range(3):  # best of three: the cores are shared
        g = gtsam.NonlinearFactorGraph()
        for k, f in enumerate(linear_bearing_factors(noise, range(n), x[:, 0] + 0.01,
                                                     estimates=x)):
            g.add(weighted_factor(f, w, k))
        t0 = time.process_time()
        lin_first = g.linearize(v)
        t1 = time.process_time()
        lin_again = g.linearize(v)
        t2 = time.process_time()
        first.append(t1 - t0)
        later.append(t2 - t1)
    assert min(first) < 3.0 * min(later) + 0.01
    assert_allclose(lin_first.jacobian()[1], lin_again.jacobian()[1], rtol=0)


def test_index_sequence_bad_input():
    """A per-row index of the wrong length or out of range raises ValueError."""
    inner = target_bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(2, 0.1), [0, 1],
                                        np.zeros((2, 2)), [0.1, 0.2])
    with pytest.raises(ValueError, match="one per row"):
        weighted_factor(inner, np.ones(3), [0, 1, 2])
    with pytest.raises(ValueError, match="out of range"):
        weighted_factor(inner, np.ones(3), [0, 3])
    with pytest.raises(ValueError, match="integer"):
        weighted_factor(inner, np.ones(3), 0.5)
