"""Tests of the multistatic tracker (fusion.active.tracker) and ``fusion track``."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from numpy.testing import assert_allclose
from scipy.stats import chi2, multivariate_normal

from fusion.active.association import EDGE_LIKELIHOOD, assign, derived_min_rank, neutral_value
from fusion.active.bistatic import bistatic_covariance, equivalent_aspect_deg
from fusion.active.kalman import cv_model, gate_threshold, kf_predict, kf_update, pair_statistics
from fusion.active.lifecycle import track_status
from fusion.active.motion import motion_statistic
from fusion.active.rulebase import default_association_system, default_variables
from fusion.active.tracker import Ping, Tracker, pings_from_table
from fusion.io import Table, read_table, write_table
from fusion.simulate.multistatic import bistatic_position, simulate_multistatic


def _paper(**kw):
    """The tracker with the defaults it had before the track score: M-of-N alone, the grid map
    with its hotspot drop and 300-m exclusion, no minimum speed, fixed sonar accuracies."""
    from fusion.active.clutter import ClutterMap

    opts = dict(confirm_llr=None, min_speed_mps=0.0, clutter_map=ClutterMap(), hotspot_drop=True,
                init_exclusion_m=300.0, noise="fixed", range_sum_sigma_m=30.0,
                bearing_sigma_deg=1.0)
    opts.update(kw)
    return Tracker(**opts)


def _random_track(rng):
    x = rng.normal(0, 1000, 4)
    A = rng.normal(0, 1, (4, 4))
    return x, A @ A.T * 100 + np.eye(4)


def test_predict_update_equal_filterpy():
    """Vectorised predict/update equal filterpy's KalmanFilter for several tracks."""
    rng = np.random.default_rng(3)
    F, Q = cv_model(75.0, 0.04)
    R = np.diag([90.0**2, 120.0**2])
    xs, Ps = zip(*(_random_track(rng) for _ in range(5)), strict=True)
    z = rng.normal(0, 1000, (5, 2))
    x1, P1 = kf_predict(np.array(xs), np.array(Ps), F, Q)
    x2, P2 = kf_update(x1, P1, z, R)
    for i in range(5):
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x, kf.P, kf.F, kf.Q, kf.R = xs[i].copy(), Ps[i].copy(), F, Q, R
        kf.H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
        kf.predict()
        assert_allclose(x1[i], kf.x, rtol=1e-12)
        assert_allclose(P1[i], kf.P, rtol=1e-10)
        kf.update(z[i])
        assert_allclose(x2[i], kf.x, rtol=1e-9, atol=1e-9)
        assert_allclose(P2[i], kf.P, rtol=1e-8, atol=1e-8)


def test_cv_model_known_answer():
    """F and Q of the constant-velocity model for dt = 2 s, q = 3."""
    F, Q = cv_model(2.0, 3.0)
    assert_allclose(F[:2, 2:], 2 * np.eye(2))
    assert_allclose(Q[0, 0], 3 * 8 / 3)
    assert_allclose(Q[0, 2], 3 * 2)
    assert_allclose(Q[2, 2], 3 * 2)
    with pytest.raises(ValueError, match="time step"):
        cv_model(-1.0, 1.0)


def test_likelihood_equals_scipy():
    """Pair log-likelihoods equal scipy.stats.multivariate_normal; L = exp(-d2/2)."""
    rng = np.random.default_rng(4)
    xs, Ps = zip(*(_random_track(rng) for _ in range(3)), strict=True)
    x, P = np.array(xs), np.array(Ps)
    z = rng.normal(0, 1000, (7, 2))
    R = np.eye(2) * 100.0**2
    st = pair_statistics(x, P, z, R)
    for t in range(3):
        mvn = multivariate_normal(mean=x[t, :2], cov=P[t, :2, :2] + R)
        assert_allclose(st.log_pdf[t], mvn.logpdf(z), rtol=1e-10)
        d = z - x[t, :2]
        d2 = np.einsum("ni,ij,nj->n", d, np.linalg.inv(P[t, :2, :2] + R), d)
        assert_allclose(st.d2[t], d2, rtol=1e-10)
    assert_allclose(st.likelihood_ratio, np.exp(-st.d2 / 2))


def test_gate_keeps_the_stated_fraction():
    """The chi-square gate keeps ~99 % of detections drawn from the innovation covariance."""
    assert_allclose(gate_threshold(0.99), chi2.ppf(0.99, 2))
    rng = np.random.default_rng(5)
    x, P = _random_track(rng)
    R = np.eye(2) * 50.0**2
    z = rng.multivariate_normal(x[:2], P[:2, :2] + R, 20000)
    st = pair_statistics(x[None], P[None], z, R)
    assert abs(np.mean(st.d2 <= gate_threshold(0.99)) - 0.99) < 0.003
    with pytest.raises(ValueError, match="gate probability"):
        gate_threshold(1.0)


