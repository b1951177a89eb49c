"""Tests of the manoeuvre allowance of crossing predictions, the far-end evaluation of the
lead-dependent variances and the allowances' gate (issue 19, 2026-12-03 afternoon):
:mod:`fusion.passive.crossing.manoeuvre`, ``--manoeuvre-scale``, ``--ahead-variance-at``,
``--allowance-gates-from``."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from fusion.passive.crossing import CrossingDetector, crossing_settings, detect_crossings
from fusion.passive.crossing.interval import crossing_time_interval, t_quantile, welch_dof
from fusion.passive.crossing.manoeuvre import (
    ManoeuvreIntensity,
    half_window_slopes,
    manoeuvre_variance,
    miss_constants,
)
from fusion.passive.crossing.pairs import pair_intervals


def test_miss_constants_closed_form():
    """The quadrature gives the closed forms of the uniform window: A = 13/35, B = 11/210,
    C = 1/105, c = 26/35."""
    A, B, C, c = miss_constants()
    assert_allclose([A, B, C, c], [13 / 35, 11 / 210, 1 / 105, 26 / 35], rtol=2e-5)


def test_miss_variance_matches_simulated_random_walk_rates():
    """Monte Carlo: bearings whose rate is a random walk of intensity q; the squared miss of
    the window line extrapolated tau ahead averages q T^3 phi(tau / T), and the slope difference
    of the window's two halves averages c q T (no noise)."""
    rng = np.random.default_rng(7)
    q, dt, T, n_mc = 1e-7, 0.25, 40.0, 4000
    n_win = int(T / dt)
    for x in (0.0, 0.5, 1.0):
        n_ahead = int(round(x * T / dt))
        steps = n_win + n_ahead
        rate = np.cumsum(rng.normal(0.0, np.sqrt(q * dt), (n_mc, steps)), axis=1)
        b = np.cumsum(rate * dt, axis=1)
        s = (np.arange(n_win) - (n_win - 1)) * dt  # window times, 0 at the sample
        coef = np.polyfit(s, b[:, :n_win].T, 1)  # (2, n_mc)
        pred = coef[1] + coef[0] * (x * T)
        miss = b[:, n_win - 1 + n_ahead] - pred
        want = manoeuvre_variance(q, T, np.array([max(x * T, 1e-9)]))[0]
        assert_allclose(np.mean(miss**2), want, rtol=0.1)
    # the half-window estimate: E[(r_new - r_old)^2] = c q T
    rate = np.cumsum(rng.normal(0.0, np.sqrt(q * dt), (n_mc, 2 * n_win)), axis=1)
    b = np.cumsum(rate * dt, axis=1)
    tau = np.tile((np.arange(2 * n_win) - (2 * n_win - 1)) * dt, (n_mc, 1))
    d2, var_sum, ok = half_window_slopes(tau, b, np.ones(b.shape, bool), T - 0.5 * dt, 3)
    assert ok.all()
    assert_allclose(np.mean(d2), miss_constants()[3] * q * T, rtol=0.1)


