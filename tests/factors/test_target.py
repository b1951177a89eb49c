"""Tests of the bearing factor on a constant-velocity target state (factors.target)."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from factors.target import (
    target_bearing,
    target_bearing_batch_factor,
    target_bearing_jacobian,
)
from factors.testing import analytic_jacobians, assert_jacobians
from fusion.geometry import compass_bearing_deg

SIGMA = np.radians(1.0)


def _noise(sigma: float = SIGMA) -> gtsam.noiseModel.Base:
    return gtsam.noiseModel.Isotropic.Sigma(1, sigma)


def _one(noise: gtsam.noiseModel.Base, key: int, own, z: float, *, dt: float = 0.0):
    """The factor of one bearing: a batch of one."""
    return target_bearing_batch_factor(noise, key, np.asarray(own, float)[None, :], [z], dt=[dt])


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
        f = _one(_noise(), 7, own, z, dt=dt)
        assert_jacobians(f, _values(7, state), delta=1e-4, rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_jacobian_and_error_target_due_south(side):
    """Target due south (bearing near ±180 deg): wrapped error is small, Jacobian still exact."""
    own = np.array([100.0, 200.0])
    state = np.array([100.0 + side * 1e-3, 200.0 - 3000.0, 1.0, -2.0])
    beta = float(target_bearing(state, own))
    assert abs(abs(beta) - np.pi) < 1e-5
    z = -side * (np.pi - 1e-4)  # measured on the other side of the ±180 deg cut
    f = _one(_noise(), 1, own, z)
    err = f.unwhitenedError(_values(1, state))
    assert abs(err[0]) < 2e-4
    assert_jacobians(f, _values(1, state), delta=1e-4, rtol=1e-5, atol=1e-9)


def test_zero_error_at_truth():
    """The factor's error vanishes when the bearing is the true one (also due south, dt != 0)."""
    rng = np.random.default_rng(3)
    for _ in range(40):
        state, own, dt = _random_geometry(rng)
        z = float(target_bearing(state, own, dt=dt))
        f = _one(_noise(), 2, own, z, dt=dt)
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
        f = _one(_noise(1.0), 0, own, 0.3, dt=dt)
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
        graph.add(_one(_noise(), key, own[k], float(z[k]), dt=float(t[k])))
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
    f = _one(_noise(), 0, [0.0, 0.0], z)
    e = f.unwhitenedError(_values(0, [x, y, 0.0, 0.0]))[0]
    assert -np.pi <= e < np.pi


def _batch_geometry(rng: np.random.Generator, m: int):
    """One state seen m times from a moving platform at times dt (seconds after the epoch)."""
    state, own0, _ = _random_geometry(rng)
    dt = np.sort(rng.uniform(0.0, 900.0, m))
    own = own0 + np.column_stack([rng.normal(0, 300, m), rng.normal(0, 300, m)])
    return state, own, dt


def test_batch_jacobian_matches_central_differences():
    """The batch factor's (m, 4) Jacobian equals central differences at 40 seeded geometries."""
    rng = np.random.default_rng(12)
    for _ in range(40):
        m = int(rng.integers(1, 30))
        state, own, dt = _batch_geometry(rng, m)
        z = target_bearing(state, own, dt=dt) + rng.normal(0, 0.05, m)
        f = target_bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(m, SIGMA), 3, own, z, dt=dt)
        assert_jacobians(f, _values(3, state), delta=1e-4, rtol=1e-5, atol=1e-9)


def test_batch_near_sensor_and_due_south():
    """A target metres from the platform (large, fast-changing Jacobian) and bearings across
    +-180 deg: the Jacobian still matches differences and the wrapped errors are small."""
    own = np.array([[100.0, 200.0], [100.0, 200.0], [100.0, 200.0], [105.0, 198.0]])
    state = np.array([100.0 + 1e-3, 200.0 - 3.0, 0.01, -0.02])  # 3 m south of the platform
    dt = np.array([0.0, 5.0, 10.0, 20.0])
    beta = target_bearing(state, own, dt=dt)
    z = np.mod(beta + np.array([1e-3, -1e-3, 2e-3, 0.0]) + np.pi, 2 * np.pi) - np.pi
    z[0] = -np.pi + 1e-4 if beta[0] > 0 else np.pi - 1e-4  # the other side of the cut
    f = target_bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(4, SIGMA), 0, own, z, dt=dt)
    v = _values(0, state)
    assert np.all(np.abs(f.unwhitenedError(v)) < 5e-3)
    assert_jacobians(f, v, delta=1e-7, rtol=1e-5, atol=1e-7)
    J = analytic_jacobians(f, v)[0]
    assert np.abs(J[:, :2]).max() > 0.1  # rad/m: the near-sensor geometry is steep