def _brute_force(score, valid):
    n, m = score.shape
    best = 0.0
    for k in range(min(n, m) + 1):
        for rows in itertools.combinations(range(n), k):
            for cols in itertools.permutations(range(m), k):
                if all(valid[r, c] for r, c in zip(rows, cols, strict=True)):
                    best = max(best, sum(score[r, c] for r, c in zip(rows, cols, strict=True)))
    return best


@pytest.mark.parametrize("seed", range(25))
def test_assignment_equals_brute_force(seed):
    """assign() reaches the brute-force maximum summed score, each row/column at most once."""
    rng = np.random.default_rng(seed)
    n, m = rng.integers(1, 5, 2)
    score = rng.uniform(0, 1, (n, m))
    valid = rng.uniform(0, 1, (n, m)) < 0.6
    r, c = assign(score, valid)
    assert len(set(r)) == len(r) and len(set(c)) == len(c)
    assert valid[r, c].all()
    assert_allclose(score[r, c].sum(), _brute_force(score, valid), rtol=1e-12)


def test_assignment_without_conflict_takes_each_best():
    """Without conflicts each row takes its highest valid column."""
    score = np.array([[0.9, 0.1, 0.3], [0.2, 0.4, 0.8]])
    r, c = assign(score, np.ones_like(score, dtype=bool))
    assert r.tolist() == [0, 1] and c.tolist() == [0, 2]
    with pytest.raises(ValueError, match="same shape|one shape"):
        assign(score, np.ones((1, 1), dtype=bool))


@pytest.mark.parametrize("history, expected", [
    ([True], "tentative"),
    ([True, True], "tentative"),
    ([True, True, True], "confirmed"),
    ([True, False, True, True], "confirmed"),
    ([True, False, False], "deleted"),
    ([True, True, False, False], "deleted"),
    ([True, True, True] + [False] * 4, "confirmed"),
    ([True, True, True] + [False] * 5, "deleted"),
    ([True, True, True, False, False, True, False, False, False, False], "confirmed"),
])
def test_confirmation_and_deletion_table(history, expected):
    """3-of-4 confirmation and deletion after 5 consecutive misses, by table."""
    assert track_status(history, m=3, n=4, max_misses=5) == expected


@pytest.mark.parametrize("heading, expected", [
    ((0.0, 1.0), 90.0), ((0.0, -1.0), 90.0), ((1.0, 0.0), 0.0), ((-1.0, 0.0), 180.0),
    ((1.0, 1.0), 45.0),
])
def test_aspect_known_answers_monostatic(heading, expected):
    """Source and receiver together to the east: north/south headings are specular (90 deg)."""
    a = equivalent_aspect_deg([0.0, 0.0], heading, [5000.0, 0.0], [5000.0, 0.0])
    assert_allclose(a, expected, atol=1e-5)


def test_aspect_bistatic_bisector():
    """Source north, receiver east: bisector points north-east; heading north-west is 90 deg."""
    a = equivalent_aspect_deg([0, 0], [[-1, 1], [1, 1], [0, 1]], [0, 3000], [3000, 0])
    assert_allclose(a, [90.0, 0.0, 45.0], atol=1e-5)
    assert np.isnan(equivalent_aspect_deg([0, 0], [0, 0], [0, 1000], [1000, 0]))


def _hotspot_scenario(seed, n_pings=12):
    """Target crossing at 3 m/s, specular-ish, good scores; two strong fixed hotspots."""
    rng = np.random.default_rng(seed)
    rows = {k: [] for k in ("event", "time", "x", "y", "snr_db", "score", "aspect_deg")}
    hot = np.array([[3000.0, 3000.0], [-2000.0, 4000.0]])
    for k in range(n_pings):
        t = 90.0 * k
        pts = [np.array([-3000.0 + 3.0 * t, 0.0]) + rng.normal(0, 60, 2)]
        clues = [(rng.uniform(14, 22), rng.uniform(0.7, 1.0), rng.uniform(80, 100))]
        for h in hot:
            pts.append(h + rng.normal(0, 60, 2))
            clues.append((rng.uniform(22, 28), rng.uniform(0.2, 0.5), rng.uniform(0, 50)))
        pts.append(rng.uniform(-8000, 8000, 2))
        clues.append((rng.uniform(10, 13), rng.uniform(0.0, 0.4), rng.uniform(0, 180)))
        for p, (snr, sc, asp) in zip(pts, clues, strict=True):
            for key, v in zip(rows, (k, t, p[0], p[1], snr, sc, asp), strict=True):
                rows[key].append(v)
    cols = {k: np.asarray(v, dtype=float) for k, v in rows.items()}
    cols["event"] = cols["event"].astype(np.int64)
    return Table(cols), hot


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fuzzy_confirms_target_not_hotspots(seed):
    """Fuzzy mode confirms the target and no hotspot; Kalman mode confirms the hotspots too."""
    table, hot = _hotspot_scenario(seed)
    for mode in ("fuzzy", "kalman"):
        cols = Tracker(mode=mode).run(table).columns()
        conf = cols["status"] == "confirmed"
        xy = np.column_stack([cols["x"], cols["y"]])[conf]
        near_hot = np.min(np.linalg.norm(xy[:, None] - hot[None], axis=2), axis=1) < 500
        on_target = np.abs(xy[:, 1]) < 500
        assert on_target.any(), mode
        if mode == "fuzzy":
            assert not near_hot.any()
        else:
            assert near_hot.any()


