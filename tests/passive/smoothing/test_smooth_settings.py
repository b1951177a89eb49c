"""Tests of the data-fitted settings of ``fusion smooth`` and of same-scan merging."""

import csv
import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.passive.smoothing.merge import merge_scan_detections
from fusion.passive.smoothing.settings import (
    fit_smooth_settings,
    lag_diffusion,
    pair_scatter,
    rate_diffusion,
    second_difference_sigma,
)

SIGMA = np.radians(1.0)


def _cluttered(seed, *, sigma=SIGMA, clutter=3.0, n_scans=400, period=1.0):
    """Three straight bearing tracks seen every scan plus Poisson clutter uniform in bearing."""
    rng = np.random.default_rng(seed)
    t, z = [], []
    for k in range(n_scans):
        tk = k * period
        for b0, rate in ((0.3, 2e-4), (1.5, -3e-4), (-2.0, 1e-4)):
            t.append(tk)
            z.append(b0 + rate * tk + rng.normal(0, sigma))
        for _ in range(rng.poisson(clutter)):
            t.append(tk)
            z.append(rng.uniform(-np.pi, np.pi))
    return np.array(t), np.angle(np.exp(1j * np.array(z)))


def test_pair_scatter_recovers_noise_and_clutter():
    """Noise within 10 % and clutter density within 30 % of the simulated 1 deg, 3/scan/2pi."""
    t, z = _cluttered(0)
    sigma, clutter, frac = pair_scatter(t, z)
    assert_allclose(sigma, SIGMA, rtol=0.10)
    assert_allclose(clutter, 3.0 / (2 * np.pi), rtol=0.30)
    assert 0 < frac < 1


def test_pair_scatter_ignores_repeated_scans():
    """A scan sent twice (identical bearings) does not collapse the noise estimate."""
    t, z = _cluttered(1, clutter=1.0)
    t2 = np.r_[t, t + 0.5]  # every scan repeated half a period later
    z2 = np.r_[z, z]
    order = np.argsort(t2, kind="stable")
    sigma, _, _ = pair_scatter(t2[order], z2[order])
    assert sigma > 0.5 * SIGMA


def test_second_difference_sigma_known_answer():
    """White noise of 0.7 deg on smooth tracks: second-difference estimate within 8 %."""
    rng = np.random.default_rng(2)
    groups = []
    for _ in range(3):
        t = np.arange(500.0)
        z = 0.4 + 1e-3 * t + 2e-7 * t**2 + rng.normal(0, np.radians(0.7), t.size)
        groups.append((t, z))
    assert_allclose(second_difference_sigma(groups), np.radians(0.7), rtol=0.08)


def test_rate_diffusion_recovers_q():
    """A white-noise-acceleration bearing with q = 1e-7 rad^2/s^3: estimate within a factor 1.6."""
    rng = np.random.default_rng(3)
    q, dt, sigma = 1e-7, 1.0, np.radians(0.2)
    groups = []
    for _ in range(20):
        n = 600
        acc = rng.normal(0, np.sqrt(q / dt), n)
        rate = np.cumsum(acc) * dt
        theta = np.cumsum(rate) * dt
        t = np.arange(n) * dt
        groups.append((t, theta + rng.normal(0, sigma, n)))
    q_est, rates = rate_diffusion(groups, sigma=sigma, block_s=20.0)
    assert q / 1.6 < q_est < q * 1.6
    assert rates.size > 100


def _white_acceleration_tracks(seed, *, q, sigma, n_tracks=8, n=2000, period=10.0, p_detect=0.85):
    """Bearing tracks whose rate is a random walk of PSD ``q`` (exact discretisation), noisy."""
    rng = np.random.default_rng(seed)
    f = np.array([[1.0, period], [0.0, 1.0]])
    chol = np.linalg.cholesky(q * np.array([[period**3 / 3, period**2 / 2],
                                            [period**2 / 2, period]]))
    groups = []
    for _ in range(n_tracks):
        steps = (chol @ rng.normal(size=(2, n)))
        x = np.zeros((2, n))
        x[:, 0] = [rng.uniform(-np.pi, np.pi), rng.normal(0.0, 1e-3)]
        for k in range(1, n):
            x[:, k] = f @ x[:, k - 1] + steps[:, k]
        t = np.arange(n) * period
        keep = rng.random(n) < p_detect  # missed scans: uneven gaps
        z = np.angle(np.exp(1j * (x[0] + rng.normal(0.0, sigma, n))))
        groups.append((t[keep], z[keep]))
    return groups


