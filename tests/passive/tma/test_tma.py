"""Tests of bearings-only target motion analysis (fusion.passive.tma, fusion.simulate.tma, CLI)."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.target import target_bearing, target_bearing_jacobian
from fusion.io import read_table, write_table
from fusion.passive.tma import (
    BearingsOnlyTMA,
    OwnshipTrack,
    ownship_manoeuvre,
    range_rel_sigma,
)
from fusion.simulate.tma import simulate_tma, write_scenario

SHORT = {"duration_s": 1200.0, "period_s": 30.0}


def _track(sc) -> OwnshipTrack:
    return OwnshipTrack(sc.ownship_times, sc.ownship_xy)


def _clean(sc) -> np.ndarray:
    d = sc.truth[:, :2] - sc.ownship_at_bearings
    return np.arctan2(d[:, 0], d[:, 1])


@pytest.mark.parametrize("motion", ["single", "chain"])
def test_recovers_noiseless_target(motion):
    """Noiseless bearings after an own-ship turn give the true track (both target models)."""
    sc = simulate_tma(seed=4, bearing_sigma_deg=0.0, **SHORT)
    res = BearingsOnlyTMA(bearing_sigma_deg=0.5, motion=motion).estimate(
        sc.times, _clean(sc), _track(sc)
    )
    assert res.observable and res.reason == ""
    assert res.motion == motion
    assert_allclose(res.states[:, :2], sc.truth[:, :2], atol=0.5)
    assert_allclose(res.states[:, 2:], sc.truth[:, 2:], atol=2e-3)
    assert_allclose(res.range, sc.true_range, rtol=1e-4)
    assert res.bearing_rms_deg < 1e-4


def test_single_state_covariance_matches_independent_information():
    """Marginal covariance at the first time equals (J^T J / sigma^2 + prior)^-1 from numpy."""
    sc = simulate_tma(seed=9, bearing_sigma_deg=1.0, **SHORT)
    tma = BearingsOnlyTMA(bearing_sigma_deg=1.0, noise="given")
    res = tma.estimate(sc.times, sc.bearings, _track(sc))
    own = sc.ownship_at_bearings
    J = target_bearing_jacobian(res.states[0], own, dt=sc.times - sc.times[0])
    info = J.T @ J / np.radians(1.0) ** 2 + np.diag([1e-10, 1e-10, 1e-4, 1e-4])
    # GTSAM linearizes the bearing residual as well; at the optimum both agree to first order
    assert_allclose(res.covariances[0], np.linalg.inv(info), rtol=1e-6, atol=1e-9)
    # the covariance propagates as F P F^T: the final position variance exceeds the first one's
    assert np.all(np.linalg.eigvalsh(res.covariances[-1]) > 0)


def test_noisy_estimate_within_a_few_sigma():
    """With 1 deg noise the final state error is within the reported covariance (NEES < 20)."""
    for seed in (1, 2, 3):
        sc = simulate_tma(seed=seed, **SHORT)
        res = BearingsOnlyTMA(bearing_sigma_deg=1.0).estimate(sc.times, sc.bearings, _track(sc))
        e = res.states[-1] - sc.truth[-1]
        assert e @ np.linalg.solve(res.covariances[-1], e) < 20.0
        assert abs(res.range[-1] / sc.true_range[-1] - 1.0) < 0.2


def test_unobservable_without_manoeuvre_warns(caplog):
    """A straight constant-speed own-ship is flagged unobservable with one warning."""
    sc = simulate_tma(seed=5, manoeuvre=False, **SHORT)
    with caplog.at_level(logging.WARNING, logger="fusion.passive.tma"):
        res = BearingsOnlyTMA().estimate(sc.times, sc.bearings, _track(sc))
    assert not res.observable
    assert "did not manoeuvre" in res.reason
    assert res.ownship_manoeuvre_m < 1e-6
    assert res.range_rel_sigma == np.inf
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "unobservable" in warnings[0].getMessage()


def test_chain_falls_back_to_single_without_manoeuvre(caplog):
    """The chain model switches to the single state when the own-ship does not manoeuvre."""
    sc = simulate_tma(seed=6, manoeuvre=False, **SHORT)
    with caplog.at_level(logging.ERROR):
        res = BearingsOnlyTMA(motion="chain").estimate(sc.times, sc.bearings, _track(sc))
    assert res.motion == "single" and not res.observable
    assert np.min(res.range) > 1.0


def test_observable_case_does_not_warn(caplog):
    """No warning when the own-ship turned."""
    sc = simulate_tma(seed=7, **SHORT)
    with caplog.at_level(logging.WARNING, logger="fusion.passive.tma"):
        res = BearingsOnlyTMA().estimate(sc.times, sc.bearings, _track(sc))
    assert res.observable and res.range_rel_sigma < 0.3
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_robust_loss_resists_an_outlier():
    """A 40 deg outlier bearing pulls the plain solution more than the Huber one."""
    sc = simulate_tma(seed=2, bearing_sigma_deg=0.0, **SHORT)
    z = _clean(sc).copy()
    z[20] += np.radians(40.0)
    err = {}
    for robust in (None, "huber"):
        res = BearingsOnlyTMA(bearing_sigma_deg=0.5, robust=robust).estimate(
            sc.times, z, _track(sc)
        )
        err[robust] = np.hypot(*(res.states[-1, :2] - sc.truth[-1, :2]))
    assert err["huber"] < 0.2 * err[None]


def test_tukey_loss_is_tukey_and_rejects_a_gross_outlier():
    """The one graph solve uses Tukey itself: a 40 deg outlier gets zero weight, so the estimate
    equals the one without that bearing; Cauchy's bounded, non-zero influence moves it."""
    sc = simulate_tma(seed=2, **SHORT)
    z = sc.bearings.copy()
    z[20] += np.radians(40.0)
    keep = np.arange(z.size) != 20
    moved = {}
    for robust in ("tukey", "cauchy"):
        tma = BearingsOnlyTMA(bearing_sigma_deg=1.0, robust=robust)
        with_outlier = tma.estimate(sc.times, z, _track(sc)).states[-1]
        without = tma.estimate(sc.times[keep], sc.bearings[keep], _track(sc)).states[-1]
        moved[robust] = float(np.hypot(*(with_outlier[:2] - without[:2])))
    assert moved["tukey"] < 0.01
    assert moved["cauchy"] > 0.1


