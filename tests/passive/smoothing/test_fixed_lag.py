"""Tests of fusion.passive.smoothing.fixed_lag: the one incremental bearing tracker."""

from __future__ import annotations

import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from numpy.testing import assert_allclose

from factors.motion import transition_matrix, wna_covariance
from fusion.passive.smoothing import FixedLagBearingTrack, TrackPrior, rts_reference

Q = math.radians(2.0 / 3600.0) ** 2  # rad^2/s^3: 2 deg/min^2 per 1 s scan
SIGMA = 0.015  # rad
PRIOR = TrackPrior(bearing=1.0, rate=5e-4, sigma_bearing=0.02, sigma_rate=3e-4)


def _bearings(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    return t, 1.0 + 6e-4 * t + 1e-6 * t**2 + SIGMA * rng.standard_normal(n)


def test_latest_state_is_the_kalman_filter():
    """The fixed-lag graph's latest state and covariance equal filterpy's Kalman filter."""
    t, z = _bearings(150, 0)
    tr = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=30.0, q=Q)
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.x, kf.P = PRIOR.mean.copy(), PRIOR.covariance.copy()
    kf.H, kf.R = np.array([[1.0, 0.0]]), np.array([[SIGMA**2]])
    for k in range(1, t.size):
        x, p = tr.update(t[k], bearing=z[k], sigma=SIGMA, q_scale=1.0 + (k % 3 == 0))
        kf.predict(F=transition_matrix(1.0, 1), Q=(1.0 + (k % 3 == 0)) * wna_covariance(1.0, Q, 1))
        kf.update(np.array([z[k]]))
        assert_allclose(x, kf.x, rtol=0, atol=1e-9)
        assert_allclose(p, kf.P, rtol=1e-6, atol=1e-16)


def test_long_lag_states_are_the_rts_smoother():
    """With a lag longer than the data, the states are the Rauch-Tung-Striebel smoother's."""
    t, z = _bearings(80, 1)
    tr = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=1e6, q=Q)
    # the reference filters z[0] into the first state too
    tr.add_bearings(np.array([0.0]), np.array([z[0]]), np.array([SIGMA]))
    for k in range(1, t.size):
        tr.update(t[k], bearing=z[k], sigma=SIGMA)
    st = tr.states()
    xs, ps, _, _ = rts_reference(t, z, PRIOR, sigma_bearing=SIGMA, q=Q)
    assert_allclose(st.time, t)
    assert_allclose(st.state, xs, rtol=0, atol=1e-9)
    assert_allclose(st.sigma, np.sqrt(np.diagonal(ps, axis1=1, axis2=2)), rtol=1e-6)


def test_states_leaving_the_lag_are_fixed_lag_smoothed():
    """A state that left the lag holds the RTS estimate on the data up to its departure."""
    t, z = _bearings(120, 2)
    lag, block = 20.0, 5.0
    tr = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=lag, q=Q, block_s=block)
    tr.add_bearings(np.array([0.0]), np.array([z[0]]), np.array([SIGMA]))
    for k in range(1, t.size):
        tr.update(t[k], bearing=z[k], sigma=SIGMA)
    st = tr.states()
    stamp = np.floor(t / block + 1e-9) * block
    for k in (0, 7, 40, 80):
        leave = int(np.flatnonzero(stamp - lag > stamp[k])[0])  # the update that marginalised k
        xs, _, _, _ = rts_reference(t[:leave], z[:leave], PRIOR, sigma_bearing=SIGMA, q=Q)
        assert_allclose(st.state[k], xs[k], rtol=0, atol=1e-8)


def test_add_bearings_equals_bearings_given_in_time():
    """Bearings added to past states later give the same latest state as given at once."""
    t, z = _bearings(60, 3)
    late = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=100.0, q=Q)
    now = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=100.0, q=Q)
    held = np.arange(20, 35)
    for k in range(1, t.size):
        now.update(t[k], bearing=z[k], sigma=SIGMA)
        late.update(t[k], bearing=None if k in held else z[k], sigma=SIGMA)
    assert late.add_bearings(t[held], z[held], np.full(held.size, SIGMA)) == held.size
    assert_allclose(late.estimate[0], now.estimate[0], rtol=0, atol=1e-10)
    assert late.add_bearings(np.array([0.5]), np.array([1.0]), np.array([SIGMA])) == 0


def test_predict_and_bad_updates():
    """predict is F x, F P F' + s Q; updates must move forward in time with a sigma."""
    tr = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=10.0, q=Q)
    x, p = tr.predict(3.0, q_scale=2.0)
    f = transition_matrix(3.0, 1)
    assert_allclose(x, f @ PRIOR.mean)
    assert_allclose(p, f @ PRIOR.covariance @ f.T + 2.0 * wna_covariance(3.0, Q, 1))
    with pytest.raises(ValueError, match="not after"):
        tr.update(0.0)
    with pytest.raises(ValueError, match="positive sigma"):
        tr.update(1.0, bearing=1.0)
    with pytest.raises(ValueError, match="lag_s"):
        FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=0.0, q=Q)


def test_infinite_lag_keeps_every_state_and_equals_the_long_lag():
    """lag_s = inf never marginalises: the states equal those of a lag longer than the data."""
    t, z = _bearings(40, 4)
    inf = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=math.inf, q=Q)
    long = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=1e6, q=Q)
    for k in range(1, t.size):
        inf.update(t[k], bearing=z[k], sigma=SIGMA)
        long.update(t[k], bearing=z[k], sigma=SIGMA)
    assert_allclose(inf.states().state, long.states().state, rtol=0, atol=1e-12)
    assert inf.add_bearings(t[:1], z[:1], np.array([SIGMA])) == 1  # the first state is live


def test_robust_loss_resists_an_outlier():
    """With a Huber loss a 40-sigma bearing moves the latest state far less than with the
    Gaussian loss; without outliers the two agree closely."""
    t, z = _bearings(30, 5)
    z_bad = z.copy()
    z_bad[20] += 40 * SIGMA
    out = {}
    for loss in ("none", "huber"):
        tr = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=math.inf, q=Q, robust=loss)
        for k in range(1, 21):
            tr.update(t[k], bearing=z_bad[k], sigma=SIGMA)
        out[loss] = tr.estimate[0][0]
    clean = FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=math.inf, q=Q)
    for k in range(1, 21):
        clean.update(t[k], bearing=z[k], sigma=SIGMA)
    ref = clean.estimate[0][0]
    assert abs(out["huber"] - ref) < 0.3 * abs(out["none"] - ref)
    with pytest.raises(ValueError, match="robust loss"):
        FixedLagBearingTrack(prior=PRIOR, t0=0.0, lag_s=1.0, q=Q, robust="tukey")