@pytest.mark.parametrize("q_deg", [1e-8, 1e-7, 1e-6, 1e-5, 1e-4])
def test_lag_diffusion_recovers_q_and_noise(q_deg):
    """Known q (1e-8..1e-4 deg^2/s^3, 10 s scans, 0.5 deg): q within x1.5, noise within 20 %."""
    deg2 = np.radians(1.0) ** 2
    sigma = np.radians(0.5)
    groups = _white_acceleration_tracks(int(-np.log10(q_deg)), q=q_deg * deg2, sigma=sigma)
    q_est, sigma_est = lag_diffusion(groups)
    assert q_deg / 1.5 < q_est / deg2 < q_deg * 1.5
    assert_allclose(sigma_est, sigma, rtol=0.20)


def test_lag_diffusion_follows_curvature_of_long_tracks():
    """A 5.5 h curving bearing: the fitted q lets the smoother follow it (RMS miss ~ noise)."""
    from fusion.passive.smoothing.batch import BearingSmoother

    rng = np.random.default_rng(11)
    sigma = np.radians(0.5)
    t = np.arange(2000) * 10.0
    # closest approach of a straight-line target at 3 km, 5 m/s, half-way through
    truth = np.arctan2(5.0 * (t - t.mean()), 3000.0)
    z = truth + rng.normal(0.0, sigma, t.size)
    q_est, _ = lag_diffusion([(t, z)])
    q_old, _ = rate_diffusion([(t, z)], sigma=sigma, block_s=100.0)
    assert q_est > 10 * q_old  # consecutive blocks see mostly noise
    fit = BearingSmoother(sigma_bearing=sigma, q=q_est, robust="huber").smooth(t, z)
    rms = np.sqrt(np.mean(np.angle(np.exp(1j * (fit.bearing - z))) ** 2))
    assert rms < 1.05 * sigma


def test_fit_raises_q_for_long_curving_tracks():
    """Labelled 5.5 h curving tracks: the fitted q is the lag fit, far above the block rates'."""
    rng = np.random.default_rng(12)
    t = np.arange(2000) * 10.0
    ids, times, z = [], [], []
    for k, (r, v) in enumerate(((3000.0, 5.0), (4000.0, 4.0), (5000.0, 6.0))):
        ids.append(np.full(t.size, k))
        times.append(t)
        z.append(np.arctan2(v * (t - t.mean()), r) + rng.normal(0.0, np.radians(0.5), t.size))
    st = fit_smooth_settings(np.concatenate(ids), np.concatenate(times), np.concatenate(z))
    groups = [(t, zk) for zk in z]
    sigma = np.radians(st.sigma_bearing_deg)
    q_lags, _ = lag_diffusion(groups, sigma=sigma)
    q_rates, _ = rate_diffusion(groups, sigma=sigma, block_s=100.0)
    assert_allclose(st.q_deg2_per_s3, q_lags / np.radians(1.0) ** 2, rtol=1e-9)
    assert q_lags > 4 * max(q_rates, 3e-6 * sigma**2 / 10.0**3)


def test_fit_keeps_block_q_when_the_lags_agree():
    """White-acceleration tracks: the lags agree with the block rates, whose q is kept."""
    deg2 = np.radians(1.0) ** 2
    groups = _white_acceleration_tracks(5, q=1e-5 * deg2, sigma=np.radians(0.5), n_tracks=4,
                                        n=800, p_detect=1.0)
    ids = np.concatenate([np.full(t.size, k) for k, (t, _) in enumerate(groups)])
    st = fit_smooth_settings(ids, np.concatenate([t for t, _ in groups]),
                             np.concatenate([z for _, z in groups]))
    q_rates, _ = rate_diffusion(groups, sigma=np.radians(st.sigma_bearing_deg), block_s=100.0)
    assert_allclose(st.q_deg2_per_s3 * deg2, q_rates, rtol=1e-9)
    assert 1e-5 / 2 < st.q_deg2_per_s3 < 1e-5 * 2


def test_lag_diffusion_without_long_tracks_is_nan():
    """Tracks shorter than three lag windows give no estimate (nan), not a guess."""
    t = np.arange(30.0)
    assert np.isnan(lag_diffusion([(t, 1e-3 * t)])[0])


