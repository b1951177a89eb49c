"""Tests of the per-receiver accuracy estimate from recurring echoes (fusion.active.noise)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.active.noise import NoiseEstimator, range_sum_and_bearing
from fusion.active.types import Ping
from fusion.simulate.multistatic import bistatic_position

SRC = np.zeros(2)
RCV = np.array([6000.0, 1000.0])


def _pings(sigma_rho, sigma_deg, *, n_pings=15, n_features=6, n_clutter=10, seed=0):
    """Fixed features echoing on every ping with range-sum and bearing errors, plus clutter."""
    rng = np.random.default_rng(seed)
    feats = rng.uniform(-8000, 8000, (n_features, 2))
    rho0, th0 = range_sum_and_bearing(feats, SRC, RCV)
    pings = []
    for k in range(n_pings):
        xy = bistatic_position(SRC, RCV, rho0 + rng.normal(0, sigma_rho, n_features),
                               th0 + np.radians(rng.normal(0, sigma_deg, n_features)))
        xy = np.vstack([xy, rng.uniform(-9000, 9000, (n_clutter, 2))])
        n = xy.shape[0]
        geo = {"src_x": np.zeros(n), "src_y": np.zeros(n), "rcv_x": np.full(n, RCV[0]),
               "rcv_y": np.full(n, RCV[1])}
        pings.append(Ping(k, 90.0 * k, xy, geo))
    return pings


def test_range_sum_and_bearing_inverts_the_bistatic_position():
    """The measured quantities recovered from positions equal those the positions came from."""
    rng = np.random.default_rng(1)
    rho = np.hypot(*RCV) + rng.uniform(1500, 9000, 20)
    th = rng.uniform(-np.pi, np.pi, 20)
    r, t = range_sum_and_bearing(bistatic_position(SRC, RCV, rho, th), SRC, RCV)
    assert_allclose(r, rho, rtol=1e-9)
    assert_allclose(np.angle(np.exp(1j * (t - th))), 0.0, atol=1e-9)


@pytest.mark.parametrize("sigma_rho, sigma_deg", [(60.0, 0.7), (250.0, 1.5)])
@pytest.mark.parametrize("n_clutter, rel", [(0, 0.1), (10, 0.3)])
def test_recovers_the_accuracies(sigma_rho, sigma_deg, n_clutter, rel):
    """Six features over 15 pings, the data alone (no prior weight): within 10 % of the true
    accuracies without clutter, within 30 % with ten clutter echoes per ping (clutter pairs
    with a small bearing difference pass for feature pairs and widen the range-sum estimate:
    errs on the safe side, wider gates)."""
    est = NoiseEstimator(range_sum_sigma_m=100.0, bearing_sigma_deg=1.5, prior_pairs=0.0)
    for p in _pings(sigma_rho, sigma_deg, n_clutter=n_clutter):
        est.update(p)
    e = est.estimate((0.0, 0.0, RCV[0], RCV[1]))
    assert e.range_sum_sigma_m == pytest.approx(sigma_rho, rel=rel)
    assert e.bearing_sigma_deg == pytest.approx(sigma_deg, rel=rel)
    assert e.pairs > 100


def test_prior_weight_known_answer():
    """The variances blend prior and data as n_0 sigma_0^2 + sum w d^2 / 2 over n_0 + sum w:
    checked against the data-only fit (same Gaussian weights) for a 20-pair prior."""
    pings = _pings(120.0, 1.0, n_clutter=0)
    data, prior = NoiseEstimator(prior_pairs=0.0), NoiseEstimator(prior_pairs=20.0)
    for p in pings:
        data.update(p)
        prior.update(p)
    key = (0.0, 0.0, RCV[0], RCV[1])
    d, n = data.estimate(key), data.estimate(key).pairs
    want = np.sqrt((20 * 100.0**2 + n * d.range_sum_sigma_m**2) / (20 + n))
    assert prior.estimate(key).range_sum_sigma_m == pytest.approx(want, rel=0.01)


def test_prior_until_pairs_arrive_and_per_detection_sigmas():
    """Before any pair the estimate is the prior; sigmas() gives every detection its receiver's
    estimate, None without source/receiver positions; reset forgets."""
    est = NoiseEstimator(range_sum_sigma_m=80.0, bearing_sigma_deg=1.2)
    pings = _pings(150.0, 1.0, n_pings=6)
    est.update(pings[0])
    s_rho, s_th = est.sigmas(pings[0])
    assert_allclose(s_rho, 80.0) and assert_allclose(s_th, 1.2)
    for p in pings[1:]:
        est.update(p)
    s_rho, _ = est.sigmas(pings[-1])
    assert np.all(s_rho == s_rho[0]) and abs(s_rho[0] - 80.0) > 10.0
    assert est.sigmas(Ping(0, 0.0, [[0.0, 0.0]])) is None
    est.reset()
    assert est.estimates() == {}


@pytest.mark.parametrize("kwargs, match", [
    ({"range_sum_sigma_m": 0.0}, "range_sum_sigma_m"), ({"prior_pairs": -1.0}, "prior_pairs"),
    ({"lag_pings": 0}, "lag_pings"), ({"max_pairs": 5}, "max_pairs")])
def test_bad_options(kwargs, match):
    """Bad options raise ValueError naming the option."""
    with pytest.raises(ValueError, match=match):
        NoiseEstimator(**kwargs)
