"""Tests of factors.bearing: scalar, batch (vector) and linear bearing factors."""

import gtsam
import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.bearing import (
    bearing_batch_factor,
    bearing_factor,
    linear_bearing_factor,
    linear_bearing_factors,
    state_bearing_noise,
)
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


# -- vector (batch) and linear forms ------------------------------------------------------

SIG = 0.01
SCALAR = gtsam.noiseModel.mEstimator.Base.ReweightScheme.Scalar


def _states(rng, n_states, near_south):
    x = np.column_stack([rng.uniform(-np.pi, np.pi, n_states), rng.normal(0, 0.01, n_states)])
    if near_south:
        x[:, 0] = rng.choice([-1, 1], n_states) * (np.pi - rng.uniform(0.0, 0.03, n_states))
    return x


def _batch(rng, n_states, m, near_south):
    """States, the state index of m bearings (every state at least once) and the bearings."""
    x = _states(rng, n_states, near_south)
    idx = np.r_[np.arange(n_states), rng.integers(0, n_states, m - n_states)]
    z = x[idx, 0] + rng.normal(0, 3 * SIG, m)
    if near_south:
        z = np.mod(z + np.pi, 2 * np.pi) - np.pi  # measured on the other side of the cut
    return x, idx, z


def _values_of(x):
    v = gtsam.Values()
    for k, xk in enumerate(x):
        v.insert(k, np.asarray(xk, float))
    return v


@pytest.mark.parametrize("near_south", [False, True])
def test_batch_jacobians_many_states(near_south):
    """Batch factor Jacobians equal central differences at seeded states, bearings near +-180."""
    rng = np.random.default_rng(21 + near_south)
    for _ in range(30):
        n_states = int(rng.integers(1, 4))
        m = n_states + int(rng.integers(0, 4))
        x, idx, z = _batch(rng, n_states, m, near_south)
        f = bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(m, SIG), idx, z)
        assert_jacobians(f, _values_of(x))


