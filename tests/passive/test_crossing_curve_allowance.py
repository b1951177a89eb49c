"""Tests of the manoeuvre allowance on curved pairs (issue 19, 2026-12-03 late afternoon):
``curved_pair_intervals(ahead_var=...)``, ``CrossingDetector(curve_manoeuvre=True)``,
``--no-curve-manoeuvre``."""

from __future__ import annotations

import numpy as np

from fusion.passive.crossing import CrossingDetector
from fusion.passive.crossing.curve import curve_fits, curved_pair_intervals
from fusion.passive.crossing.judge import judge_pairs
from fusion.passive.line_fit import SlidingLineFit


def _close_pass_windows(seed: int = 0):
    """Window of 20 samples (K = 4 s) of a contact passing close to the sensor (curved) and of
    a straight track it meets about 30 s after the last sample."""
    rng = np.random.default_rng(seed)
    K, n = 4.0, 20
    t = np.arange(n) * K
    tt = t - t[-1]
    b0 = np.arctan2(-150.0 + 5.0 * (tt + 10.0), 300.0)  # sweeps ~1 deg/s near its closest point
    b1 = np.arctan2(-150.0 + 5.0 * 40.0, 300.0) + 0.004 * (tt - 30.0)
    b = np.stack([b0, b1]) + np.radians(0.2) * rng.standard_normal((2, n))
    fit = SlidingLineFit(window=n)
    ids = np.arange(2)
    for k, tk in enumerate(t):
        fit.update(ids, float(tk), b[:, k])
    st = fit.stats(ids, float(t[-1]))
    tau, val, ok = fit.windows(ids, float(t[-1]))
    return curve_fits(tau, val, ok, st, alpha=0.001)


def test_ahead_variance_widens_only_ahead_and_matches_a_fine_grid():
    """A variance added ahead of the sample widens the curved pair's interval on its upper side
    only; its upper end is where ``d^2 = q^2 (var + extra)`` on a grid 64 times finer."""
    cs = _close_pass_windows()
    assert cs.curved[0] and not cs.curved[1]
    ia, ib = np.array([0]), np.array([1])
    extra = 4e-6  # rad^2 per s of lead

    def ahead(tt):
        return extra * tt

    tau0, lo0, hi0, ok0, _ = curved_pair_intervals(ia, ib, cs, q=2.8, reach_s=80.0, back_s=80.0)
    tau1, lo1, hi1, ok1, _ = curved_pair_intervals(ia, ib, cs, q=2.8, reach_s=80.0, back_s=80.0,
                                                   ahead_var=ahead)
    assert ok0[0] and ok1[0] and 0 < tau0[0] < 80 and tau1[0] == tau0[0]
    assert hi1[0] > hi0[0] + 1.0
    assert lo1[0] <= lo0[0]
    # by hand on a fine grid: the connected set around the crossing
    g = np.linspace(-80.0, 80.0, 128 * 64 + 1)
    ba, va = cs.bearing(ia, g[None, :])
    bb, vb = cs.bearing(ib, g[None, :])
    d = (bb - ba)[0]
    var = (va + vb)[0] + np.where(g > 0, extra * g, 0.0)
    inside = d * d <= 2.8**2 * var
    k = np.argmin(np.abs(g - tau1[0]))
    hi = k
    while hi + 1 < g.size and inside[hi + 1]:
        hi += 1
    assert abs(g[hi] - hi1[0]) < 160.0 / 128  # within one cell of the coarse grid
    # behind the sample nothing is added: a crossing there keeps its interval
    _, lob0, hib0, okb0, _ = curved_pair_intervals(ia, ib, cs, q=2.8, reach_s=0.0,
                                                   back_s=160.0)
    _, lob1, hib1, okb1, _ = curved_pair_intervals(ia, ib, cs, q=2.8, reach_s=0.0,
                                                   back_s=160.0, ahead_var=ahead)
    np.testing.assert_array_equal([lob0, hib0, okb0], [lob1, hib1, okb1])