def test_positions_only_still_tracks_and_skips_rules():
    """Without clue columns the tracker runs on the likelihood (and hotspot) rules alone."""
    table, _ = _hotspot_scenario(0)
    bare = Table({k: table[k] for k in ("event", "time", "x", "y")})
    cols = Tracker().run(bare).columns()
    conf = cols["status"] == "confirmed"
    assert np.any(conf & (np.abs(cols["y"]) < 500))


def test_step_equals_run_and_is_deterministic():
    """Streaming step() equals batch run(); two runs give identical output."""
    table, _ = _hotspot_scenario(3, n_pings=6)
    a = Tracker().run(table).columns()
    b = Tracker().run(table).columns()
    tr = Tracker()
    pings = [tr.step(p) for p in pings_from_table(table)]
    c = np.concatenate([p.state for p in pings])
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    assert_allclose(np.column_stack([a["x"], a["y"], a["vx"], a["vy"]]), c)


def test_missing_event_counts_as_empty_ping():
    """An event number absent from the table becomes an empty ping at an interpolated time."""
    t = Table({"event": np.array([0, 2]), "time": np.array([0.0, 100.0]),
               "x": np.array([0.0, 1.0]), "y": np.array([0.0, 1.0])})
    pings = pings_from_table(t)
    assert [p.event for p in pings] == [0, 1, 2]
    assert pings[1].n == 0 and pings[1].time == 50.0


def test_bad_inputs():
    """Bad options and pings raise ValueError."""
    with pytest.raises(ValueError, match="mode"):
        Tracker(mode="nearest")
    with pytest.raises(ValueError, match="unknown clue"):
        Tracker(clues=["colour"])
    with pytest.raises(ValueError, match="confirm_hits"):
        Tracker(confirm_hits=5, confirm_window=4)
    with pytest.raises(ValueError, match="clue 'snr_db'"):
        Ping(0, 0.0, np.zeros((2, 2)), {"snr_db": np.zeros(3)})
    tr = Tracker()
    tr.step(Ping(0, 10.0, np.zeros((1, 2))))
    with pytest.raises(ValueError, match="goes back"):
        tr.step(Ping(1, 5.0, np.zeros((1, 2))))


def test_cli_round_trip(tmp_path, run_cli):
    """fusion track writes the formats.md columns; kalman mode too; notes absent clues once."""
    table, _ = _hotspot_scenario(0)
    src = tmp_path / "d.csv"
    write_table(src, {k: table[k] for k in ("event", "time", "x", "y", "snr_db", "score")})
    out = tmp_path / "t.csv"
    code, _, err = run_cli("track", "--detections", src, "--out", out)
    assert code == 0
    assert err.count("note") == 1 and "aspect_deg" in err
    t = read_table(out, required=("track_id", "event", "time", "x", "y", "vx", "vy", "status"),
                   text=("status",))
    assert set(t["status"]) <= {"tentative", "confirmed", "deleted"}
    assert "confirmed" in set(t["status"])
    code, _, _ = run_cli("track", "--detections", src, "--out", tmp_path / "k.csv",
                         "--mode", "kalman", "--confirmed-only")
    assert code == 0