def test_batch_equals_one_bearing_factors_and_zero_at_truth():
    """Batch cost = sum of one-bearing costs (single state and one state per bearing); zero at truth."""
    rng = np.random.default_rng(14)
    for _ in range(20):
        state, own, dt = _batch_geometry(rng, 12)
        z = target_bearing(state, own, dt=dt)
        f0 = target_bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(12, SIGMA), 0, own, z,
                                         dt=dt)
        assert_allclose(f0.unwhitenedError(_values(0, state)), 0.0, atol=1e-12)
        zn = z + rng.normal(0, 0.02, 12)
        f = target_bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(12, SIGMA), 0, own, zn,
                                        dt=dt)
        scalars = [_one(_noise(), 0, own[j], float(zn[j]), dt=float(dt[j]))
                   for j in range(12)]
        v = _values(0, state)
        assert_allclose(f.error(v), sum(s.error(v) for s in scalars), rtol=1e-12)
        # one state per bearing (chain layout): keys repeat in pairs
        keys = np.repeat(np.arange(6), 2)
        states = [state + np.array([0, 0, 0.1 * i, 0]) for i in range(6)]
        vv = gtsam.Values()
        for i, s in enumerate(states):
            vv.insert(i, s)
        fk = target_bearing_batch_factor(gtsam.noiseModel.Isotropic.Sigma(12, SIGMA), keys, own,
                                         zn, dt=dt)
        sk = [_one(_noise(), int(keys[j]), own[j], float(zn[j]), dt=float(dt[j]))
              for j in range(12)]
        assert_allclose(fk.error(vv), sum(s.error(vv) for s in sk), rtol=1e-12)
        assert_jacobians(fk, vv, delta=1e-4, rtol=1e-5, atol=1e-9)


def _tma_graph(kind, own, t, z, noise1, noise_m, init):
    key = gtsam.symbol("s", 0)
    g = gtsam.NonlinearFactorGraph()
    if kind == "scalar":
        for k in range(t.size):
            g.add(_one(noise1, key, own[k], float(z[k]), dt=float(t[k])))
    else:
        g.add(target_bearing_batch_factor(noise_m, key, own, z, dt=t))
    p = gtsam.LevenbergMarquardtParams()
    p.setRelativeErrorTol(1e-15)
    p.setAbsoluteErrorTol(1e-20)
    sol = gtsam.LevenbergMarquardtOptimizer(g, _values(key, init), p).optimize()
    return sol.atVector(key), g.error(sol)


def _robust_noises(robust, m, sigma):
    if robust is None:
        return _noise(sigma), gtsam.noiseModel.Isotropic.Sigma(m, sigma)
    make, k = {"huber": (gtsam.noiseModel.mEstimator.Huber, 1.345),
               "tukey": (gtsam.noiseModel.mEstimator.Tukey, 4.685)}[robust]
    scalar = gtsam.noiseModel.mEstimator.Base.ReweightScheme.Scalar
    return (gtsam.noiseModel.Robust.Create(make.Create(k), _noise(sigma)),
            gtsam.noiseModel.Robust.Create(make.Create(k, scalar),
                                           gtsam.noiseModel.Isotropic.Sigma(m, sigma)))


@pytest.mark.parametrize("robust", [None, "huber", "tukey"])
def test_batch_graph_converges_like_one_bearing_factors(robust):
    """From a poor guess the batch graph reaches the same optimum as a graph of one-bearing
    factors; with a
    30-sigma outlier bearing, Huber and Tukey (per bearing) around the batch factor resist it
    (Tukey, redescending, starts from the Huber solution)."""
    truth = np.array([3000.0, 4000.0, -4.0, 1.5])
    t = np.arange(0.0, 1200.0, 30.0)
    own = np.column_stack([np.where(t < 600, 0.0, 5.0 * (t - 600)), 5.0 * np.minimum(t, 600)])
    sigma = np.radians(0.2)
    rng = np.random.default_rng(15)
    z = target_bearing(truth, own, dt=t) + rng.normal(0, sigma, t.size)
    z[17] += 30 * sigma
    init = np.array([2500.0, 3500.0, -2.0, 0.0])
    if robust == "tukey":
        init = _tma_graph("batch", own, t, z, *_robust_noises("huber", t.size, sigma), init)[0]
    n1, nm = _robust_noises(robust, t.size, sigma)
    s_scalar, c_scalar = _tma_graph("scalar", own, t, z, n1, nm, init)
    s_batch, c_batch = _tma_graph("batch", own, t, z, n1, nm, init)
    assert_allclose(s_batch, s_scalar, rtol=1e-9, atol=1e-7)
    assert_allclose(c_batch, c_scalar, rtol=1e-9)
    err = np.hypot(*(s_batch[:2] - truth[:2]))
    plain = _tma_graph("batch", own, t, z, *_robust_noises(None, t.size, sigma), init)[0]
    err_plain = np.hypot(*(plain[:2] - truth[:2]))
    assert err_plain < 300.0
    if robust is not None:
        assert err < 0.5 * err_plain


def test_batch_bad_input_raises():
    """Wrong noise dimension, key count, platform shape and non-finite inputs are ValueErrors."""
    n2 = gtsam.noiseModel.Isotropic.Sigma(2, SIGMA)
    own = np.zeros((2, 2))
    with pytest.raises(ValueError, match="dimension"):
        target_bearing_batch_factor(_noise(), 0, own, [0.1, 0.2])
    with pytest.raises(ValueError, match="platform_xy"):
        target_bearing_batch_factor(n2, 0, np.zeros((3, 2)), [0.1, 0.2])
    with pytest.raises(ValueError, match="keys"):
        target_bearing_batch_factor(n2, [0, 1, 2], own, [0.1, 0.2])
    with pytest.raises(ValueError, match="finite"):
        target_bearing_batch_factor(n2, 0, own, [0.1, np.inf])
    with pytest.raises(ValueError, match="dt"):
        target_bearing_batch_factor(n2, 0, own, [0.1, 0.2], dt=[0.0, np.nan])
