"""Tests of the factor-graph smoothing of active tracks (fusion.active.smoothing, track --smooth)."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from filterpy.common import Q_continuous_white_noise
from filterpy.kalman import KalmanFilter, rts_smoother
from numpy.testing import assert_allclose

from fusion.active.pilot import fitted_tracker_options
from fusion.active.smoothing import (
    TrackSmoother,
    position_factor,
    smooth_tracks,
    velocity_prior_factor,
)
from fusion.active.tracker import Tracker
from fusion.active.types import pings_from_columns
from fusion.io import read_table, write_table
from fusion.simulate.multistatic import simulate_multistatic

Q_PSD, SPEED_SIGMA = 0.04, 3.0


def _random_covariances(rng, n):
    A = rng.normal(0.0, 40.0, (n, 2, 2))
    return A @ np.swapaxes(A, 1, 2) + np.eye(2) * 100.0


def _linear_gaussian_run(seed, n=25):
    """A constant-velocity target, irregular ping times, full per-detection covariances, misses."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(np.r_[0.0, rng.uniform(30.0, 120.0, n - 1)])
    p = np.array([1000.0, -2000.0]) + np.outer(t, [2.5, 1.5]) + rng.normal(0, 20, (n, 2))
    R = _random_covariances(rng, n)
    z = np.array([rng.multivariate_normal(p[k], R[k]) for k in range(n)])
    z[rng.uniform(size=n) < 0.25] = np.nan
    z[0] = p[0]
    return t, z, R


def _filterpy_rts(t, z, R):
    """filterpy's Kalman filter from the birth detection + RTS smoother (independent F and Q)."""
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x = np.r_[z[0], 0.0, 0.0]
    kf.P = np.zeros((4, 4))
    kf.P[:2, :2] = R[0]
    kf.P[2:, 2:] = np.eye(2) * SPEED_SIGMA**2
    kf.H = np.hstack([np.eye(2), np.zeros((2, 2))])
    xs, ps, fs, qs = [kf.x.copy()], [kf.P.copy()], [], []
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        F = np.eye(4)
        F[0, 2] = F[1, 3] = dt
        Q = Q_continuous_white_noise(dim=2, dt=dt, spectral_density=Q_PSD, block_size=2,
                                     order_by_dim=False)
        kf.predict(F=F, Q=Q)
        if np.all(np.isfinite(z[k])):
            kf.update(z[k], R=R[k])
        fs.append(F)
        qs.append(Q)
        xs.append(kf.x.copy())
        ps.append(kf.P.copy())
    fs.append(np.eye(4))  # filterpy applies Fs[k], Qs[k] from step k to k + 1; the last is unused
    qs.append(np.zeros((4, 4)))
    return rts_smoother(np.array(xs), np.array(ps), fs, qs)[:2], np.array(xs)


@pytest.mark.parametrize("seed", range(3))
def test_graph_equals_filterpy_rts_smoother(seed):
    """On linear-Gaussian data the graph's states and marginal covariances equal filterpy's
    Kalman filter + Rauch-Tung-Striebel smoother with the same model and detections."""
    t, z, R = _linear_gaussian_run(seed)
    (x_ref, P_ref), _ = _filterpy_rts(t, z, R)
    sm = TrackSmoother(accel_psd=Q_PSD, speed_sigma_mps=SPEED_SIGMA).smooth(t, z, R)
    assert_allclose(sm.time, t)
    assert_allclose(sm.state, x_ref, rtol=1e-8, atol=1e-8)
    assert_allclose(sm.covariance, P_ref, rtol=1e-8, atol=1e-8)


def test_linearisation_point_does_not_matter():
    """The factors are linear: starting from the filter's states or from the detections gives
    the same solution."""
    t, z, R = _linear_gaussian_run(7)
    _, x_filter = _filterpy_rts(t, z, R)
    sm = TrackSmoother(accel_psd=Q_PSD, speed_sigma_mps=SPEED_SIGMA)
    a, b = sm.smooth(t, z, R), sm.smooth(t, z, R, initial=x_filter + 500.0)
    assert_allclose(a.state, b.state, rtol=1e-9, atol=1e-7)
    assert_allclose(a.covariance, b.covariance, rtol=1e-9)