def test_cli_bad_input_exit_2(tmp_path, run_cli):
    """Missing column, missing file and a bad option: exit 2 with one line, no output file."""
    bad = tmp_path / "bad.csv"
    bad.write_text("event,time,x\n0,0,1\n")
    out = tmp_path / "t.csv"
    code, _, err = run_cli("track", "--detections", bad, "--out", out)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "column" in err
    code, _, err = run_cli("track", "--detections", tmp_path / "none.csv", "--out", out)
    assert code == 2 and len(err.strip().splitlines()) == 1
    good = tmp_path / "g.csv"
    good.write_text("event,time,x,y\n0,0,1,1\n")
    code, _, err = run_cli("track", "--detections", good, "--out", out, "--min-rank", "2")
    assert code == 2 and "--min-rank" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def _union_centroid(low, medium, high):
    """Centroid of max(min(low, tri(0,0,.5)), min(medium, tri(0,.5,1)), min(high, tri(.5,1,1)))
    by a dense trapezoid rule (independent of the engine's exact integration)."""
    y = np.linspace(0.0, 1.0, 400001)
    mu = np.maximum.reduce([np.minimum(low, np.clip(1 - y / 0.5, 0, 1)),
                            np.minimum(medium, np.clip(1 - np.abs(y - 0.5) / 0.5, 0, 1)),
                            np.minimum(high, np.clip((y - 0.5) / 0.5, 0, 1))])
    return np.trapezoid(y * mu, y) / np.trapezoid(mu, y)


def test_neutral_values_are_the_crossovers():
    """Neutral clue values: where the default terms are 1/2 (score 0.65, aspect 70 deg,
    SNR 16 dB, hotspot 300 m)."""
    names = [v.name for v in default_variables()]
    values = {n: neutral_value(v) for n, v in zip(names, default_variables(), strict=True)}
    assert values["score"] == pytest.approx(0.65)
    assert values["aspect_deg"] == pytest.approx(70.0)
    assert values["snr_db"] == pytest.approx(16.0)
    assert values["hotspot_distance_m"] == pytest.approx(300.0)


def test_threshold_derivation_known_ranks():
    """The derived threshold is the documented rank at L = 0.25 with neutral clues:
    likelihood alone: unlikely = somewhat_likely = 1/2 -> 0.4405; with the hotspot clue at
    300 m (near = 1/2, rule weight 0.8): low = 0.9, medium = 0.5 -> 0.3977."""
    system = default_association_system()
    assert EDGE_LIKELIHOOD == 0.25
    alone = derived_min_rank(system, [])
    assert alone == pytest.approx(_union_centroid(0.5, 0.5, 0.0), abs=1e-6)
    assert round(alone, 4) == 0.4405
    hot = derived_min_rank(system, ["hotspot_distance_m"])
    assert hot == pytest.approx(_union_centroid(0.9, 0.5, 0.0), abs=1e-6)
    assert round(hot, 4) == 0.3977
    # All clues (rules 4, 6, 7 at 1/2 strength): low 0.5 + 0.3 + 0.4 -> 1, medium 0.5,
    # high 0.2 + 0.3 = 0.5.
    every = derived_min_rank(system, ["score", "snr_db", "aspect_deg", "hotspot_distance_m"])
    assert every == pytest.approx(_union_centroid(1.0, 0.5, 0.5), abs=1e-6)
    # A detection exactly at the edge with neutral clues is accepted; a little further, not.
    for present, limit in (([], alone), (["hotspot_distance_m"], hot)):
        inputs = {"likelihood": np.array([0.25, 0.2])}
        if present:
            inputs["hotspot_distance_m"] = np.array([300.0, 300.0])
        r = system.evaluate(inputs).crisp
        assert r[0] >= limit - 1e-12 and r[1] < limit
    with pytest.raises(ValueError, match="edge_likelihood"):
        derived_min_rank(system, [], edge_likelihood=0.0)


def test_tracker_threshold_follows_the_clues():
    """Positions-only data get the positions-only threshold, all-clue data the all-clue one."""
    table, _ = _hotspot_scenario(0)
    tr = Tracker()
    tr.run(Table({k: table[k] for k in ("event", "time", "x", "y")}))
    assert set(tr.ranker.thresholds) == {frozenset({"hotspot_distance_m"})}
    tr = Tracker(aspect="measured")
    tr.run(table)
    assert set(tr.ranker.thresholds) == {frozenset(("score", "snr_db", "aspect_deg",
                                              "hotspot_distance_m"))}
    # Without source/receiver positions the aspect cannot come from geometry: the column is
    # ignored unless declared a measurement.
    tr = Tracker()
    tr.run(table)
    assert set(tr.ranker.thresholds) == {frozenset(("score", "snr_db", "hotspot_distance_m"))}
    assert Tracker(min_rank=0.6).threshold(["score"]) == 0.6


