"""Tests of the curvature allowance of line predictions (issue 19, 2026-12-03):
``--extrapolation curvature``, :mod:`fusion.passive.crossing.curvature`."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from fusion.passive.crossing.curvature import curvature_stats, curvature_variance
from fusion.passive.crossing.pairs import pair_intervals


def test_quadratic_term_known_answer(window_lines):
    """A bearing ``b0 + r t + c t^2`` (no noise): the coefficient is c, the line's miss at tau is
    ``c g(tau)`` (checked against np.polyfit's line extrapolated), its variance 0; a straight
    track has c = 0."""
    t = np.arange(12) * 5.0
    tr = t - t[-1]
    c = 2e-5
    b = np.stack([0.3 + 0.004 * tr + c * tr * tr, 0.5 - 0.002 * tr])
    st, (tau, val, ok) = window_lines(t, b)
    cs = curvature_stats(tau, val, ok, st)
    assert_allclose(cs.c, [c, 0.0], atol=1e-12)
    line = np.polyfit(tr, b[0], 1)
    # its variance: the line's residual variance over sum h^2 (h: t^2 off its own line)
    s2 = np.sum((b[0] - np.polyval(line, tr)) ** 2) / (t.size - 2)
    h = tr * tr - np.polyval(np.polyfit(tr, tr * tr, 1), tr)
    assert_allclose(cs.var_c[0], s2 / np.sum(h * h), rtol=1e-6)
    assert cs.var_c[1] < 1e-6 * cs.var_c[0]  # round-off of a straight track
    for ahead in (10.0, 30.0):
        miss = (0.3 + 0.004 * ahead + c * ahead**2) - np.polyval(line, ahead)
        assert_allclose(c * cs.g(np.array([0]), np.array([ahead]))[0], miss, rtol=1e-9)
    # the pair's variance at tau: the difference's miss squared plus the estimates' variance
    e = curvature_variance(cs, np.array([0]), np.array([1]), np.array([30.0]))
    ga, gb = (cs.g(np.array([k]), np.array([30.0]))[0] for k in (0, 1))
    assert_allclose(e, (c * ga) ** 2 + cs.var_c[0] * ga**2 + cs.var_c[1] * gb**2, rtol=1e-9)


def test_curving_track_interval_holds_with_the_allowance(window_lines):
    """Track a curves gently (too little in 12 noisy samples for its quadratic term to be
    resolved: |c| about its standard error); its line predicts the crossing with a straight
    track too early and the lines' own interval misses it, the interval with the curvature
    allowance holds it."""
    rng = np.random.default_rng(3)
    K, n = 5.0, 12
    t = np.arange(n) * K
    tr = t - t[-1]
    c = -4e-6  # rad/s^2
    sigma = np.radians(0.05)
    a = 0.010 * tr + c * tr * tr + rng.normal(0, sigma, n)
    b = np.full(n, np.radians(20.0)) + rng.normal(0, sigma, n)
    st, (tau, val, ok) = window_lines(t, np.stack([a, b]))
    cs = curvature_stats(tau, val, ok, st)
    # the true crossing: 0.01 tau + c tau^2 = 0.349 (20 deg)
    true = (-0.010 + np.sqrt(0.010**2 + 4 * c * np.radians(20.0))) / (2 * c)
    ia, ib = np.array([0]), np.array([1])
    tc, lo, hi, okl = pair_intervals(ia, ib, st.value, st, level=0.999)
    _, lo2, hi2, ok2 = pair_intervals(ia, ib, st.value, st, level=0.999, curvature=cs)
    assert okl[0] and ok2[0] and tc[0] > 0
    assert not lo[0] <= true <= hi[0]  # the lines alone: too narrow
    assert lo2[0] <= true <= hi2[0]  # with the curvature left out
    assert lo2[0] <= lo[0] and hi2[0] >= hi[0]


def test_curvature_allowance_holds_more_intervals_on_traffic(traffic_interval_scores):
    """Manoeuvring traffic (tuning seed 0): with the allowance the alerts' intervals hold the
    crossing more often and as many crossings are predicted."""
    before = {"manoeuvre_scale": 0.0, "far_side": False, "level": 0.999}  # as measured then
    with_c = traffic_interval_scores(0, curvature=True, **before)
    without = traffic_interval_scores(0, curvature=False, **before)
    assert with_c.coverage >= without.coverage + 0.02
    assert with_c.n_predicted >= without.n_predicted - 2


def test_confirmation_counted_from_further_out_alerts_one_sample_sooner():
    """Two straight tracks crossing at 40 s (K = 1 s, 10-sample window, predictions reach 5 s,
    two samples to confirm): the first prediction comes at 36 s when confirming samples must
    lie within the reach, at 35 s -- as soon as the crossing is within reach -- when they are
    counted from a window ahead; no prediction is raised beyond the reach either way."""
    from fusion.passive.crossing import CrossingDetector

    rng = np.random.default_rng(1)
    t = np.arange(0.0, 60.0, 1.0)
    b = np.stack([0.5 * t, 40.0 - 0.5 * t]) + rng.normal(0, 0.02, (2, t.size))
    first = {}
    for confirm_lead in (None, 1.0):
        det = CrossingDetector(J=10, K=1.0, horizon_s=60.0, lead_windows=0.5, confirm=2,
                               level=0.999, confirm_overlap=True,
                               confirm_lead_windows=confirm_lead)
        pred = [a for k, tk in enumerate(t) for a in det.step(tk, [1, 2], b[:, k])
                if a.kind == "predicted"]
        assert pred and all(a.t_cross - a.time <= 5.0 + 1e-9 for a in pred)
        assert all(a.t_cross_low <= 40.0 <= a.t_cross_high for a in pred)
        first[confirm_lead] = pred[0].time
    assert first[None] == 36.0 and first[1.0] == 35.0
