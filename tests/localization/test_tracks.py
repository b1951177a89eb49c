"""Tests of source tracking across windows and constant-velocity smoothing."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from numpy.testing import assert_allclose

from factors.motion import transition_matrix, wna_covariance
from fusion.localization.localize import SourceFix
from fusion.localization.tracks import SourceTracker, WindowSources

DT = 2.0


def fix(position, cov, weights=None) -> SourceFix:
    """A window fix with a given covariance (and TDOA weights)."""
    w = np.ones(4) if weights is None else np.asarray(weights, dtype=float)
    return SourceFix(position=np.asarray(position, float), covariance=np.asarray(cov, float),
                     information=np.eye(3), weights=w, tdoas_used=int((w > 0.5).sum()),
                     residual_rms_s=0.0, condition_number=1.0, observable=True,
                     mirror_ambiguous=False, mirror_position=np.full(3, np.nan))


def linear_scene(seed, n=30, std=5.0):
    """Two whales moving in straight lines 600 m apart; noisy fixes every DT seconds."""
    rng = np.random.default_rng(seed)
    t = DT * np.arange(n)
    starts = np.array([[0.0, 0.0, -800.0], [0.0, 600.0, -900.0]])
    vel = np.array([[1.5, 0.5, 0.05], [-1.0, 1.0, -0.1]])
    truth = starts[:, None, :] + vel[:, None, :] * t[None, :, None]  # (2, n, 3)
    cov = np.diag([std**2, std**2, (2 * std) ** 2])
    noise = rng.multivariate_normal(np.zeros(3), cov, (2, n))
    windows = [WindowSources(t[k], tuple(fix(truth[s, k] + noise[s, k], cov) for s in (1, 0)))
               for k in range(n)]
    return windows, truth, vel


def test_linear_motion_recovered_and_smoothed_better_than_raw():
    """Two straight tracks: both recovered whole; smoothed error below raw; velocity found."""
    windows, truth, vel = linear_scene(3)
    tracks = SourceTracker(q=1e-3).track(windows)
    assert len(tracks) == 2
    for tr in tracks:
        assert tr.times.size == len(windows)
        s = int(np.argmin([np.linalg.norm(tr.raw_positions[0] - truth[k, 0]) for k in (0, 1)]))
        raw = np.sqrt(np.mean(np.sum((tr.raw_positions - truth[s]) ** 2, axis=1)))
        smooth = np.sqrt(np.mean(np.sum((tr.positions - truth[s]) ** 2, axis=1)))
        assert smooth < 0.6 * raw
        assert np.all(np.abs(tr.velocities[5:-5] - vel[s]) < 0.3)
        assert np.all(np.trace(tr.covariances, axis1=1, axis2=2) <
                      np.trace(np.diag([25.0, 25.0, 100.0])))


def _rts(t, z, covs, q):
    """filterpy's Kalman filter + RTS smoother of 3-D positions (white-noise acceleration,
    diffuse prior): smoothed states (n, 6) and covariances (n, 6, 6)."""
    kf = KalmanFilter(dim_x=6, dim_z=3)
    kf.x = np.r_[z[0], 0.0, 0.0, 0.0]
    kf.P = np.eye(6) * 1e10
    kf.H = np.hstack([np.eye(3), np.zeros((3, 3))])
    dts = np.r_[1.0, np.diff(t)]
    fs = [transition_matrix(d, 3) for d in dts]
    qs = [wna_covariance(d, q, 3) for d in dts]
    fs[0], qs[0] = np.eye(6), np.zeros((6, 6))  # the first update is at the first time
    mu, cov, _, _ = kf.batch_filter(list(z), Fs=fs, Qs=qs, Rs=covs)
    xs, ps, _, _ = kf.rts_smoother(mu, cov, Fs=fs, Qs=qs)
    return xs, ps


def test_smoother_equals_rts_on_linear_gaussian_data():
    """The factor-graph smoother equals filterpy's Kalman filter + RTS smoother (diffuse prior)."""
    rng = np.random.default_rng(7)
    n, q = 12, 0.02
    t = np.cumsum(rng.uniform(1.5, 2.5, n))
    covs = []
    for _ in range(n):  # full (correlated) fix covariances, as localization gives
        a = rng.normal(0.0, 3.0, (3, 3))
        covs.append(a @ a.T + np.diag(rng.uniform(2.0, 10.0, 3)))
    z = np.array([[1.0 * k, 0.5 * k, -800.0] for k in t]) + rng.normal(0, 4.0, (n, 3))
    windows = [WindowSources(t[k], (fix(z[k], covs[k]),)) for k in range(n)]
    (tr,) = SourceTracker(q=q, max_speed=50.0).track(windows)

    xs, ps = _rts(t, z, covs, q)
    assert_allclose(tr.positions, xs[:, :3], atol=1e-5)
    assert_allclose(tr.velocities, xs[:, 3:], atol=1e-5)  # 1e10 diffuse prior: ~1e-6 rounding
    assert_allclose(tr.covariances, ps[:, :3, :3], rtol=1e-4)