def test_tentative_track_on_a_hotspot_is_dropped():
    """A fixed echo on every ping starts a track on ping 0 that is dropped when the map flags
    the echo (its third ping, index 2), before 3-of-4 confirmation; Kalman mode confirms it."""
    rng = np.random.default_rng(0)
    pings = [Ping(k, 90.0 * k, np.array([[5000.0, 5000.0]]) + rng.normal(0, 30, (1, 2)))
             for k in range(6)]
    fuzzy = _paper().run(pings)
    assert fuzzy.confirmed_ids().size == 0
    assert fuzzy.pings[2].status[0] == "deleted"
    assert Tracker(mode="kalman").run(pings).confirmed_ids().size == 1


def test_motion_statistic_known_answer_and_calibration():
    """2 m/s over three pings 90 s apart, 100-m errors: |v|^2 S_tt / sigma^2 = 4 * 16200 / 1e4;
    for a stationary object the statistic is chi-square with 2 degrees of freedom."""
    q = motion_statistic([0.0, 90.0, 180.0], [[0.0, 0.0], [180.0, 0.0], [360.0, 0.0]], 100.0)
    assert q == pytest.approx(6.48)
    assert motion_statistic([5.0, 5.0], [[0.0, 0.0], [100.0, 0.0]], 100.0) == 0.0
    rng = np.random.default_rng(8)
    t = np.array([0.0, 70.0, 150.0, 230.0])
    qs = np.array([motion_statistic(t, rng.normal(0, 100.0, (4, 2)), 100.0) for _ in range(20000)])
    assert abs(qs.mean() - 2.0) < 0.05
    assert abs(np.mean(qs > chi2.ppf(0.99, 2)) - 0.01) < 0.003


def _crossing_pings(k_birth=3, n=8):
    """A fixed feature at the origin on every ping; from ping ``k_birth`` a target at 4 m/s
    that reaches the feature's region on its third detection."""
    rng = np.random.default_rng(2)
    pings = []
    for k in range(n):
        xy = [[0.0, 0.0] + rng.normal(0, 30.0, 2)]
        if k >= k_birth:
            xy.append([-1100.0 + 360.0 * (k - k_birth), 0.0] + rng.normal(0, 30.0, 2))
        pings.append(Ping(k, 90.0 * k, np.array(xy)))
    return pings


def test_moving_tentative_track_survives_a_hotspot():
    """A tentative track that reaches a hotspot region on its third detection is kept and
    confirmed when its detections move significantly (4 m/s: statistic 25.9 > 13.8); without
    the motion test (probability -> 1) it is dropped like the feature's own track."""
    pings = _crossing_pings()
    res = _paper().run(pings)
    assert len(res.pings[4].hotspots) == 1
    conf = res.confirmed_ids()
    assert conf.size == 1
    cols = res.columns()
    m = (cols["track_id"] == conf[0]) & (cols["status"] == "confirmed")
    assert np.all(np.abs(cols["y"][m]) < 200) and cols["x"][m].min() < -200
    assert _paper(motion_probability=1 - 1e-12).run(pings).confirmed_ids().size == 0
    with pytest.raises(ValueError, match="motion_probability"):
        Tracker(motion_probability=1.0)


# ------------------------------------------------------------------------------------------
# geometry-aware (bistatic) position errors
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("target, receiver", [
    ([3000.0, 6000.0], [5000.0, 1000.0]),       # wide bistatic angle, range error matters
    ([-6000.0, -5000.0], [5000.0, 1000.0]),     # far from the receiver: bearing error dominates
    ([2500.0, 2000.0], [5000.0, 0.0]),          # near the baseline (still outside blanking)
    ([0.0, 3000.0], [0.0, 0.0]),                # monostatic
])
def test_bistatic_covariance_equals_monte_carlo(target, receiver):
    """First-order covariance equals the sample covariance of bistatic_position with Gaussian
    range-sum (30 m) and bearing (1 deg) errors: every element within 3 % of the scale
    sqrt(C_ii C_jj) (Monte Carlo standard error ~0.3 %)."""
    rng = np.random.default_rng(11)
    s, r, p = np.zeros(2), np.asarray(receiver), np.asarray(target)
    rho = np.linalg.norm(p - s) + np.linalg.norm(p - r)
    theta = np.arctan2(p[0] - r[0], p[1] - r[1])
    n = 200_000
    z = bistatic_position(s, r, rho + rng.normal(0.0, 30.0, n),
                          theta + rng.normal(0.0, np.radians(1.0), n))
    mc = np.cov(z.T)
    c = bistatic_covariance([p], s, r, 30.0, 1.0)[0]
    scale = np.sqrt(np.outer(np.diag(mc), np.diag(mc)))
    assert np.all(np.abs(c - mc) <= 0.03 * scale), (c, mc)
    assert_allclose(c, c.T)