def test_detections_of_one_time_share_a_state():
    """Two detections at one time equal one detection with their information-weighted mean and
    combined covariance."""
    rng = np.random.default_rng(2)
    R = _random_covariances(rng, 4)
    z = np.array([[0.0, 0.0], [200.0, 40.0], [230.0, 10.0], [410.0, 30.0]])
    t = np.array([0.0, 90.0, 90.0, 180.0])
    W1, W2 = np.linalg.inv(R[1]), np.linalg.inv(R[2])
    R12 = np.linalg.inv(W1 + W2)
    z12 = R12 @ (W1 @ z[1] + W2 @ z[2])
    sm = TrackSmoother()
    two = sm.smooth(t, z, R)
    one = sm.smooth(t[[0, 1, 3]], np.array([z[0], z12, z[3]]), np.array([R[0], R12, R[3]]))
    assert two.time.size == 3
    assert_allclose(two.state, one.state, rtol=1e-10, atol=1e-9)
    assert_allclose(two.covariance, one.covariance, rtol=1e-10)


def test_position_and_velocity_factors_known_error():
    """Factor errors are 0.5 r^T C^-1 r with r = Hx - z (position) and r = v (velocity prior)."""
    rng = np.random.default_rng(4)
    C = _random_covariances(rng, 1)[0]
    z = np.array([100.0, -50.0])
    x = rng.normal(0, 100, 4)
    values = gtsam.Values()
    values.insert(3, x)
    f = position_factor(3, z, C, estimate=rng.normal(0, 100, 4))
    r = x[:2] - z
    assert f.error(values) == pytest.approx(0.5 * r @ np.linalg.solve(C, x[:2] - z), rel=1e-12)
    g = velocity_prior_factor(3, 2.0, estimate=np.zeros(4))
    assert g.error(values) == pytest.approx(0.5 * x[2:] @ x[2:] / 4.0, rel=1e-12)


def test_bad_inputs():
    """Bad options and tracks raise ValueError naming the problem."""
    with pytest.raises(ValueError, match="accel_psd"):
        TrackSmoother(accel_psd=0.0)
    with pytest.raises(ValueError, match="speed_sigma_mps"):
        TrackSmoother(speed_sigma_mps=-1.0)
    sm = TrackSmoother()
    eye = np.broadcast_to(np.eye(2) * 100.0, (2, 2, 2))
    with pytest.raises(ValueError, match="birth"):
        sm.smooth([0.0, 60.0], [[np.nan, np.nan], [0.0, 0.0]], eye)
    with pytest.raises(ValueError, match="non-decreasing"):
        sm.smooth([60.0, 0.0], [[0.0, 0.0], [0.0, 0.0]], eye)
    with pytest.raises(ValueError, match="positive definite"):
        sm.smooth([0.0, 60.0], [[0.0, 0.0], [1.0, 0.0]], np.zeros((2, 2, 2)))


def _tracked(seed):
    sc = simulate_multistatic(seed=seed)
    tracker = Tracker()
    result = tracker.run(sc.detections)
    smoother = TrackSmoother(accel_psd=tracker.accel_psd, speed_sigma_mps=tracker.speed_sigma_mps)
    return sc, result, smooth_tracks(result, smoother)


def test_last_smoothed_state_is_the_filter_state():
    """The tracker's filter is the graph's forward pass: at each confirmed track's last row the
    smoothed state equals the filtered one; rows of other tracks are unchanged."""
    _, result, sm = _tracked(0)
    filt = result.columns()
    ids = result.confirmed_ids()
    assert ids.size >= 1
    for tid in ids:
        last = np.flatnonzero(filt["track_id"] == tid)[-1]
        for c in ("x", "y", "vx", "vy"):
            assert sm.columns[c][last] == pytest.approx(filt[c][last], rel=1e-8, abs=1e-6)
    other = ~np.isin(filt["track_id"], ids)
    for c in ("x", "y", "vx", "vy"):
        assert_allclose(sm.columns[c][other], filt[c][other], rtol=0, atol=0)
    assert np.array_equal(sm.smoothed, ~other)
    assert np.all(sm.columns["sigma_x"] > 0) and np.all(sm.columns["sigma_y"] > 0)


