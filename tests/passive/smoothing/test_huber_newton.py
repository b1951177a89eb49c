"""The Huber-loss track graph minimised by Newton steps (fusion.passive.smoothing.huber)
against Levenberg-Marquardt run to convergence on the same graph."""

import numpy as np
from numpy.testing import assert_allclose

from fusion.passive.smoothing.graph import (
    _default_prior,
    _initial_states,
    _Measurements,
    _Model,
    _solve,
)

SIG = np.radians(0.1)


def _two_boxes(seed, n=250):
    """One boat boxed twice, 1.2 deg apart, in random turns (each box the other's outliers),
    and a few far outliers: the case where reweighted least squares crawls."""
    rng = np.random.default_rng(seed)
    t = 0.2 * np.arange(n)
    truth = 1.0 + np.radians(0.05) * t + np.radians(0.3) * np.sin(t / 15.0)
    off = np.where(rng.random(n) < 0.5, 0.0, np.radians(1.2))
    z = truth + off + rng.normal(0, SIG, n)
    far = rng.random(n) < 0.03
    z[far] += rng.uniform(-0.2, 0.2, far.sum())
    meas = _Measurements(state=np.arange(n, dtype=np.int64), bearing=z)
    x0 = _initial_states(t, meas, None)
    return t, meas, x0


def _model(loss, iterations):
    return _Model(sigma_bearing=SIG, q=np.radians(0.05) ** 2, loss=loss, k=1.345,
                  max_iterations=iterations)


def test_newton_reaches_the_minimum_that_lm_approaches():
    t, meas, x0 = _two_boxes(3)
    prior = _default_prior(x0[0, 0], _model("none", 1), 0.05)
    got, sig = _solve(t, meas, prior, _model("huber", 100), marginals=True)
    # reference: LM on GTSAM's robust noise model, run far past its default cap ("cauchy"
    # first solves with Huber: use the LM path through a weighted copy of the bearings)
    ref_meas = _Measurements(state=meas.state, bearing=meas.bearing,
                             weight_index=np.arange(meas.state.size, dtype=np.int64))
    ref, _ = _solve(t, ref_meas, prior, _model("huber", 5000),
                    weights=np.ones(meas.state.size))
    assert_allclose(got[:, 0], ref[:, 0], atol=np.radians(1e-4))
    assert np.all(np.isfinite(sig)) and np.all(sig > 0)
    # and no costlier than LM stopped at the smoothers' 100 iterations
    short, _ = _solve(t, ref_meas, prior, _model("huber", 100), weights=np.ones(meas.state.size))
    assert _cost(got, t, meas, prior) <= _cost(short, t, meas, prior) + 1e-9


def _cost(x, t, meas, prior):
    from factors.motion import wna_sqrt_information
    from fusion.passive.smoothing.huber import _cost as cost

    return cost(x, t, meas.state, meas.bearing, prior, _model("huber", 1),
                wna_sqrt_information(np.diff(t), _model("huber", 1).q, 1))