def test_bistatic_covariance_degenerate_points_are_nan():
    """An echo on the receiver or on the baseline between source and receiver has no
    first-order covariance (NaN)."""
    c = bistatic_covariance([[5000.0, 0.0], [2500.0, 0.0], [7000.0, 0.0]], [0.0, 0.0],
                            [5000.0, 0.0], 30.0, 1.0)
    assert np.isnan(c[0]).all() and np.isnan(c[1]).all()
    assert np.isfinite(c[2]).all()        # beyond the receiver, on the baseline's extension


def test_measurement_covariances_geometry_and_fallback():
    """Detections with source/receiver positions get the bistatic ellipse; without positions,
    with NaN positions, on the baseline, or with position_errors='isotropic' they get
    position_sigma_m^2 I."""
    xy = np.array([[3000.0, 6000.0], [2500.0, 0.0], [-4000.0, 2000.0]])
    geo = {"src_x": np.zeros(3), "src_y": np.zeros(3), "rcv_x": np.array([5000.0, 5000.0, np.nan]),
           "rcv_y": np.zeros(3)}
    tr = Tracker(position_sigma_m=80.0, range_sum_sigma_m=20.0, bearing_sigma_deg=2.0,
                 noise="fixed")
    R, geometric = tr.measurement_covariances(Ping(0, 0.0, xy, geo))
    assert geometric
    assert_allclose(R[0], bistatic_covariance(xy[:1], [0, 0], [5000, 0], 20.0, 2.0)[0])
    assert_allclose(R[1:], np.broadcast_to(np.eye(2) * 80.0**2, (2, 2, 2)))
    for ping, trk in ((Ping(0, 0.0, xy), tr),
                      (Ping(0, 0.0, xy, geo), Tracker(position_sigma_m=80.0,
                                                      position_errors="isotropic"))):
        R, geometric = trk.measurement_covariances(ping)
        assert not geometric
        assert_allclose(R, np.broadcast_to(np.eye(2) * 80.0**2, (3, 2, 2)))


def test_new_track_and_update_use_the_detection_covariance():
    """A new track's position covariance is its detection's ellipse; the Kalman update of the
    next ping uses the next detection's ellipse (equal to filterpy with that R)."""
    src, rcv = np.zeros(2), np.array([5000.0, 1000.0])
    geo = {"src_x": [0.0], "src_y": [0.0], "rcv_x": [rcv[0]], "rcv_y": [rcv[1]]}
    z0, z1 = np.array([[-6000.0, -5000.0]]), np.array([[-5800.0, -5150.0]])
    tr = Tracker(mode="kalman", noise="fixed", range_sum_sigma_m=30.0, bearing_sigma_deg=1.0)
    tr.step(Ping(0, 0.0, z0, geo))
    R0 = bistatic_covariance(z0, src, rcv, 30.0, 1.0)[0]
    assert_allclose(tr._P[0, :2, :2], R0)
    x0, P0 = tr._x[0].copy(), tr._P[0].copy()
    tr.step(Ping(1, 80.0, z1, geo))
    kf = KalmanFilter(dim_x=4, dim_z=2)
    F, Q = cv_model(80.0, tr.accel_psd)
    kf.x, kf.P, kf.F, kf.Q = x0, P0, F, Q
    kf.H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    kf.R = bistatic_covariance(z1, src, rcv, 30.0, 1.0)[0]
    kf.predict()
    kf.update(z1[0])
    assert_allclose(tr._x[0], kf.x, rtol=1e-9, atol=1e-9)
    assert_allclose(tr._P[0], kf.P, rtol=1e-8, atol=1e-8)


def test_update_with_full_per_track_R_equals_filterpy():
    """kf_update with a different full (correlated) R per track equals filterpy."""
    rng = np.random.default_rng(5)
    xs, Ps = zip(*(_random_track(rng) for _ in range(4)), strict=True)
    A = rng.normal(0.0, 60.0, (4, 2, 2))
    R = A @ np.swapaxes(A, 1, 2) + np.eye(2) * 25.0
    z = rng.normal(0, 1000, (4, 2))
    x2, P2 = kf_update(np.array(xs), np.array(Ps), z, R)
    for i in range(4):
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x, kf.P, kf.R = xs[i].copy(), Ps[i].copy(), R[i]
        kf.H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
        kf.update(z[i])
        assert_allclose(x2[i], kf.x, rtol=1e-9, atol=1e-9)
        assert_allclose(P2[i], kf.P, rtol=1e-8, atol=1e-8)