def test_fit_keeps_given_values_and_names_estimates():
    """Given settings are kept and not marked estimated; the others are estimated."""
    t, z = _cluttered(4, n_scans=150)
    st = fit_smooth_settings(np.full(t.size, -1), t, z, sigma_bearing_deg=0.8, p_detect=0.7)
    assert st.sigma_bearing_deg == 0.8 and st.p_detect == 0.7
    assert "sigma_bearing_deg" not in st.estimated and "p_detect" not in st.estimated
    assert {"q_deg2_per_s3", "clutter_density", "period_s", "max_misses"} <= set(st.estimated)
    assert_allclose(st.period_s, 1.0)
    assert st.max_misses >= 4  # at least max_miss_s = 4 s at 1 s per scan
    assert "(est.)" in st.describe() and "sigma 0.8 deg," in st.describe()
    st2 = fit_smooth_settings(np.full(t.size, -1), t, z)
    assert_allclose(st2.sigma_bearing_deg, 1.0, rtol=0.15)


def test_merge_known_answer_and_wrap():
    """Bearings of one scan within the width become their circular mean, also across north."""
    t, z, g = merge_scan_detections([0, 0, 0, 1], np.radians([10, 10.4, 30, 10]),
                                    within=np.radians(1.0))
    assert_allclose(np.degrees(z), [10.2, 30.0, 10.0], atol=1e-9)
    assert g.tolist() == [0, 0, 1, 2] and t.tolist() == [0, 0, 1]
    t, z, g = merge_scan_detections([5, 5], np.radians([359.6, 0.2]), within=np.radians(1.0))
    assert z.size == 1 and abs(np.degrees(z[0]) - (-0.1)) < 1e-9
    t, z, g = merge_scan_detections([0, 0], [0.1, 0.1 + 1e-6], within=0.0)
    assert z.size == 2
    with pytest.raises(ValueError, match="within"):
        merge_scan_detections([0], [0.0], within=-1.0)


def test_cli_prints_and_writes_settings(run_cli, tmp_path):
    """fusion smooth prints the chosen settings in one line and writes them beside the output."""
    t, z = _cluttered(5, n_scans=120, clutter=1.0)
    src = tmp_path / "b.csv"
    with open(src, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["track_id", "time", "bearing_deg"])
        for ti, zi in zip(t, np.degrees(z), strict=True):
            w.writerow([-1, ti, zi])
    code, out, err = run_cli("smooth", "--bearings", src, "--out", tmp_path / "s.csv",
                             "--accel-psd-deg2-per-s3", "1e-4")
    assert code == 0, err
    lines = [ln for ln in out.splitlines() if ln.startswith("fusion smooth:")]
    assert len(lines) == 1 and "sigma" in lines[0] and "(est.)" in lines[0]
    meta = json.loads((tmp_path / "s.settings.json").read_text())
    assert meta["settings"]["q_deg2_per_s3"] == 1e-4
    assert "q_deg2_per_s3" not in meta["settings"]["estimated"]
    assert_allclose(meta["settings"]["sigma_bearing_deg"], 1.0, rtol=0.15)
    assert meta["tracks"] >= 3


def _track(tid, t, theta):
    from fusion.passive.smoothing.types import SmoothedTrack

    n = t.size
    return SmoothedTrack(tid, t, np.angle(np.exp(1j * theta)), np.zeros(n), np.ones(n),
                         np.ones(n))


def test_twin_groups_join_twins_not_crossers():
    """Side-by-side tracks 0.5 deg apart are one group; tracks that cross stay apart."""
    from fusion.passive.smoothing.twins import twin_groups

    t = np.arange(0.0, 100.0)
    a = _track(0, t, np.radians(10 + 0.2 * t))
    twin = _track(1, t[20:90], np.radians(10.5 + 0.2 * t[20:90]))
    crosser = _track(2, t, np.radians(30 - 0.2 * t))  # crosses a at t = 50
    far = _track(3, t, np.radians(-170 + 0.01 * t))
    groups = twin_groups((a, twin, crosser, far), within=np.radians(2.0))
    assert groups == [[0, 1], [2], [3]]
    assert twin_groups((a, twin), within=np.radians(0.2)) == [[0], [1]]
