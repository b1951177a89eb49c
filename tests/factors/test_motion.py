"""Tests of factors.motion: WNA covariance, the linear constant-velocity factors."""

import gtsam
import numpy as np
import pytest
from filterpy.common import Q_continuous_white_noise
from numpy.testing import assert_allclose

from factors.motion import (
    constant_velocity_chain,
    constant_velocity_steps,
    linear_constant_velocity_factor,
    transition_matrix,
    wna_covariance,
    wna_sqrt_information,
)
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


def test_error_and_wrap():
    """Zero error on the CV prediction; the bearing part wraps across +-180 deg for d=1."""
    dt = 4.0
    unit2, unit4 = gtsam.noiseModel.Unit.Create(2), gtsam.noiseModel.Unit.Create(4)
    x0 = np.array([np.pi - 0.01, 0.005])
    x1 = transition_matrix(dt, 1) @ x0
    x1w = x1 - np.array([2 * np.pi, 0.0])  # same bearing on the other branch
    for nxt in (x1, x1w):
        f = linear_constant_velocity_factor(unit2, 0, 1, dt, estimate_prev=x0, estimate_next=nxt)
        assert f.error(_values(x0, nxt)) < 1e-24
    far = np.array([7.0, 0, 0, 0])
    f2 = linear_constant_velocity_factor(unit4, 0, 1, dt, estimate_prev=np.zeros(4),
                                         estimate_next=far)
    assert_allclose(f2.error(_values(np.zeros(4), far)), 0.5 * 7.0**2)  # no wrap of positions


def test_graph_converges_to_truth():
    """Prior + CV chain + noise-free position priors recover the true 2-D trajectory."""
    dt, n = 2.0, 8
    truth = [np.array([1.0, -2.0, 0.3, 0.7])]
    F = transition_matrix(dt, 2)
    for _ in range(n - 1):
        truth.append(F @ truth[-1])
    g = gtsam.NonlinearFactorGraph()
    g.push_back(constant_velocity_chain(np.arange(n), dt * np.arange(n), 0.01,
                                        estimates=np.zeros((n, 4))))
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


# -- linear (built-in) form -----------------------------------------------------------------


@pytest.mark.parametrize("d", [1, 2, 3])
def test_sqrt_information_inverts_covariance(d):
    """R^T R = Q^-1 for many steps and spectral densities, vectorised and one at a time."""
    rng = np.random.default_rng(70 + d)
    dt = rng.uniform(0.01, 100.0, 12)
    q = float(rng.uniform(1e-9, 10.0))
    R = wna_sqrt_information(dt, q, d)
    assert R.shape == (12, 2 * d, 2 * d)
    for k in range(dt.size):
        Q = wna_covariance(dt[k], q, d)
        assert_allclose(R[k].T @ R[k] @ Q, np.eye(2 * d), atol=1e-9)
        assert_allclose(wna_sqrt_information(dt[k], q, d), R[k], rtol=1e-14)


@pytest.mark.parametrize("d", [1, 2])
def test_linear_jacobians_and_error_equal_wrapped_model(d, wrapped_track):
    """Linear CV factor: whitened Jacobians equal central differences, and its cost equals the
    wrapped model's (tests' reference) at points moved away from the linearisation point
    (bearings near +-pi)."""
    rng = np.random.default_rng(80 + d)
    for _ in range(25):
        dt = rng.uniform(0.1, 20.0)
        noise = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, rng.uniform(1e-6, 1.0), d))
        x0 = rng.normal(size=2 * d)
        x0[:d] = rng.choice([-1, 1]) * np.pi * rng.uniform(0.97, 1.0, d)
        x1 = transition_matrix(dt, d) @ x0 + 0.1 * rng.normal(size=2 * d)
        if d == 1:
            x1[0] = np.mod(x1[0] + np.pi, 2 * np.pi) - np.pi  # next bearing on the other branch
        lin = linear_constant_velocity_factor(noise, 0, 1, dt, estimate_prev=x0, estimate_next=x1)
        old = wrapped_track.motion(noise, 0, 1, dt)
        at = _values(x0, x1)
        assert_jacobians(lin, at)  # no unwhitened error: checked on the whitened error
        moved = _values(x0 + 0.05 * rng.normal(size=2 * d), x1 + 0.05 * rng.normal(size=2 * d))
        assert_allclose(lin.error(moved), old.error(moved), rtol=1e-9)
        assert_allclose(lin.error(at), old.error(at), rtol=1e-9)


def test_linear_zero_at_truth_and_chain_equals_single_factors():
    """Zero cost on the CV prediction; the vectorised chain builds the same factors one by one."""
    rng = np.random.default_rng(91)
    t = np.cumsum(rng.uniform(0.5, 6.0, 8))
    q = 0.02
    x = rng.normal(size=(8, 4))
    chain = constant_velocity_chain(np.arange(8), t, q, estimates=x)
    assert chain.size() == 7
    v = _values(*x)
    for k in range(chain.size()):
        f = chain.at(k)
        dt = t[k + 1] - t[k]
        noise = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, q, 2))
        one = linear_constant_velocity_factor(noise, k, k + 1, dt, estimate_prev=x[k],
                                              estimate_next=x[k + 1])
        assert_allclose(f.error(v), one.error(v), rtol=1e-10)
        truth = _values(*[np.zeros(4)] * k, x[k], transition_matrix(dt, 2) @ x[k])
        assert f.error(truth) < 1e-20
    assert constant_velocity_chain([0], [0.0], q, estimates=x[:1]).size() == 0