def test_likelihood_with_per_detection_R_equals_scipy():
    """Pair statistics with one R per detection: S = P_t + R_d for every pair."""
    rng = np.random.default_rng(6)
    xs, Ps = zip(*(_random_track(rng) for _ in range(3)), strict=True)
    x, P = np.array(xs), np.array(Ps)
    z = rng.normal(0, 1000, (5, 2))
    A = rng.normal(0.0, 80.0, (5, 2, 2))
    R = A @ np.swapaxes(A, 1, 2) + np.eye(2)
    st = pair_statistics(x, P, z, R)
    for t in range(3):
        for d in range(5):
            S = P[t, :2, :2] + R[d]
            assert st.log_pdf[t, d] == pytest.approx(
                multivariate_normal(x[t, :2], S).logpdf(z[d]), rel=1e-9)
            nu = z[d] - x[t, :2]
            assert st.d2[t, d] == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-9)


def test_motion_statistic_with_covariances():
    """With sigma^2 I covariances the generalised statistic equals the isotropic one; with
    elongated, differently oriented covariances it is chi-square (2 dof) for a stationary
    object."""
    rng = np.random.default_rng(9)
    t = np.array([0.0, 70.0, 150.0, 230.0])
    xy = rng.normal(0, 100.0, (4, 2))
    iso = np.broadcast_to(np.eye(2) * 100.0**2, (4, 2, 2))
    assert motion_statistic(t, xy, cov=iso) == pytest.approx(motion_statistic(t, xy, 100.0))
    ang = np.radians([0.0, 40.0, 100.0, 160.0])
    rot = np.stack([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]]).transpose(2, 0, 1)
    C = rot @ np.diag([250.0**2, 30.0**2]) @ np.swapaxes(rot, 1, 2)
    L = np.linalg.cholesky(C)
    qs = np.array([motion_statistic(t, np.einsum("kij,kj->ki", L, rng.normal(size=(4, 2))),
                                    cov=C) for _ in range(20000)])
    assert abs(qs.mean() - 2.0) < 0.06
    assert abs(np.mean(qs > chi2.ppf(0.99, 2)) - 0.01) < 0.003
    with pytest.raises(ValueError, match="exactly one"):
        motion_statistic(t, xy)


def test_geometry_errors_on_a_simulated_run():
    """On a simulated run with source/receiver columns, geometry errors and isotropic errors
    both track; the hotspot extents differ (they follow the receivers' error ellipses)."""
    sc = simulate_multistatic(seed=3)
    geo = Tracker().run(sc.detections)
    iso = Tracker(position_errors="isotropic").run(sc.detections)
    assert geo.confirmed_ids().size > 0 and iso.confirmed_ids().size > 0
    assert not np.array_equal(geo.columns()["x"], iso.columns()["x"])


def test_position_error_options_rejected():
    """Bad position-error options raise ValueError naming the option."""
    with pytest.raises(ValueError, match="position_errors"):
        Tracker(position_errors="ellipse")
    with pytest.raises(ValueError, match="range_sum_sigma_m"):
        Tracker(range_sum_sigma_m=-1.0)
    with pytest.raises(ValueError, match="bearing_sigma_deg"):
        Tracker(bearing_sigma_deg=float("nan"))
    with pytest.raises(ValueError, match="both be 0"):
        Tracker(range_sum_sigma_m=0.0, bearing_sigma_deg=0.0)


def test_cli_position_error_flags(tmp_path, run_cli):
    """fusion track --position-errors isotropic differs from the default geometry errors on
    data with source/receiver columns; --range-sum-sigma-m / --bearing-sigma-deg are used."""
    sc = simulate_multistatic(seed=3)
    d = sc.detections
    src = tmp_path / "d.csv"
    write_table(src, {k: d[k] for k in ("event", "time", "x", "y", "snr_db", "score",
                                        "aspect_deg", "src_x", "src_y", "rcv_x", "rcv_y")})
    outs = {}
    for name, extra in (("geo", ()), ("iso", ("--position-errors", "isotropic")),
                        ("sig", ("--range-sum-sigma-m", "60", "--bearing-sigma-deg", "2"))):
        out = tmp_path / f"{name}.csv"
        code, _, _ = run_cli("track", "--detections", src, "--out", out, *extra)
        assert code == 0
        outs[name] = read_table(out, required=("x",), text=("status",))["x"]
    assert not np.array_equal(outs["geo"], outs["iso"])
    assert not np.array_equal(outs["geo"], outs["sig"])
    code, _, err = run_cli("track", "--detections", src, "--out", tmp_path / "b.csv",
                           "--bearing-sigma-deg", "-1")
    assert code == 2 and "--bearing-sigma-deg" in err


# ------------------------------------------------------------------------------------------
# stationary tracks are held tentative (track-level form of the clutter-map test)
# ------------------------------------------------------------------------------------------
def _no_flag_map():
    """A clutter map that cannot flag anything within a short run (min_pings = 50)."""
    from fusion.active.clutter import ClutterMap

    return ClutterMap(min_pings=50)