@pytest.mark.parametrize("near_south", [False, True])
def test_batch_equals_scalar_error_and_linearisation(near_south):
    """The batch factor's cost and normal equations equal those of m scalar factors."""
    rng = np.random.default_rng(31 + near_south)
    for _ in range(20):
        x, idx, z = _batch(rng, 3, 7, near_south)
        v = _values_of(x)
        batch = bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(7, SIG), idx, z)
        scalars = [bearing_factor(gtsam.noiseModel.Isotropic.Sigma(1, SIG), int(k), float(zj))
                   for k, zj in zip(idx, z, strict=True)]
        assert_allclose(batch.error(v), sum(f.error(v) for f in scalars), rtol=1e-12)
        gb, gs = gtsam.GaussianFactorGraph(), gtsam.GaussianFactorGraph()
        gb.push_back(batch.linearize(v))
        for f in scalars:
            gs.push_back(f.linearize(v))
        order = gtsam.Ordering([0, 1, 2])
        hb, hs = gb.hessian(order), gs.hessian(order)
        assert_allclose(hb[0], hs[0], rtol=1e-12)
        assert_allclose(hb[1], hs[1], rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("estimator", ["huber", "tukey"])
def test_robust_batch_equals_robust_scalars(estimator):
    """Robust (scalar-reweighted) noise around the batch factor: its cost and linearisation
    equal those of robust scalar factors and the Gaussian linearisation reweighted row by row
    with sqrt(w(e_i)); the Gaussian part's Jacobians match central differences."""
    make = {"huber": gtsam.noiseModel.mEstimator.Huber,
            "tukey": gtsam.noiseModel.mEstimator.Tukey}[estimator]
    k = 1.345 if estimator == "huber" else 4.685
    rng = np.random.default_rng(41)
    for _ in range(15):
        x, idx, z = _batch(rng, 2, 6, bool(rng.integers(0, 2)))
        z[rng.integers(0, 6)] += 0.3  # an outlier
        v = _values_of(x)
        gauss = gtsam.noiseModel.Isotropic.Sigma(6, SIG)
        est = make.Create(k, SCALAR)
        batch = bearing_batch_factor(gtsam.noiseModel.Robust.Create(est, gauss), idx, z)
        plain = bearing_batch_factor(gauss, idx, z)
        assert_jacobians(plain, v)
        rob1 = gtsam.noiseModel.Robust.Create(make.Create(k), gtsam.noiseModel.Isotropic.Sigma(1, SIG))
        scalars = [bearing_factor(rob1, int(s), float(zj)) for s, zj in zip(idx, z, strict=True)]
        assert_allclose(batch.error(v), sum(f.error(v) for f in scalars), rtol=1e-12)
        u = plain.whitenedError(v)
        assert_allclose(batch.error(v), sum(est.loss(ui) for ui in u), rtol=1e-12)
        sw = np.sqrt([est.weight(ui) for ui in u])  # sqrt(w(e_i)), row by row
        a_r, b_r = batch.linearize(v).jacobian()
        a_g, b_g = plain.linearize(v).jacobian()
        assert_allclose(a_r, sw[:, None] * a_g, rtol=1e-12, atol=1e-12)
        assert_allclose(b_r, sw * b_g, rtol=1e-12, atol=1e-12)
        gb, gs = gtsam.GaussianFactorGraph(), gtsam.GaussianFactorGraph()
        gb.push_back(batch.linearize(v))
        for f in scalars:
            gs.push_back(f.linearize(v))
        hb, hs = gb.hessian(gtsam.Ordering([0, 1])), gs.hessian(gtsam.Ordering([0, 1]))
        assert_allclose(hb[0], hs[0], rtol=1e-10, atol=1e-6)
        assert_allclose(hb[1], hs[1], rtol=1e-10, atol=1e-6)
        with pytest.raises(ValueError, match="robust"):
            assert_jacobians(batch, v)


def _track_graph(kind, theta, rate, dt, z, robust=None):
    """Prior + CV chain + bearing factors of one form; states initialised at the truth + 0.02."""
    n = theta.size
    g = gtsam.NonlinearFactorGraph()
    motion = gtsam.noiseModel.Gaussian.Covariance(wna_covariance(dt, 1e-8, 1))
    g.add(gtsam.PriorFactorVector(0, np.array([theta[0], rate]),
                                  gtsam.noiseModel.Diagonal.Sigmas([0.1, 0.01])))
    for k in range(1, n):
        g.add(constant_velocity_factor(motion, k - 1, k, dt))
    base = gtsam.noiseModel.Isotropic.Sigma(1, SIG)
    noise = base if robust is None else gtsam.noiseModel.Robust.Create(robust, base)
    init = np.column_stack([theta + 0.02, np.zeros(n)])
    if kind == "scalar":
        for k in range(n):
            g.add(bearing_factor(noise, k, float(z[k])))
    elif kind == "batch":
        vec = gtsam.noiseModel.Isotropic.Sigma(5, SIG)
        if robust is not None:
            vec = gtsam.noiseModel.Robust.Create(robust, vec)
        for s in range(0, n, 5):
            g.add(bearing_batch_factor(vec, range(s, s + 5), z[s:s + 5]))
    else:
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
def test_all_forms_same_optimum_across_south(robust):
    """Scalar, batch and linear bearing factors give the same optimum and cost for a noisy
    track crossing +-180 deg (Gaussian, and Huber with an outlier)."""
    rng = np.random.default_rng(51)
    dt, rate, n = 5.0, 0.003, 30
    theta = np.pi - 0.04 + rate * dt * np.arange(n)
    z = np.mod(theta + rng.normal(0, SIG, n) + np.pi, 2 * np.pi) - np.pi
    z[7] += 0.5
    est = None if robust is None else gtsam.noiseModel.mEstimator.Huber.Create(1.345, SCALAR)
    out = {kind: _solve(*_track_graph(kind, theta, rate, dt, z, est))
           for kind in ("scalar", "batch", "linear")}
    for kind in ("batch", "linear"):
        assert_allclose(out[kind][0], out["scalar"][0], atol=1e-9)
        assert_allclose(out[kind][1], out["scalar"][1], rtol=1e-9)
    err = np.angle(np.exp(1j * (out["linear"][0][:, 0] - theta)))
    assert np.sqrt(np.mean(err**2)) < (2 * SIG if robust else 4 * SIG)


def test_linear_factor_jacobians_and_wrapped_error():
    """Linear factors: whitened Jacobians equal central differences; the whitened error equals
    the scalar factor's wrapped one near +-180 deg and vanishes at the truth."""
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
        assert_allclose(e_lin[0], bearing_factor(noise, 0, z).whitenedError(v)[0], atol=1e-9)
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


def test_fast_forms_bad_input():
    """Mismatched keys/bearings, wrong noise dimension, bad estimates raise ValueError."""
    n1 = gtsam.noiseModel.Isotropic.Sigma(1, SIG)
    with pytest.raises(ValueError, match="one key per bearing"):
        bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(2, SIG), [0], [0.1, 0.2])
    with pytest.raises(ValueError, match="dimension"):
        bearing_batch_factor(n1, [0, 1], [0.1, 0.2])
    with pytest.raises(ValueError, match="finite"):
        bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(2, SIG), [0, 1], [0.1, np.nan])
    with pytest.raises(ValueError, match="estimates"):
        linear_bearing_factors(n1, [0, 1], [0.1, 0.2], estimates=np.zeros((1, 2)))
    with pytest.raises(ValueError, match="1-dimensional"):
        state_bearing_noise(gtsam.noiseModel.Isotropic.Sigma(2, SIG), 2)
    with pytest.raises(ValueError, match="1-D"):
        linear_bearing_factor(n1, 0, 0.1, estimate=np.zeros((2, 2)))