def test_dense_fallback_equals_rts_where_gtsam_refuses(monkeypatch):
    """Where GTSAM's Cholesky refuses (fixes hundreds of metres wide beside a stiff motion
    model), the smoother solves the same linear problem by dense QR: the same answer as
    filterpy's Kalman filter + RTS smoother."""
    import fusion.localization.tracks as tracks_module

    def refuse(*args, **kwargs):
        raise RuntimeError("Indeterminate linear system")

    rng = np.random.default_rng(8)
    n, q = 9, 0.02
    t = np.cumsum(rng.uniform(1.5, 2.5, n))
    covs = [np.diag(rng.uniform(2.0, 10.0, 3)) * 1e4 for _ in range(n)]
    z = np.array([[1.0 * k, 0.5 * k, -800.0] for k in t]) + rng.normal(0, 40.0, (n, 3))
    windows = [WindowSources(t[k], (fix(z[k], covs[k]),)) for k in range(n)]
    monkeypatch.setattr(tracks_module.gtsam, "Marginals", refuse)
    (tr,) = SourceTracker(q=q, max_speed=500.0).track(windows)
    xs, ps = _rts(t, z, covs, q)
    assert_allclose(tr.positions, xs[:, :3], atol=1e-3)
    assert_allclose(tr.covariances, ps[:, :3, :3], rtol=1e-3)


def test_tdoa_links_connect_sources_the_gate_would_split():
    """Jumps beyond the position gate: linked TDOAs keep two tracks, gating alone makes many."""
    n = 6
    cov = np.eye(3)
    windows = []
    for k in range(n):
        a = fix([1000.0 * k, 0.0, -800.0], cov, [1, 1, 1, 1, 0, 0, 0, 0])
        b = fix([0.0, 1000.0 * k, -900.0], cov, [0, 0, 0, 0, 1, 1, 1, 1])
        srcs = (a, b) if k % 2 else (b, a)
        links = np.arange(8) if k else None  # TDOA m continues TDOA m of the previous window
        windows.append(WindowSources(DT * k, srcs, links))
    linked = SourceTracker().track(windows)
    assert len(linked) == 2 and all(tr.times.size == n for tr in linked)
    for tr in linked:  # each track stays on one whale
        assert np.ptp(tr.raw_positions[:, 0]) == 0.0 or np.ptp(tr.raw_positions[:, 1]) == 0.0
    unlinked = SourceTracker().track([WindowSources(w.time_s, w.sources) for w in windows])
    assert len(unlinked) == 2 * n


def test_gaps_bridged_up_to_max_gap():
    """A track missing one window continues with max_gap=1 and splits with max_gap=0."""
    cov = np.eye(3)
    windows = [WindowSources(DT * k, () if k == 3 else (fix([1.0 * k * DT, 0.0, -800.0], cov),))
               for k in range(7)]
    assert len(SourceTracker(max_gap=1).track(windows)) == 1
    assert len(SourceTracker(max_gap=0).track(windows)) == 2


def test_unobservable_fixes_are_not_tracked_and_output_format():
    """A fix with a NaN covariance starts no track; to_dict gives the formats' track points."""
    nan = np.full((3, 3), np.nan)
    windows = [WindowSources(0.0, (fix([0.0, 0.0, -800.0], np.eye(3)), fix([9e3, 0, -5], nan))),
               WindowSources(2.0, (fix([2.0, 0.0, -800.0], np.eye(3)),))]
    (tr,) = SourceTracker().track(windows)
    d = tr.to_dict()
    assert d["id"] == 0 and [p["t"] for p in d["points"]] == [0.0, 2.0]
    assert set(d["points"][0]) == {"t", "x", "y", "z"}
    assert list(tr.sources) == [0, 0] and list(tr.windows) == [0, 1]


def test_tracker_checks_inputs():
    """Out-of-order windows, mismatched links and bad options are ValueErrors."""
    f = fix([0.0, 0, -800], np.eye(3))
    with pytest.raises(ValueError, match="increasing"):
        SourceTracker().track([WindowSources(2.0, (f,)), WindowSources(1.0, (f,))])
    with pytest.raises(ValueError, match="tdoa_links"):
        WindowSources(0.0, (f,), np.arange(7))
    with pytest.raises(ValueError, match="q"):
        SourceTracker(q=0.0)
    with pytest.raises(ValueError, match="max_gap"):
        SourceTracker(max_gap=-1)
