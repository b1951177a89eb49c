"""Tests of the narrowband bearing tracker."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.common import Q_discrete_white_noise
from numpy.testing import assert_allclose

from fusion.geometry import beam_from_bearing
from fusion.io import Cube
from fusion.passive.tracker import BearingTracker, beamwidth_deg, cell_power_statistics
from fusion.simulate.cube import simulate_cube


@pytest.mark.parametrize(("bearing0", "rate", "seed"), [(60.0, 20.0, 1), (120.0, -30.0, 2),
                                                        (45.0, 15.0, 3)])
def test_follows_a_simulated_line(bearing0, rate, seed):
    """From a correct start the tracker stays within a fraction of a beamwidth of the line."""
    sc = simulate_cube(seed=seed, n_scans=70, bearing0_deg=bearing0,
                       bearing_rate_deg_per_min=rate, snr_db=12.0)
    h = BearingTracker().track(sc.cube, bearing_deg=bearing0, bearing_rate_deg_per_min=rate,
                               freq_hz=sc.click_freq)
    truth = sc.shown_bearing_deg[h.scan]
    err = h.bearing_deg - truth
    bw = beamwidth_deg(truth, wavelength=1500.0 / 300.0, aperture=50.0)
    assert np.sqrt(np.mean(err[10:] ** 2)) < 0.3 * np.mean(bw)
    assert np.all(np.abs(err) < bw)
    assert_allclose(np.mean(h.bearing_rate_deg_per_min[30:]), rate, atol=3.0)
    assert h.scan[0] == 1 and h.scan[-1] == 69
    assert_allclose(h.time, h.scan * sc.cube.scan_period)


def test_catches_up_from_zero_rate():
    """Initialised with rate 0 on a 20 deg/min line, the rate estimate converges to the truth."""
    sc = simulate_cube(seed=4, n_scans=80, bearing0_deg=70.0, bearing_rate_deg_per_min=20.0,
                       snr_db=12.0)
    h = BearingTracker().track(sc.cube, bearing_deg=70.0, bearing_rate_deg_per_min=0.0,
                               freq_hz=sc.click_freq)
    assert_allclose(np.mean(h.bearing_rate_deg_per_min[-20:]), 20.0, atol=4.0)
    assert abs(h.bearing_deg[-1] - sc.shown_bearing_deg[-1]) < 1.5


def test_amplitude_statistics_match_the_model():
    """A(k) on noise alone has mean 1, var 1; on a strong line about 1 + SNR (minus losses)."""
    rng = np.random.default_rng(0)
    power = rng.exponential(1.0, size=(400, 32, 4))
    cube = Cube(power=power, freqs=np.arange(4) + 100.0, scan_period=1.0, aperture=30.0)
    h = BearingTracker().track(cube, bearing_deg=90.0, bearing_rate_deg_per_min=0.0,
                               freq_hz=101.0)
    mean, std = cell_power_statistics(-np.inf)
    assert_allclose(h.amplitude.mean(), mean, rtol=0.15)
    assert_allclose(h.amplitude.std(), std, rtol=0.2)
    sc = simulate_cube(seed=5, n_scans=200, bearing0_deg=90.0, bearing_rate_deg_per_min=0.0,
                       snr_db=10.0, line_offset_bins=0.0, freq_spread_hz=0.0)
    h = BearingTracker().track(sc.cube, bearing_deg=90.0, bearing_rate_deg_per_min=0.0,
                               freq_hz=sc.click_freq)
    mean, std = cell_power_statistics(10.0)
    # the line sits between two beams at most half a beam off: loss below 1 dB
    assert 0.8 * mean < h.amplitude.mean() < 1.05 * mean
    assert 0.7 * std < h.amplitude.std() < 1.2 * std


def test_residual_is_measured_minus_predicted():
    """The residual is the measured bearing minus the predicted one."""
    sc = simulate_cube(seed=6, n_scans=30, bearing0_deg=80.0, bearing_rate_deg_per_min=10.0,
                       snr_db=9.0)
    h = BearingTracker().track(sc.cube, bearing_deg=80.0, bearing_rate_deg_per_min=10.0,
                               freq_hz=sc.click_freq)
    assert_allclose(h.residual_deg, h.measured_bearing_deg - h.predicted_bearing_deg)
    assert_allclose(h.beam, beam_from_bearing(np.radians(h.bearing_deg), 64))
    cols = h.amplitude_columns(track_id=7)
    assert set(cols) == {"track_id", "time", "amplitude", "residual"}
    assert np.all(cols["track_id"] == 7)


def test_kalman_steps_match_textbook_equations():
    """The filterpy-based filter equals the Kalman equations written out with its inputs."""
    sc = simulate_cube(seed=7, n_scans=25, bearing0_deg=100.0, bearing_rate_deg_per_min=-12.0,
                       snr_db=10.0)
    trk = BearingTracker(accel_sigma_deg_per_min2=3.0, beam_sigma=0.4,
                         init_bearing_sigma_deg=1.0, init_rate_sigma_deg_per_min=5.0)
    h = trk.track(sc.cube, bearing_deg=100.0, bearing_rate_deg_per_min=-12.0,
                  freq_hz=sc.click_freq)
    dt, n = sc.cube.scan_period, sc.cube.n_beams
    x = np.array([np.radians(100.0), np.radians(-12.0) / 60.0])
    p = np.diag([np.radians(1.0) ** 2, (np.radians(5.0) / 60.0) ** 2])
    f = np.array([[1.0, dt], [0.0, 1.0]])
    q = Q_discrete_white_noise(2, dt=dt, var=(np.radians(3.0) / 3600.0) ** 2)
    sin_floor = np.sin(np.arccos(1 - 2 * 0.5 / (n - 1)))
    for k in range(len(h)):
        x = f @ x
        p = f @ p @ f.T + q
        assert_allclose(np.degrees(x[0]), h.predicted_bearing_deg[k], atol=1e-9)
        r = (0.4 * 2 / (n - 1) / max(np.sin(x[0]), sin_floor)) ** 2
        s = p[0, 0] + r
        gain = p[:, 0] / s
        x = x + gain * (np.radians(h.measured_bearing_deg[k]) - x[0])
        p = p - np.outer(gain, p[0, :])
        assert_allclose(np.degrees(x[0]), h.bearing_deg[k], atol=1e-9)
        assert_allclose(np.degrees(x[1]) * 60, h.bearing_rate_deg_per_min[k], atol=1e-9)
        assert_allclose(np.degrees(np.sqrt(p[0, 0])), h.bearing_sigma_deg[k], rtol=1e-6)


def test_reproducible():
    """Same cube and start, same track."""
    sc = simulate_cube(seed=8, n_scans=20, snr_db=6.0)
    a = BearingTracker().track(sc.cube, bearing_deg=60.0, bearing_rate_deg_per_min=30.0,
                               freq_hz=sc.click_freq)
    b = BearingTracker().track(sc.cube, bearing_deg=60.0, bearing_rate_deg_per_min=30.0,
                               freq_hz=sc.click_freq)
    assert_allclose(a.bearing_deg, b.bearing_deg)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"bearing_deg": 200.0}, "bearing_deg"),
        ({"freq_hz": 50.0}, "outside the cube's band"),
        ({"init_scan": 19}, "init_scan"),
        ({"n_scans": 30}, "runs past"),
        ({"bearing_rate_deg_per_min": float("nan")}, "finite"),
    ],
)
def test_bad_track_arguments(kwargs, match):
    """Bad starts raise ValueError naming the problem."""
    sc = simulate_cube(seed=9, n_scans=20)
    args = {"bearing_deg": 60.0, "bearing_rate_deg_per_min": 0.0, "freq_hz": sc.click_freq}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        BearingTracker().track(sc.cube, **args)


def test_bad_tracker_options():
    """Non-positive options raise ValueError."""
    with pytest.raises(ValueError, match="beam_sigma"):
        BearingTracker(beam_sigma=0.0)
    with pytest.raises(ValueError, match="search_beams"):
        BearingTracker(search_beams=0)
    with pytest.raises(ValueError, match="n_looks"):
        cell_power_statistics(3.0, n_looks=0)
