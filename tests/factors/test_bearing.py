"""Tests of factors.bearing: the built-in linear bearing factors, against the wrapped model."""

import gtsam
import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.bearing import (
    linear_bearing_factor,
    linear_bearing_factors,
    state_bearing_noise,
)
from factors.motion import constant_velocity_chain, wna_covariance
from factors.testing import assert_jacobians


def _v(x):
    v = gtsam.Values()
    v.insert(0, np.asarray(x, float))
    return v


def test_reference_model_jacobians(wrapped_track):
    """The tests' wrapped reference model (conftest) has the Jacobians of central differences,
    bearings near +-180 deg: the oracle the built-in forms are checked against."""
    rng = np.random.default_rng(5)
    noise = gtsam.noiseModel.Isotropic.Sigma(1, 0.01)
    for i in range(40):
        n = 1 + i % 3
        x = rng.normal(size=n)
        z = rng.uniform(-np.pi, np.pi)
        if i % 2:
            x[0] = np.pi - rng.uniform(0.0, 0.05)
            z = -np.pi + rng.uniform(0.0, 0.05)
        assert_jacobians(wrapped_track.bearing(noise, 0, z), _v(x))
    motion = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(3.0, 1e-4, 1))
    v = gtsam.Values()
    v.insert(0, np.array([np.pi - 0.01, 0.002]))
    v.insert(1, np.array([-np.pi + 0.01, 0.003]))
    assert_jacobians(wrapped_track.motion(motion, 0, 1, 3.0), v)


# -- the linear forms against the reference model ----------------------------------------

SIG = 0.01
SCALAR = gtsam.noiseModel.mEstimator.Base.ReweightScheme.Scalar


def _states(rng, n_states, near_south):
    x = np.column_stack([rng.uniform(-np.pi, np.pi, n_states), rng.normal(0, 0.01, n_states)])
    if near_south:
        x[:, 0] = rng.choice([-1, 1], n_states) * (np.pi - rng.uniform(0.0, 0.03, n_states))
    return x


def _values_of(x):
    v = gtsam.Values()
    for k, xk in enumerate(x):
        v.insert(k, np.asarray(xk, float))
    return v


def _track_graph(kind, theta, rate, dt, z, wrapped_track, robust=None):
    """Prior + CV chain + bearing factors: the reference model, or the built-in linear forms
    (built at the start); states initialised at the truth + 0.02."""
    n = theta.size
    g = gtsam.NonlinearFactorGraph()
    g.add(gtsam.PriorFactorVector(0, np.array([theta[0], rate]),
                                  gtsam.noiseModel.Diagonal.Sigmas([0.1, 0.01])))
    base = gtsam.noiseModel.Isotropic.Sigma(1, SIG)
    noise = base if robust is None else gtsam.noiseModel.Robust.Create(robust, base)
    init = np.column_stack([theta + 0.02, np.zeros(n)])
    if kind == "reference":
        motion = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, 1e-8, 1))
        for k in range(n):
            g.add(wrapped_track.bearing(noise, k, float(z[k])))
            if k:
                g.add(wrapped_track.motion(motion, k - 1, k, dt))
    else:
        g.push_back(constant_velocity_chain(np.arange(n), dt * np.arange(n), 1e-8,
                                            estimates=init))
        for f in linear_bearing_factors(noise, range(n), z, estimates=init):
            g.add(f)
    return g, _values_of(init)


def _solve(g, init):
    p = gtsam.LevenbergMarquardtParams()
    p.setRelativeErrorTol(1e-14)
    p.setAbsoluteErrorTol(1e-16)
    res = gtsam.LevenbergMarquardtOptimizer(g, init, p).optimize()
    return np.array([res.atVector(k) for k in range(init.size())]), g.error(res)