def _wander_tracks(q_b: float, *, seed: int = 0, n: int = 400, K: float = 5.0, noise_deg=0.2):
    """Track 0 straight, track 1 with a random-walk rate of intensity q_b (rad^2/s^3)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * K
    rate = 0.002 + np.cumsum(rng.normal(0.0, np.sqrt(q_b * K), n))
    b1 = 1.0 + np.cumsum(rate * K)
    b0 = 0.2 + 0.001 * t
    noise = np.radians(noise_deg) * rng.standard_normal((2, n))
    return t, np.degrees(np.stack([b0, b1]) + noise)


def test_each_track_gets_its_own_intensity():
    """Through the detector: a straight track's intensity stays near 0, that of a track whose
    rate wanders with q = 4e-8 is estimated within 35 % (the noise's part subtracted)."""
    q_b = 4e-8
    t, b = _wander_tracks(q_b)
    det = CrossingDetector(J=10, K=5.0, n_windows=2, level=0.99, manoeuvre_scale=1.0,
                           manoeuvre_memory_s=1e9)
    for k, tk in enumerate(t):
        det.step(float(tk), [0, 1], b[:, k])
    q = det.manoeuvre_q
    assert q[0] < 0.1 * q_b
    assert_allclose(q[1], q_b, rtol=0.35)
    # the scale multiplies it; the memory forgets it
    est = ManoeuvreIntensity(2.0, memory_s=10.0, period_s=5.0)
    ids = np.array([3])
    assert_allclose(est.add(ids, np.array([5.0]), np.array([1.0]), np.array([True]), 10.0),
                    2.0 * 4.0 / (miss_constants()[3] * 10.0))
    again = est.add(ids, np.array([0.0]), np.array([0.0]), np.array([False]), 10.0)
    assert_allclose(again, 2.0 * 4.0 / (miss_constants()[3] * 10.0))  # ratio kept as both decay


def test_manoeuvre_widens_predictions_and_far_end_recomputes_the_upper_bound(window_lines):
    """A pair converging 40 s ahead: the manoeuvre term widens the interval of the prediction
    (and of nothing behind the sample); with `far_side` the upper bound is the Fieller bound
    with the variance taken at the first pass's upper bound (cross-checked by hand)."""
    rng = np.random.default_rng(1)
    t = np.arange(10) * 4.0
    tr = t - t[-1]
    b = np.stack([0.0 + 0.002 * tr, 0.08 - 0.0 * tr]) + np.radians(0.1) * rng.standard_normal(
        (2, t.size))
    st, _ = window_lines(t, b)
    ia, ib = np.array([0]), np.array([1])
    qm = np.array([2e-8, 0.0])
    tau0, lo0, hi0, ok0 = pair_intervals(ia, ib, st.value, st, level=0.99)
    tau, lo, hi, ok = pair_intervals(ia, ib, st.value, st, level=0.99, manoeuvre=(qm, 40.0))
    assert ok0[0] and ok[0] and tau[0] > 0 and tau0[0] == tau[0]
    assert lo[0] < lo0[0] and hi[0] > hi0[0]
    _, lof, hif, _ = pair_intervals(ia, ib, st.value, st, level=0.99, manoeuvre=(qm, 40.0),
                                    far_side=True)
    assert lof[0] == lo[0] and hif[0] > hi[0]
    # by hand: Fieller with v00 + m(hi) for the pair
    d0 = st.value[1] - st.value[0]
    d1 = st.slope[1] - st.slope[0]
    v00 = st.var_value.sum() + manoeuvre_variance(qm.sum(), 40.0, hi)
    q = t_quantile(0.99, welch_dof(st.var_slope[0], st.var_slope[1], st.n[0] - 2.0,
                                   st.n[1] - 2.0))
    _, hand, _ = crossing_time_interval([d0], [d1], v00, [st.cov.sum()], [st.var_slope.sum()], q)
    assert_allclose(hif, hand, rtol=1e-10)
    # a crossing behind the sample gets nothing
    _, lob, hib, _ = pair_intervals(ia, ib, -st.value, st, level=0.99)
    _, lobm, hibm, _ = pair_intervals(ia, ib, -st.value, st, level=0.99, manoeuvre=(qm, 40.0))
    if np.isfinite(lob[0]) and hib[0] < 0:
        assert_allclose([lobm[0], hibm[0]], [lob[0], hib[0]])


def _never_alerted(sc, alerts) -> float:
    alerted = {(a.track_a, a.track_b) for a in alerts}
    return sum(p in alerted for p in sc.non_crossing_pairs) / len(sc.non_crossing_pairs)


def test_allowances_hold_more_intervals_on_traffic(traffic_interval_scores):
    """Manoeuvring traffic (tuning seed 0): with the manoeuvre allowance, and with the far-end
    evaluation, the alerts' intervals hold the crossing more often and fewer alerts are false
    than without each, and as many crossings are predicted."""
    full = traffic_interval_scores(0)
    for without in (traffic_interval_scores(0, manoeuvre_scale=0.0),
                    traffic_interval_scores(0, far_side=False)):
        print(full.coverage, without.coverage, full.n_false, without.n_false,
              full.n_predicted, without.n_predicted)
        assert full.coverage >= without.coverage + 0.005
        assert full.n_false <= without.n_false - 3
        assert full.n_predicted >= without.n_predicted - 2


def test_allowance_gate_alerts_fewer_never_crossing_pairs():
    """Traffic tuning seeds 0 and 3: gating on the widened intervals from the third window on
    alerts fewer of the pairs that never cross than widening only."""
    from fusion.simulate.bearings import simulate_traffic

    gated = ungated = 0.0
    for seed in (0, 3):
        sc = simulate_traffic(seed=seed)
        cols = {"track_id": sc.track_id, "time": sc.time, "bearing_deg": sc.bearing_deg}
        for gate in (2, None):
            st = crossing_settings(sc.track_id, sc.time, allowance_gate_level=gate)
            frac = _never_alerted(sc, detect_crossings(cols, **st.detector_options()))
            if gate is None:
                ungated += frac
            else:
                gated += frac
    assert gated <= ungated - 0.02