def test_linear_chain_graph_matches_wrapped_model(wrapped_track):
    """A bearing track across +-180 deg: the chain of linear CV factors and the wrapped model's
    chain (tests' reference) give the same optimum (to 1e-9) with the same bearings and prior."""
    rng = np.random.default_rng(5)
    n, q, sig = 25, 1e-7, 0.01
    t = np.cumsum(rng.uniform(2.0, 6.0, n))
    theta = np.pi - 0.05 + 0.003 * (t - t[0])
    z = np.mod(theta + rng.normal(0, sig, n) + np.pi, 2 * np.pi) - np.pi
    init = np.column_stack([np.unwrap(z), np.zeros(n)])
    out = []
    for kind in ("reference", "linear"):
        g = gtsam.NonlinearFactorGraph()
        g.add(gtsam.PriorFactorVector(0, init[0], gtsam.noiseModel.Diagonal.Sigmas([0.1, 0.01])))
        if kind == "reference":
            for k in range(n - 1):
                dt = t[k + 1] - t[k]
                noise = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, q, 1))
                g.add(wrapped_track.motion(noise, k, k + 1, dt))
        else:
            g.push_back(constant_velocity_chain(np.arange(n), t, q, estimates=init))
        for k in range(n):
            g.add(gtsam.PriorFactorVector(
                k, np.array([init[k, 0], 0.0]),
                gtsam.noiseModel.Diagonal.Precisions(np.array([1 / sig**2, 0.0]))))
        p = gtsam.LevenbergMarquardtParams()
        p.setRelativeErrorTol(1e-14)
        res = gtsam.LevenbergMarquardtOptimizer(g, _values(*init), p).optimize()
        out.append(np.array([res.atVector(k) for k in range(n)]))
    assert_allclose(out[1], out[0], atol=1e-9)
    assert_allclose(out[1][:, 1], 0.003, atol=1e-3)


def test_linear_bad_input():
    """Robust or odd-dimensional noise, equal keys, bad estimates and times raise ValueError."""
    huber = gtsam.noiseModel.mEstimator.Huber.Create(1.0)
    robust = gtsam.noiseModel.Robust.Create(huber, gtsam.noiseModel.Unit.Create(2))
    z2 = np.zeros(2)
    with pytest.raises(ValueError, match="Gaussian"):
        linear_constant_velocity_factor(robust, 0, 1, 1.0, estimate_prev=z2, estimate_next=z2)
    with pytest.raises(ValueError, match="even"):
        linear_constant_velocity_factor(gtsam.noiseModel.Unit.Create(3), 0, 1, 1.0,
                                        estimate_prev=np.zeros(3), estimate_next=np.zeros(3))
    with pytest.raises(ValueError, match="differ"):
        linear_constant_velocity_factor(gtsam.noiseModel.Unit.Create(2), 0, 0, 1.0,
                                        estimate_prev=z2, estimate_next=z2)
    with pytest.raises(ValueError, match="shape"):
        linear_constant_velocity_factor(gtsam.noiseModel.Unit.Create(2), 0, 1, 1.0,
                                        estimate_prev=np.zeros(4), estimate_next=z2)
    with pytest.raises(ValueError, match="strictly increasing"):
        constant_velocity_chain([0, 1], [1.0, 1.0], 0.1, estimates=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="estimates"):
        constant_velocity_chain([0, 1], [0.0, 1.0], 0.1, estimates=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="dt"):
        wna_sqrt_information(np.array([1.0, 0.0]), 0.1, 1)


def test_steps_of_many_tracks_equal_single_factors():
    """One vectorised call for one step of many tracks (different dt, d=2) builds the factors
    of linear_constant_velocity_factor; a key shared by two steps keeps one estimate."""
    rng = np.random.default_rng(95)
    m, q = 6, 0.05
    dt = rng.uniform(0.5, 9.0, m)
    x0, x1 = rng.normal(size=(m, 4)), rng.normal(size=(m, 4))
    kp, kn = np.arange(m), np.arange(m) + 100
    steps = constant_velocity_steps(kp, kn, dt, q, estimates_prev=x0, estimates_next=x1)
    assert steps.size() == m
    v = gtsam.Values()
    for i in range(m):
        v.insert(int(kp[i]), x0[i] + 0.1 * rng.normal(size=4))
        v.insert(int(kn[i]), x1[i])
    for i in range(m):
        noise = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt[i], q, 2))
        one = linear_constant_velocity_factor(noise, int(kp[i]), int(kn[i]), dt[i],
                                              estimate_prev=x0[i], estimate_next=x1[i])
        assert_allclose(steps.at(i).error(v), one.error(v), rtol=1e-10)
    shared = constant_velocity_steps([0, 1], [1, 2], 1.0, q, estimates_prev=x0[:2, :2] * 0,
                                     estimates_next=x0[:2, :2] * 0)
    assert shared.size() == 2
    with pytest.raises(ValueError, match="one key pair"):
        constant_velocity_steps([0, 1], [1], 1.0, q, estimates_prev=x0[:2], estimates_next=x1[:2])
