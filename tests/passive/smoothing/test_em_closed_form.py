"""The closed-form M-step of the crossing-cluster EM (fusion.passive.smoothing.em) against the
graph solved with the same weights, and the chain's joint covariance against a dense inverse."""

import gtsam
import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.passive.smoothing.em import SharedBearingPosterior
from fusion.passive.smoothing.graph import (
    _build_graph,
    _chain_bearing_covariance,
    _Measurements,
    _Model,
    _solve,
)
from fusion.passive.smoothing.types import TrackPrior

SIG = 0.01


def _member(seed):
    """A track of 40 scans with hard bearings, 12 weighted ones (two per scan on 6 scans),
    some of them in the free set (the cluster's)."""
    rng = np.random.default_rng(seed)
    times = 10.0 * np.arange(40)
    truth = 3.1 + 2e-3 * times  # crosses the wrap at pi
    hard = np.flatnonzero(rng.random(40) < 0.7)
    soft_state = np.repeat(np.arange(15, 21), 2)
    z = np.r_[truth[hard], truth[soft_state] + rng.choice([0.0, 0.03], soft_state.size)]
    z = np.angle(np.exp(1j * (z + rng.normal(0, SIG, z.size))))
    widx = np.r_[np.full(hard.size, -1), np.arange(soft_state.size)]
    meas = _Measurements(state=np.r_[hard, soft_state], bearing=z, weight_index=widx)
    weights = rng.uniform(0.0, 1.0, soft_state.size)
    free = np.arange(2, soft_state.size)  # pairs 0, 1 stay fixed (another cluster's)
    prior = TrackPrior(bearing=3.1, rate=2e-3, sigma_bearing=10 * SIG, sigma_rate=1e-3)
    model = _Model(sigma_bearing=SIG, q=1e-9, loss="none", k=1.345, max_iterations=50)
    init = np.column_stack([3.1 + 1.5e-3 * times, np.full(40, 1.5e-3)])
    return times, meas, prior, model, init, weights, free, soft_state[free], z[hard.size:][free]


@pytest.mark.parametrize("seed", range(4))
def test_closed_form_m_step_equals_the_graph_solved_with_the_weights(seed):
    times, meas, prior, model, init, weights, free, st, zf = _member(seed)
    post = SharedBearingPosterior(times, meas, prior, model, init, weights, free, st, zf)
    rng = np.random.default_rng(100 + seed)
    for w in (rng.uniform(0, 1, free.size), np.zeros(free.size), np.ones(free.size),
              np.r_[np.ones(5), np.zeros(free.size - 5)]):
        full = weights.copy()
        full[free] = w
        states, _ = _solve(times, meas, prior, model, init=init, weights=full)
        got = post.bearings(w)
        assert_allclose(np.angle(np.exp(1j * (got - states[st, 0]))), 0.0, atol=1e-9)
    # the weights move the bearings (the test can fail)
    assert np.max(np.abs(post.bearings(np.ones(free.size)) - post.bearings(np.zeros(free.size)))) > 1e-3


def test_chain_bearing_covariance_equals_the_dense_inverse():
    times, meas, prior, model, init, weights, *_ = _member(5)
    graph = _build_graph(times, meas, prior, model, "none", weights, init)
    values = gtsam.Values()
    for k in range(times.size):
        values.insert(k, init[k])
    lin = graph.linearize(values)
    a, _ = lin.jacobian()
    cov = np.linalg.inv(a.T @ a)  # columns in key order 0..n-1, two per state
    states = np.array([30, 3, 17, 17, 39, 0])
    got = _chain_bearing_covariance(lin, times.size, states)
    want = cov[np.ix_(2 * states, 2 * states)]
    assert_allclose(got, want, rtol=1e-7, atol=1e-14)


@pytest.mark.parametrize("seed", range(2))
def test_closed_form_states_equal_the_graph_solved_with_the_weights(seed):
    times, meas, prior, model, init, weights, free, st, zf = _member(seed)
    post = SharedBearingPosterior(times, meas, prior, model, init, weights, free, st, zf)
    w = np.random.default_rng(200 + seed).uniform(0, 1, free.size)
    full = weights.copy()
    full[free] = w
    states, _ = _solve(times, meas, prior, model, init=init, weights=full)
    got = post.states_at(w)
    assert_allclose(np.angle(np.exp(1j * (got[:, 0] - states[:, 0]))), 0.0, atol=1e-9)
    assert_allclose(got[:, 1], states[:, 1], atol=1e-11)
    assert np.max(np.abs(got - post.states_at(np.zeros(free.size)))) > 1e-4