def test_curve_allowance_widens_only_what_is_reported():
    """Through the detector on traffic tuning seed 0: on the shortest window (curves) the pairs
    resolved, their crossing times and the confirming intervals are those without the allowance;
    the reported intervals contain them, and are wider for some curved predictions."""
    from fusion.passive.bearing_grid import resample_bearings
    from fusion.passive.crossing import crossing_settings
    from fusion.simulate.bearings import simulate_traffic

    sc = simulate_traffic(seed=0)
    st = crossing_settings(sc.track_id, sc.time)
    opts = st.detector_options()
    d1, d0 = (CrossingDetector(**{**opts, "curve_manoeuvre": flag}) for flag in (True, False))
    rs = resample_bearings(sc.track_id, sc.time, sc.bearing_deg, period_s=d1.K,
                           max_gap_s=d1.max_gap_s)
    times = np.unique(rs.time)
    widened = compared = 0
    for k, t in enumerate(times[:300]):
        m = rs.time == t
        for det in (d1, d0):
            det.step(float(t), rs.track_id[m], rs.bearing_deg[m])
        if d1.manoeuvre_q is None or k % 4:
            continue
        ids = np.sort(rs.track_id[m])
        model = d1._models(d1.fits[0], ids, float(t), curves=True)
        if model[1] is None or not model[1].curved.any():
            continue
        full = np.flatnonzero(model[0].n >= d1.J)
        ia, ib = (full[x] for x in np.triu_indices(full.size, 1))
        span = d1.windows[0] * d1.K
        kw = {"back_s": span * 0.5, "reach_s": span * 0.5, "span_s": span}
        r1 = judge_pairs(d1, model, ia, ib, **kw)
        r0 = judge_pairs(d0, model, ia, ib, **kw)  # same model: the allowance is the only change
        np.testing.assert_array_equal(r1[3], r0[3])  # resolved alike
        np.testing.assert_array_equal(r1[0], r0[0])  # the same crossing times
        ok = r1[3]
        np.testing.assert_array_equal(r1[5][ok], r0[1][ok])  # confirming: the curves' own
        np.testing.assert_array_equal(r1[6][ok], r0[2][ok])
        assert np.all(r1[1][ok] <= r0[1][ok]) and np.all(r1[2][ok] >= r0[2][ok])
        compared += int(ok.sum())
        widened += int(np.sum(r1[2][ok] > r0[2][ok] + 1e-9))
    print(compared, widened)
    assert compared > 50 and widened > 5


def test_curve_allowance_holds_more_intervals_on_traffic(traffic_interval_scores):
    """Traffic tuning seeds 1 and 5: with the allowance on curved pairs, the alerts' intervals
    hold the crossing at least 3 points more often than without, with as many predictions
    (within 1 %)."""
    for seed in (1, 5):
        on = traffic_interval_scores(seed)
        off = traffic_interval_scores(seed, curve_manoeuvre=False)
        print(seed, on.coverage, off.coverage, on.n_predicted, off.n_predicted)
        assert on.coverage >= off.coverage + 0.03
        assert on.n_predicted >= off.n_predicted - max(2, 0.01 * off.n_crossings)


def test_ladder_judges_a_pair_once_per_window_and_sample(monkeypatch):
    """Decision 10: with three windows whose reaches overlap, no pair is judged twice on one
    window at one sample; the sorted-key store gives the dense table's verdicts."""
    import fusion.passive.crossing.judge as judge

    rng = np.random.default_rng(3)
    n, K = 60, 5.0
    b0 = rng.uniform(0.0, 360.0, n)
    rate = rng.normal(0.0, 0.05, n)
    seen: list[tuple[float, float, int]] = []
    orig = judge.judge_pairs

    def counting(det, model, ia, ib, **kw):
        seen.extend((det._last_time, kw["span_s"], int(k)) for k in ia * 1000 + ib)
        return orig(det, model, ia, ib, **kw)

    monkeypatch.setattr(judge, "judge_pairs", counting)
    det = CrossingDetector(J=10, K=K, n_windows=3, level=0.99, lead_windows=0.5,
                           horizon_s=600.0)
    for i in range(60):
        det.step(K * i, np.arange(n), b0 + rate * K * i + rng.normal(0.0, 0.3, n))
    assert len(seen) > 1000
    assert len(set(seen)) == len(seen)
    # the two stores agree
    key = rng.choice(n * n, 500, replace=False).astype(np.int64)
    ok = rng.random(500) < 0.5
    dense, sparse = judge._Judged(n), judge._Judged(n)
    sparse.dense = None
    for store in (dense, sparse):
        store.add(key[:300], ok[:300])
    probe = key[250:]
    for a, b in zip(dense.find(probe), sparse.find(probe), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(dense.find(probe)[0], np.arange(250, 500) < 300)


def test_command_switches_the_curve_allowance_off(tmp_path, capsys):
    """``fusion crossings --no-curve-manoeuvre`` runs without it (the summary says so) and its
    predictions' intervals are never wider than with the default."""
    from fusion.cli import main
    from fusion.io import read_table

    assert main(["simulate", "bearings", "--seed", "1", "--out", str(tmp_path / "s")]) == 0
    widths = {}
    for flag in ([], ["--no-curve-manoeuvre"]):
        out = tmp_path / f"a{len(flag)}.csv"
        capsys.readouterr()
        assert main(["crossings", "--bearings", str(tmp_path / "s" / "bearings.csv"),
                     "--out", str(out), *flag]) == 0
        said = capsys.readouterr().out
        assert ("(curves too)" in said) == (not flag)
        t = read_table(out, required=("t_cross_low", "t_cross_high"))
        widths[len(flag)] = np.sum(t["t_cross_high"] - t["t_cross_low"])
    assert widths[0] >= widths[1]