def _row_origins(detections, result):
    """Origin (target, hotspot, clutter, or none) of each output row's associated detection."""
    ev = np.asarray(detections["event"])
    order = np.argsort(ev, kind="stable")  # the pings' detection order
    origin, ev = np.asarray(detections["origin"])[order], ev[order]
    out = []
    for p in result.pings:
        o = np.full(p.track_id.size, "none", dtype=object)
        hit = p.detection >= 0
        o[hit] = origin[np.searchsorted(ev, p.event) + p.detection[hit]]
        out.append(o)
    return np.concatenate(out)


def test_smoothing_reduces_position_error_on_a_multistatic_run():
    """On simulated multistatic runs (seeds 0-4) the confirmed tracks made of target detections
    only are closer to the truth smoothed than filtered (position RMSE at least 20 % lower), and
    the smoothed sigmas of every confirmed track are never larger than the filter's."""
    err_f, err_s = [], []
    for seed in range(5):
        sc, result, sm = _tracked(seed)
        filt = result.columns()
        origin = _row_origins(sc.detections, result)
        k = filt["event"] - int(sc.truth["event"][0])
        tx, ty = sc.truth["x"][k], sc.truth["y"][k]
        P = np.concatenate([p.covariance for p in result.pings])
        for tid in result.confirmed_ids():
            rows = filt["track_id"] == tid
            assert np.all(sm.columns["sigma_x"][rows] <= np.sqrt(P[rows, 0, 0]) * (1 + 1e-9))
            assert np.all(sm.columns["sigma_y"][rows] <= np.sqrt(P[rows, 1, 1]) * (1 + 1e-9))
            if not np.all(np.isin(origin[rows], ("target", "none"))):
                continue  # took a clutter or hotspot echo: the truth is not its target
            err_f.append(np.hypot(filt["x"][rows] - tx[rows], filt["y"][rows] - ty[rows]))
            err_s.append(np.hypot(sm.columns["x"][rows] - tx[rows],
                                  sm.columns["y"][rows] - ty[rows]))
    rmse_f = np.sqrt(np.mean(np.concatenate(err_f) ** 2))
    rmse_s = np.sqrt(np.mean(np.concatenate(err_s) ** 2))
    assert len(err_f) >= 4
    assert rmse_s < 0.8 * rmse_f


def test_cli_smooth_appends_sigmas(tmp_path, run_cli):
    """fusion track --smooth writes the formats.md columns plus sigma_x, sigma_y; confirmed
    tracks' rows are the smoothed ones, the others as without --smooth."""
    sc = simulate_multistatic(seed=1)
    write_table(tmp_path / "d.csv", sc.detections.columns)
    code, _, err = run_cli("track", "--detections", tmp_path / "d.csv", "--out",
                           tmp_path / "plain.csv")
    assert code == 0, err
    code, _, err = run_cli("track", "--detections", tmp_path / "d.csv", "--out",
                           tmp_path / "smooth.csv", "--smooth")
    assert code == 0, err
    cols = ("track_id", "event", "time", "x", "y", "vx", "vy", "status")
    plain = read_table(tmp_path / "plain.csv", required=cols, text=("status",))
    smooth = read_table(tmp_path / "smooth.csv", required=(*cols, "sigma_x", "sigma_y"),
                        text=("status",))
    assert len(plain) == len(smooth)
    # The command's tracker: the scales read from the detections, the pilot speed prior.
    tracker = Tracker(**fitted_tracker_options(pings_from_columns(sc.detections)))
    result = tracker.run(sc.detections)
    want = smooth_tracks(result, TrackSmoother(accel_psd=tracker.accel_psd,
                                               speed_sigma_mps=tracker.speed_sigma_mps)).columns
    assert_allclose(smooth["x"], want["x"], rtol=1e-6)
    assert_allclose(smooth["sigma_y"], want["sigma_y"], rtol=1e-6)
    changed = ~np.isclose(plain["x"], smooth["x"], rtol=0, atol=1e-6)
    assert changed.any()
    assert set(np.unique(plain["track_id"][changed])) <= set(result.confirmed_ids().tolist())
    code, _, err = run_cli("track", "--detections", tmp_path / "d.csv", "--out",
                           tmp_path / "bad.csv", "--smooth", "--accel-psd-m2-per-s3", "0")
    assert code == 2 and "--accel-psd-m2-per-s3" in err
