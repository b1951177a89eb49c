"""Tests of the crossing-time intervals, the window ladder, the settings in seconds and scoring."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import stats

from fusion.metrics.crossings import score_intervals
from fusion.passive.bearing_grid import resample_bearings
from fusion.passive.crossing import (
    CrossingAlert,
    CrossingDetector,
    crossing_settings,
    detect_crossings,
)
from fusion.passive.crossing.pairs import crossing_time_interval, pair_intervals, t_quantile
from fusion.passive.line_fit import SlidingLineFit
from fusion.simulate.bearings import simulate_bearings, varied_settings


def _lines(times, specs, *, noise_deg=0.0, seed=0) -> dict:
    """Table of straight bearing lines {track: (bearing at t=0 deg, rate deg/s)} plus noise."""
    rng = np.random.default_rng(seed)
    tid, tt, bb = [], [], []
    for k, (b0, r) in specs.items():
        tid += [k] * len(times)
        tt += list(times)
        bb += list(np.mod(b0 + r * np.asarray(times) + rng.normal(0, noise_deg, len(times)), 360))
    return {"track_id": np.array(tid), "time": np.array(tt, float), "bearing_deg": np.array(bb)}


# --------------------------------------------------------------------------------------------
# the fit's covariance and the Fieller interval
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(4))
def test_line_stats_match_numpy_polyfit_covariance(seed):
    """Value, slope, residual variance and covariance equal np.polyfit's (cov=True)."""
    rng = np.random.default_rng(seed)
    J = int(rng.integers(5, 30))
    t = 100.0 + np.cumsum(rng.uniform(0.5, 3.0, 2 * J))
    y = 0.3 + 0.002 * t + rng.normal(0, 0.01, t.size)
    fit = SlidingLineFit(window=J, angular=False)
    for k in range(t.size):
        fit.update([4], t[k], [y[k]])
    t_eval = t[-1] + 7.0
    st = fit.stats([4], t_eval)
    x = t[-J:] - t_eval  # polyfit about the evaluation time: intercept = value there
    coef, cov = np.polyfit(x, y[-J:], 1, cov="unscaled")
    resid = y[-J:] - np.polyval(coef, x)
    s2 = resid @ resid / (J - 2)
    assert_allclose(st.slope[0], coef[0], rtol=1e-8)
    assert_allclose(st.value[0], coef[1], rtol=1e-9, atol=1e-12)
    assert_allclose(st.residual_var[0], s2, rtol=1e-6)
    assert_allclose([st.var_slope[0], st.var_value[0], st.cov[0]],
                    [s2 * cov[0, 0], s2 * cov[1, 1], s2 * cov[0, 1]], rtol=1e-6)


def test_t_quantile_matches_scipy():
    """Tabulated two-sided quantiles equal scipy's; fractional dof rounds down (wider)."""
    dof = np.array([1.0, 2.0, 8.0, 8.7, 40.0, 999.0])
    assert_allclose(t_quantile(0.95, dof), stats.t.ppf(0.975, np.floor(dof)), rtol=1e-12)
    assert_allclose(t_quantile(0.99, [5e4]), stats.norm.ppf(0.995), rtol=1e-12)
    with pytest.raises(ValueError, match="level"):
        t_quantile(1.0, [3.0])


@pytest.mark.parametrize("seed", range(6))
def test_fieller_interval_is_the_set_where_the_line_is_near_zero(seed):
    """The interval's ends are where |d(tau)| = q sd(d(tau)); inside it is smaller (dense grid)."""
    rng = np.random.default_rng(seed)
    d0, d1 = rng.normal(0, 0.05), rng.choice([-1, 1]) * rng.uniform(1e-3, 1e-2)
    a = rng.normal(size=(2, 2))
    v = (a @ a.T) * np.array([[1e-5, 1e-7], [1e-7, 1e-9]])  # covariance of (d0, d1)
    q = 2.1
    lo, hi, ok = crossing_time_interval([d0], [d1], [v[0, 0]], [v[0, 1]], [v[1, 1]], q)
    tau = np.linspace(-200, 200, 400001) + (-d0 / d1)
    inside = (d0 + d1 * tau) ** 2 <= q * q * (v[0, 0] + 2 * tau * v[0, 1] + tau * tau * v[1, 1])
    if ok[0]:
        grid = tau[inside]
        assert_allclose([lo[0], hi[0]], [grid.min(), grid.max()], atol=2e-3)
        assert lo[0] <= -d0 / d1 <= hi[0]
    else:  # unresolved rate difference: the set is not a bounded interval
        assert d1 * d1 <= q * q * v[1, 1] and inside[0] | inside[-1]