def test_ownship_manoeuvre_and_range_information():
    """CV own-ship: zero departure and infinite relative range sigma; a turn makes both finite."""
    t = np.linspace(0.0, 600.0, 31)
    straight = np.column_stack([3.0 * t, 4.0 * t])
    assert ownship_manoeuvre(t, straight) < 1e-9
    target = np.array([2000.0, 5000.0, -1.0, 2.0])
    assert range_rel_sigma(target, straight[0], t, straight, np.radians(1.0)) == np.inf
    turned = np.column_stack([np.where(t < 300, 0.0, 5 * (t - 300)), 5 * np.minimum(t, 300)])
    assert ownship_manoeuvre(t, turned) > 100.0
    rel = range_rel_sigma(target, turned[0], t, turned, np.radians(1.0))
    assert 0.0 < rel < 0.5


def test_ownship_track_interpolates_and_validates():
    """Linear interpolation inside the track; times outside or not increasing are ValueErrors."""
    track = OwnshipTrack(np.array([0.0, 10.0]), np.array([[0.0, 0.0], [10.0, -20.0]]))
    assert_allclose(track.at([5.0]), [[5.0, -10.0]])
    with pytest.raises(ValueError, match="outside the own-ship track"):
        track.at([11.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        OwnshipTrack(np.array([0.0, 0.0]), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="shape"):
        OwnshipTrack(np.array([0.0, 1.0]), np.zeros((2, 3)))


def test_estimate_bad_input():
    """Too few bearings, mismatched lengths, NaN and bad options are ValueErrors."""
    track = OwnshipTrack(np.array([0.0, 100.0]), np.array([[0.0, 0.0], [100.0, 0.0]]))
    tma = BearingsOnlyTMA()
    with pytest.raises(ValueError, match="at least 4 bearings"):
        tma.estimate([0.0, 1.0, 2.0], [0.1, 0.2, 0.3], track)
    with pytest.raises(ValueError, match="5 bearing times but 4"):
        tma.estimate(np.arange(5.0), np.zeros(4), track)
    with pytest.raises(ValueError, match="finite"):
        tma.estimate(np.arange(5.0), [0.1, np.nan, 0.1, 0.1, 0.1], track)
    with pytest.raises(ValueError, match="strictly increasing"):
        tma.estimate([0.0, 2.0, 1.0, 3.0], np.zeros(4), track)
    with pytest.raises(ValueError, match="motion"):
        BearingsOnlyTMA(motion="zigzag")
    with pytest.raises(ValueError, match="bearing_sigma_deg"):
        BearingsOnlyTMA(bearing_sigma_deg=0.0)
    with pytest.raises(ValueError, match="robust"):
        BearingsOnlyTMA(robust="l1")


def test_simulator_is_seeded_and_consistent():
    """Same seed, same scenario; noiseless bearings are the true ones; the own-ship turns."""
    a = simulate_tma(seed=12, **SHORT)
    b = simulate_tma(seed=12, **SHORT)
    assert_allclose(a.bearings, b.bearings)
    c = simulate_tma(seed=12, bearing_sigma_deg=0.0, **SHORT)
    assert_allclose(c.bearings, target_bearing(c.truth, c.ownship_at_bearings), atol=1e-12)
    assert ownship_manoeuvre(c.ownship_times, c.ownship_xy) > 100.0
    assert np.all((c.true_range[0] >= 3000.0) & (c.true_range[0] <= 8000.0))


def test_cli_round_trip(tmp_path, run_cli):
    """simulate tma -> fusion tma writes the section-8 columns with a good final range."""
    code, out, _ = run_cli("simulate", "tma", "--seed", "3", "--out", tmp_path)
    assert code == 0 and "bearings.csv" in out
    code, _, err = run_cli(
        "tma", "--bearings", tmp_path / "bearings.csv", "--ownship", tmp_path / "ownship.csv",
        "--out", tmp_path / "t.csv",
    )
    assert code == 0, err
    cols = ("time", "x", "y", "vx", "vy", "sigma_x", "sigma_y", "range")
    est = read_table(tmp_path / "t.csv", required=cols)
    truth = read_table(tmp_path / "truth.csv", required=("time", "x", "y", "range"))
    assert_allclose(est["time"], truth["time"])
    assert abs(est["range"][-1] / truth["range"][-1] - 1.0) < 0.1
    assert np.all(est["sigma_x"] > 0)


def test_cli_unobservable_warns(tmp_path, run_cli, caplog):
    """A straight own-ship track still writes output, with one unobservability warning."""
    sc = simulate_tma(seed=1, manoeuvre=False, **SHORT)
    write_table(tmp_path / "b.csv", {"time": sc.times, "bearing_deg": np.degrees(sc.bearings)})
    write_table(tmp_path / "o.csv", {"time": sc.ownship_times, "x": sc.ownship_xy[:, 0],
                                     "y": sc.ownship_xy[:, 1]})
    with caplog.at_level(logging.WARNING):
        code, _, _ = run_cli("tma", "--bearings", tmp_path / "b.csv", "--ownship",
                             tmp_path / "o.csv", "--out", tmp_path / "t.csv")
    assert code == 0
    assert (tmp_path / "t.csv").exists()
    assert len([r for r in caplog.records if "unobservable" in r.getMessage()]) == 1


def test_cli_bad_input_exit_2(tmp_path, run_cli):
    """Missing column, bearings outside the own-ship track and a missing file: exit 2, one line."""
    write_scenario(tmp_path, seed=0)
    write_table(tmp_path / "bad.csv", {"time": [0.0, 1.0], "bearing": [1.0, 2.0]})
    late = read_table(tmp_path / "bearings.csv", required=("time", "bearing_deg"))
    write_table(tmp_path / "late.csv",
                {"time": late["time"] + 1e4, "bearing_deg": late["bearing_deg"]})
    cases = [
        ("bad.csv", "bearing_deg"),
        ("late.csv", "outside the own-ship track"),
        ("missing.csv", "missing.csv"),
    ]
    for name, expected in cases:
        code, out, err = run_cli("tma", "--bearings", tmp_path / name, "--ownship",
                                 tmp_path / "ownship.csv", "--out", tmp_path / "o.csv")
        assert code == 2
        assert len(err.strip().splitlines()) == 1 and expected in err
        assert not (tmp_path / "o.csv").exists()


def test_one_graph_solve(monkeypatch):
    """Each estimate is one Levenberg-Marquardt run on the graph (no first-pass solver)."""
    import gtsam

    import fusion.passive.tma.estimator as tma_module

    runs = []
    real = gtsam.LevenbergMarquardtOptimizer

    def counting(*args):
        runs.append(args[0].size())
        return real(*args)

    monkeypatch.setattr(tma_module.gtsam, "LevenbergMarquardtOptimizer", counting)
    sc = simulate_tma(seed=3, **SHORT)
    for motion, n_factors in (("single", 2), ("chain", None)):
        runs.clear()
        res = BearingsOnlyTMA(bearing_sigma_deg=1.0, motion=motion).estimate(
            sc.times, sc.bearings, _track(sc))
        assert res.motion == motion and len(runs) == 1
        if n_factors is not None:
            assert runs[0] == n_factors  # prior + one vector bearing factor
    assert not hasattr(tma_module, "least_squares")