@pytest.mark.parametrize("robust", [None, "huber"])
def test_linear_forms_reach_the_wrapped_optimum_across_south(robust, wrapped_track):
    """The linear bearing and motion factors give the wrapped model's optimum and cost for a
    noisy track crossing +-180 deg (Gaussian, and Huber with an outlier)."""
    rng = np.random.default_rng(51)
    dt, rate, n = 5.0, 0.003, 30
    theta = np.pi - 0.04 + rate * dt * np.arange(n)
    z = np.mod(theta + rng.normal(0, SIG, n) + np.pi, 2 * np.pi) - np.pi
    z[7] += 0.5
    est = None if robust is None else gtsam.noiseModel.mEstimator.Huber.Create(1.345, SCALAR)
    out = {kind: _solve(*_track_graph(kind, theta, rate, dt, z, wrapped_track, est))
           for kind in ("reference", "linear")}
    assert_allclose(out["linear"][0], out["reference"][0], atol=1e-9)
    assert_allclose(out["linear"][1], out["reference"][1], rtol=1e-9)
    err = np.angle(np.exp(1j * (out["linear"][0][:, 0] - theta)))
    assert np.sqrt(np.mean(err**2)) < (2 * SIG if robust else 4 * SIG)


def test_linear_factor_jacobians_and_wrapped_error():
    """Linear factors: whitened Jacobians equal central differences; the whitened error equals
    the wrapped residual wrap(x[0] - z) / sigma near +-180 deg and vanishes at the truth."""
    rng = np.random.default_rng(61)
    noise = gtsam.noiseModel.Isotropic.Sigma(1, SIG)
    for i in range(40):
        x = _states(rng, 1, near_south=bool(i % 2))[0]
        if i % 3 == 0:
            x = np.r_[x, rng.normal()]  # a 3-D state: only component 0 is measured
        z = float(np.mod(x[0] + rng.normal(0, 0.05) + np.pi, 2 * np.pi) - np.pi)
        f = linear_bearing_factor(noise, 0, z, estimate=x)
        v = _v(x)
        assert_jacobians(f, v, whitened=True)
        e_lin = f.whitenedError(v)
        assert_allclose(e_lin[0], np.angle(np.exp(1j * (x[0] - z))) / SIG, atol=1e-9)
        assert_allclose(e_lin[1:], 0.0, atol=0.0)
        at_truth = linear_bearing_factor(noise, 0, float(x[0]) + 2 * np.pi, estimate=x)
        assert_allclose(at_truth.whitenedError(v), 0.0, atol=1e-9)


def test_linear_factor_keeps_robust_loss_per_bearing():
    """A robust 1-D noise becomes a robust state noise: cost rho((x0 - z) / sigma) per bearing."""
    huber = gtsam.noiseModel.mEstimator.Huber.Create(1.345)
    noise = gtsam.noiseModel.Robust.Create(huber, gtsam.noiseModel.Isotropic.Sigma(1, SIG))
    f = linear_bearing_factor(noise, 0, 0.35, estimate=[0.3, 0.2])
    u = 5.0  # (0.35 - 0.3) / 0.01
    assert_allclose(f.error(_v([0.3, -7.0])), 1.345 * u - 1.345**2 / 2, rtol=1e-12)
    assert isinstance(state_bearing_noise(noise, 2), gtsam.noiseModel.Robust)


def test_linear_forms_bad_input():
    """Mismatched keys/bearings, wrong noise dimension, bad estimates raise ValueError."""
    n1 = gtsam.noiseModel.Isotropic.Sigma(1, SIG)
    with pytest.raises(ValueError, match="one key per bearing"):
        linear_bearing_factors(n1, [0], [0.1, 0.2], estimates=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="finite"):
        linear_bearing_factors(n1, [0, 1], [0.1, np.nan], estimates=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="estimates"):
        linear_bearing_factors(n1, [0, 1], [0.1, 0.2], estimates=np.zeros((1, 2)))
    with pytest.raises(ValueError, match="1-dimensional"):
        state_bearing_noise(gtsam.noiseModel.Isotropic.Sigma(2, SIG), 2)
    with pytest.raises(ValueError, match="1-D"):
        linear_bearing_factor(n1, 0, 0.1, estimate=np.zeros((2, 2)))