def test_interval_of_noise_free_lines_is_the_crossing_itself():
    """Without noise the interval shrinks to equation (2)'s crossing time."""
    lo, hi, ok = crossing_time_interval([1.0], [-0.1], [0.0], [0.0], [0.0], 2.0)
    assert ok[0]
    assert_allclose([lo[0], hi[0]], [10.0, 10.0], rtol=1e-12)


def test_95_percent_intervals_cover_at_a_fixed_time():
    """At a fixed sample (no selection), 95 % intervals of noisy lines hold t_c in ~95 % of trials."""
    rng = np.random.default_rng(1)
    J, K, trials, noise = 20, 2.0, 2000, np.radians(0.5)
    t = np.arange(J) * K
    tc = t[-1] + 30.0  # true crossing 30 s after the last sample
    ra, rb = np.radians(0.10), np.radians(-0.05)  # rad/s
    ya = ra * (t - tc) + rng.normal(0, noise, (trials, J))
    yb = rb * (t - tc) + rng.normal(0, noise, (trials, J))
    fit = SlidingLineFit(window=J, angular=False)
    ids = np.arange(2 * trials)
    for k in range(J):
        fit.update(ids, t[k], np.concatenate([ya[:, k], yb[:, k]]))
    st = fit.stats(ids, t[-1])
    ia, ib = np.arange(trials), trials + np.arange(trials)
    tau, lo, hi, ok = pair_intervals(ia, ib, st.value, st, level=0.95)
    covered = ok & (lo <= tc - t[-1]) & (tc - t[-1] <= hi)
    assert np.mean(ok) > 0.99
    assert 0.93 <= covered.mean() <= 0.97


# --------------------------------------------------------------------------------------------
# the detector: gating, ladder, confirmation
# --------------------------------------------------------------------------------------------
def test_slow_crossing_needs_the_window_ladder():
    """A 0.4 deg/min crossing under 1 deg noise: one 60 s window never alerts, the ladder does."""
    times = np.arange(0.0, 3000.0, 5.0)
    table = _lines(times, {1: (100.0, 0.2 / 60), 2: (110.0, -0.2 / 60)}, noise_deg=1.0, seed=0)
    tc = 1500.0  # 10 deg closed at 0.4 deg/min
    opts = {"J": 12, "K": 5.0, "horizon_s": 600.0, "lead_windows": 0.5, "confirm": 2,
            "level": 0.999}
    assert detect_crossings(table, n_windows=1, **opts) == []
    ladder = detect_crossings(table, n_windows=6, **opts)
    pred = [a for a in ladder if a.kind == "predicted"]
    assert pred and pred[0].time < tc
    assert pred[0].t_cross_low <= tc <= pred[0].t_cross_high
    assert pred[0].window_s > 60.0
    assert all(a.t_cross_high - a.t_cross_low <= 600.0 for a in ladder)


def test_no_alert_interval_wider_than_the_limit():
    """Every alert on a varied scenario carries a bounded interval no wider than the horizon
    (the fits' own intervals: without the allowances that widen them on the shorter windows)."""
    sc = simulate_bearings(**{**varied_settings(3), "duration_s": 1800.0})
    st = crossing_settings(sc.track_id, sc.time, horizon_s=300.0, manoeuvre_scale=0.0,
                           far_side=False)
    alerts = detect_crossings({"track_id": sc.track_id, "time": sc.time,
                               "bearing_deg": sc.bearing_deg}, **st.detector_options())
    assert alerts
    w = np.array([a.t_cross_high - a.t_cross_low for a in alerts])
    assert np.all(np.isfinite(w)) and np.all(w <= 300.0)
    assert all(a.t_cross_low <= a.t_cross <= a.t_cross_high for a in alerts)


def test_confirmation_delays_the_prediction_by_one_sample():
    """confirm=2 delays the prediction by one sample; the pair stays confirmed for detection."""
    table = _lines(np.arange(0.0, 120.0, 2.0), {1: (20.0, 0.3), 2: (50.5, -0.2)})
    one = detect_crossings(table, J=7, K=2.0)
    two = detect_crossings(table, J=7, K=2.0, confirm=2)
    assert [a.kind for a in one] == [a.kind for a in two]
    assert_allclose([a.time for a in two], [one[0].time + 2.0, one[1].time])
    assert_allclose([a.t_cross for a in two], [61.0, 61.0], atol=1e-9)


def test_predictions_reach_lead_windows_ahead():
    """lead_windows=0.5 lets a prediction come only when t_c is within half a window."""
    table = _lines(np.arange(0.0, 300.0, 2.0), {1: (20.0, 0.1), 2: (40.0, -0.1)})  # t_c = 100
    full = detect_crossings(table, J=20, K=2.0, horizon_s=200.0)
    half = detect_crossings(table, J=20, K=2.0, horizon_s=200.0, lead_windows=0.5)
    p_full = [a for a in full if a.kind == "predicted"][0]
    p_half = [a for a in half if a.kind == "predicted"][0]
    assert 100.0 - p_full.time <= 40.0 and 100.0 - p_half.time <= 20.0
    assert p_half.time > p_full.time


