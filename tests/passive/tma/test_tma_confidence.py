"""Tests of what TMA knows about range: noise-fitted covariance, range interval, flags."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.io import read_table, write_table
from fusion.passive.tma import BearingsOnlyTMA, OwnshipTrack
from fusion.passive.tma.confidence import noise_inflation, range_interval
from fusion.simulate.tma import simulate_tma

SHORT = {"duration_s": 1200.0, "period_s": 30.0}


def test_noise_inflation_white_and_correlated():
    """White residuals of the assumed sigma: scale near 1; AR(1) rho 0.8: about 9x."""
    rng = np.random.default_rng(0)
    sigma = 0.01
    white = rng.normal(0, sigma, 20000)
    scale, rho, s = noise_inflation(white, sigma)
    assert 1.0 <= scale < 1.05 and rho < 0.02
    assert_allclose(s, sigma, rtol=0.02)
    ar = np.zeros(20000)
    e = rng.normal(0, sigma * np.sqrt(1 - 0.8**2), ar.size)
    for k in range(1, ar.size):
        ar[k] = 0.8 * ar[k - 1] + e[k]  # stationary variance sigma^2
    scale, rho, _ = noise_inflation(ar, sigma)
    assert_allclose(rho, 0.8, atol=0.02)
    assert_allclose(scale, 9.0, rtol=0.1)
    assert noise_inflation(0.1 * white, sigma)[0] == 1.0  # never below the given noise


def test_range_interval_known_answer():
    """Line of sight along y: sigma_r is the y sigma; the interval is r exp(-/+ 1.96 s)."""
    states = np.array([[0.0, 1000.0, 1.0, 0.0]])
    cov = np.diag([100.0**2, 50.0**2, 1.0, 1.0])[None]
    low, high, rel = range_interval(states, cov, np.zeros((1, 2)), level=0.95)
    assert_allclose(rel, [0.05])
    assert_allclose(low, 1000.0 * np.exp(-1.959964 * 0.05), rtol=1e-6)
    assert_allclose(high, 1000.0 * np.exp(1.959964 * 0.05), rtol=1e-6)
    with pytest.raises(ValueError, match="level"):
        range_interval(states, cov, np.zeros((1, 2)), level=1.0)


def test_interval_covers_truth_when_observable():
    """Observable simulated cases (1 deg): the 95 % interval holds the true final range."""
    held = 0
    for seed in range(6):
        sc = simulate_tma(seed=seed, **SHORT)
        res = BearingsOnlyTMA().estimate(sc.times, sc.bearings,
                                         OwnshipTrack(sc.ownship_times, sc.ownship_xy))
        assert res.observable, res.reason
        assert res.range_low[-1] < res.range[-1] < res.range_high[-1]
        held += res.range_low[-1] <= sc.true_range[-1] <= res.range_high[-1]
    assert held >= 5


def test_small_manoeuvre_for_the_range_is_flagged(caplog):
    """A 30 deg turn at 0.2 deg/s, 1.5 m/s own-ship, target at 12-15 km: flagged, reason given."""
    sc = simulate_tma(seed=3, duration_s=900.0, period_s=10.0, bearing_sigma_deg=2.0,
                      ownship_speed_mps=1.5, turn_rate_deg_s=0.2, range_m=(12000.0, 15000.0))
    with caplog.at_level(logging.WARNING, logger="fusion.passive.tma"):
        res = BearingsOnlyTMA().estimate(sc.times, sc.bearings,
                                         OwnshipTrack(sc.ownship_times, sc.ownship_xy))
    assert not res.observable
    assert "too small for the range" in res.reason or "ill-conditioned" in res.reason
    assert res.range_high[-1] / res.range_low[-1] > 2.0  # the interval says so too


def test_correlated_noise_widens_the_interval():
    """Slowly wandering bearing errors (AR(1), rho 0.95) scale the covariance up."""
    sc = simulate_tma(seed=2, bearing_sigma_deg=0.0, duration_s=1200.0, period_s=5.0)
    rng = np.random.default_rng(1)
    n = sc.times.size
    wander = np.zeros(n)
    e = rng.normal(0, np.radians(1.0) * np.sqrt(1 - 0.95**2), n)
    for k in range(1, n):
        wander[k] = 0.95 * wander[k - 1] + e[k]
    track = OwnshipTrack(sc.ownship_times, sc.ownship_xy)
    fit = BearingsOnlyTMA().estimate(sc.times, sc.bearings + wander, track)
    given = BearingsOnlyTMA(noise="given").estimate(sc.times, sc.bearings + wander, track)
    assert fit.residual_rho > 0.5
    assert fit.covariance_scale > 2.0 and given.covariance_scale == 1.0
    assert (fit.range_high[-1] - fit.range_low[-1]) > 1.4 * (given.range_high[-1]
                                                            - given.range_low[-1])


def test_cli_writes_interval_and_flag(tmp_path, run_cli):
    """fusion tma writes range_low, range_high, observable and sums up in one line."""
    sc = simulate_tma(seed=1, manoeuvre=False, **SHORT)
    write_table(tmp_path / "b.csv", {"time": sc.times, "bearing_deg": np.degrees(sc.bearings)})
    write_table(tmp_path / "o.csv", {"time": sc.ownship_times, "x": sc.ownship_xy[:, 0],
                                     "y": sc.ownship_xy[:, 1]})
    code, out, err = run_cli("tma", "--bearings", tmp_path / "b.csv", "--ownship",
                             tmp_path / "o.csv", "--out", tmp_path / "t.csv")
    assert code == 0, err
    t = read_table(tmp_path / "t.csv", required=("range", "range_low", "range_high",
                                                 "observable"))
    assert np.all(t["observable"] == 0)
    assert np.all(t["range_low"] <= t["range"]) and np.all(t["range"] <= t["range_high"])
    assert "RANGE UNOBSERVABLE" in out and len(out.strip().splitlines()) == 1