def _line_pings(speed_mps, n=10, interval=90.0, noise_m=0.0, seed=0):
    """One detection per ping moving east at ``speed_mps`` (positions only: 100-m errors)."""
    rng = np.random.default_rng(seed)
    return [Ping(k, interval * k, np.array([[speed_mps * interval * k, 3000.0]])
                 + rng.normal(0, noise_m, (1, 2))) for k in range(n)]


def test_stationary_track_is_held_until_misses_end_it():
    """A fixed echo the map does not flag: confirmed on its third ping (index 2) on hits alone;
    held tentative by default, and deleted after max_misses (5) consecutive misses once the
    echo stops (pings 6-10 empty: deleted on ping 10)."""
    pings = _line_pings(0.0, n=6, noise_m=30.0)
    pings += [Ping(k, 90.0 * k, np.zeros((0, 2))) for k in range(6, 12)]
    plain = _paper(clutter_map=_no_flag_map(), hold_stationary=False).run(pings)
    assert plain.confirmed_ids().tolist() == [0]
    assert plain.pings[2].status[0] == "confirmed"
    held = _paper(clutter_map=_no_flag_map()).run(pings)
    assert held.confirmed_ids().size == 0
    status = [str(p.status[p.track_id == 0][0]) for p in held.pings if (p.track_id == 0).any()]
    assert status == ["tentative"] * 10 + ["deleted"]


def test_moving_track_is_confirmed_on_its_third_hit():
    """4 m/s, 90 s pings, 100-m errors: the motion statistic of three exact detections is
    16 * 16200 / 1e4 = 25.9 > 13.8 (chi-square 2 dof at 0.999): confirmed on ping 2 as before."""
    pings = _line_pings(4.0, n=4)
    q = motion_statistic([0.0, 90.0, 180.0], [p.xy[0] for p in pings[:3]], 100.0)
    assert q == pytest.approx(25.92)
    res = _paper(clutter_map=_no_flag_map()).run(pings)
    assert res.pings[2].status[0] == "confirmed"


def test_slow_track_is_confirmed_once_it_moves_significantly():
    """1 m/s, 90 s pings, exact positions, 100-m errors: k detections give
    S_tt = 8100 k (k^2 - 1) / 12 and the statistic 1 * S_tt / 1e4, which first exceeds
    chi2.ppf(0.999, 2) = 13.82 at k = 6 (14.18; k = 5: 8.10): confirmed on ping 5, not 2."""
    pings = _line_pings(1.0, n=8)
    gate = chi2.ppf(0.999, 2)
    qs = [motion_statistic(90.0 * np.arange(k), [p.xy[0] for p in pings[:k]], 100.0)
          for k in range(3, 8)]
    assert_allclose(qs, [8100 * k * (k * k - 1) / 12 / 1e4 for k in range(3, 8)])
    assert [q > gate for q in qs] == [False, False, False, True, True]
    res = _paper(clutter_map=_no_flag_map()).run(pings)
    status = [str(p.status[0]) for p in res.pings]
    assert status == ["tentative"] * 5 + ["confirmed"] * 3
    assert _paper(clutter_map=_no_flag_map(), hold_stationary=False).run(
        pings).pings[2].status[0] == "confirmed"


def test_hold_is_fuzzy_only():
    """Kalman mode (no clutter map) confirms a fixed echo on hits alone."""
    pings = _line_pings(0.0, n=4, noise_m=30.0)
    assert Tracker(mode="kalman").run(pings).pings[2].status[0] == "confirmed"


def test_cli_confirm_stationary_flag(tmp_path, run_cli):
    """A fixed echo scattered by 30 m, with 1-m map cells (the map never flags it): the default
    holds its track tentative; --confirm-stationary confirms it on its third ping."""
    rng = np.random.default_rng(4)
    rows = {"event": np.arange(5), "time": 90.0 * np.arange(5),
            "x": rng.normal(0, 30.0, 5), "y": 3000.0 + rng.normal(0, 30.0, 5)}
    src = tmp_path / "d.csv"
    write_table(src, rows)
    for flag, out in (((), "a.csv"), (("--confirm-stationary",), "b.csv")):
        code, _, _ = run_cli("track", "--detections", src, "--out", tmp_path / out,
                             "--hotspot-cell-m", "1", *flag)
        assert code == 0
    a = read_table(tmp_path / "a.csv", required=("status",), text=("status",))
    b = read_table(tmp_path / "b.csv", required=("status",), text=("status",))
    assert "confirmed" not in set(a["status"])
    assert list(b["status"][:5]) == ["tentative", "tentative", "confirmed", "confirmed",
                                     "confirmed"]