def test_detector_option_validation():
    """Bad ladder, level, lead and confirm options raise ValueError naming them."""
    for kw, match in (({"n_windows": 0}, "n_windows"), ({"level": 1.0}, "level"),
                      ({"lead_windows": 0.0}, "lead_windows"), ({"confirm": 0}, "confirm"),
                      ({"max_interval_s": -1.0}, "max_interval_s")):
        with pytest.raises(ValueError, match=match):
            CrossingDetector(J=5, K=1.0, **kw)


# --------------------------------------------------------------------------------------------
# settings in seconds and dense data
# --------------------------------------------------------------------------------------------
def test_settings_for_dense_data_set_the_window_in_seconds():
    """10 Hz tracks: the grid is window / 30, so the warning time does not shrink with the rate."""
    times = np.arange(0.0, 1200.0, 0.1)
    tid = np.repeat([1, 2], times.size)
    st = crossing_settings(tid, np.tile(times, 2))
    assert st.data_step_s == pytest.approx(0.1)
    assert st.window_s == pytest.approx(40.0)
    assert st.period_s == pytest.approx(40.0 / 30) and st.J == 30
    assert st.horizon_s == 600.0
    line = st.describe()
    assert "\n" not in line and "K=1.333 s" in line and "horizon 600 s" in line


def test_settings_for_short_records_and_coarse_sampling():
    """Short records get an eighth of their span; coarse sampling keeps ten samples a window."""
    short = crossing_settings([1] * 120 + [2] * 120, np.tile(np.arange(120) * 0.5, 2))
    assert short.window_s == pytest.approx(59.5 / 8, rel=0.1)
    coarse = crossing_settings([1] * 200 + [2] * 200, np.tile(np.arange(200) * 20.0, 2))
    assert coarse.period_s == 20.0 and coarse.J == 10 and coarse.window_s == 200.0
    given = crossing_settings([1, 1, 2, 2], [0.0, 1.0, 0.0, 1.0], J=12)
    assert given.J == 12 and given.period_s == 1.0
    with pytest.raises(ValueError, match="window_s"):
        crossing_settings([1, 1], [0.0, 1.0], window_s=-1.0)


def test_dense_tracks_are_averaged_onto_the_grid():
    """Samples denser than the grid are averaged within each cell (bin means, then the grid)."""
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 20.0, 0.1)
    b = 10.0 + 0.5 * t + rng.normal(0, 1.0, t.size)
    rs = resample_bearings(np.zeros(t.size, int), t, b, period_s=2.0)
    cell = np.floor(t / 2.0 + 0.5)
    centre = np.array([b[cell == c].mean() for c in np.unique(cell)])
    tm = np.array([t[cell == c].mean() for c in np.unique(cell)])
    assert_allclose(rs.bearing_deg, np.interp(rs.time, tm, centre), atol=1e-9)
    assert np.std(rs.bearing_deg - (10.0 + 0.5 * rs.time)) < 0.5  # noise averaged down


# --------------------------------------------------------------------------------------------
# scoring
# --------------------------------------------------------------------------------------------
def test_score_intervals_known_answer():
    """Hand-made alerts: predicted, false, detected and coverage counted as defined."""
    crossings = [(0, 1, 100.0), (0, 2, 300.0), (1, 2, 500.0)]
    alerts = [
        CrossingAlert(60.0, 0, 1, 98.0, "predicted", 95.0, 101.0),  # true, covers
        CrossingAlert(101.0, 0, 1, 100.5, "detected", 99.0, 102.0),  # true, covers
        CrossingAlert(250.0, 0, 2, 280.0, "predicted", 275.0, 298.0),  # true only with tol 5
        CrossingAlert(400.0, 2, 3, 420.0, "predicted", 410.0, 430.0),  # pair never crosses
    ]
    s = score_intervals(alerts, crossings, eligible=[True, True, False], tol_s=5.0,
                        lead_min_s=10.0)
    assert (s.n_crossings, s.n_predicted, s.n_detected) == (2, 2, 1)
    assert (s.n_false, s.n_on_crossing_pairs, s.n_covered) == (1, 3, 2)
    assert_allclose(s.lead_s, [40.0, 50.0])
    assert_allclose(s.error_s, [-2.0, -20.0])
    strict = score_intervals(alerts, crossings, tol_s=0.0)
    assert strict.n_false == 2 and strict.n_predicted == 1
