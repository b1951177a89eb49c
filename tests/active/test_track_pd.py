"""Each track's own detection probability per receiver in the track score (issue 20,
``--track-pd-prior-pings``; :mod:`fusion.active.track_pd`)."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.active.track_pd import TrackRates
from fusion.active.track_score import TrackScorer
from fusion.active.tracker import Tracker
from fusion.simulate.multistatic_varied import simulate_varied

KEY = (0.0, 0.0, 5000.0, 0.0)


def _scan(scorer, hit: bool, n_tracks: int = 1):
    """One scan of a receiver: track 0 takes detection 0 (or misses); far from the blind zone."""
    xy = np.array([[0.0, 9000.0]])
    return scorer.scan_delta(
        KEY, xy=xy, cov=np.eye(2)[None] * 1e4, scores=None, hotspots=None,
        track_xy=np.tile([0.0, 9000.0], (n_tracks, 1)),
        hits=np.array([0]) if hit else np.zeros(0, np.int64),
        dets=np.array([0]) if hit else np.zeros(0, np.int64),
        log_pdf=np.array([-13.0]) if hit else np.zeros(0), confirmed=np.zeros(n_tracks, bool))


def test_misses_and_hits_score_the_beta_bernoulli_predictive():
    """Known answer: prior P_D 0.7 worth 1 ping; miss, miss, hit. Predictives 0.7, 0.35,
    0.7/3; the receiver's P_D alone charges ln 0.3 on every miss."""
    sc = TrackScorer(detection_probability=0.7, clutter_intensity=1e-7, track_pd_prior_pings=1.0)
    plain = TrackScorer(detection_probability=0.7, clutter_intensity=1e-7)
    for s in (sc, plain):
        s.remember(np.zeros(0, np.int64), np.zeros(0, np.int64), KEY, np.zeros((0, 2)), new=1)
    got = [_scan(sc, h)[0] for h in (False, False, True)]
    ref = [_scan(plain, h)[0] for h in (False, False, True)]
    hit = -13.0 - math.log(1e-7)
    assert_allclose(got, [math.log(0.3), math.log(0.65), math.log(0.7 / 3) + hit])
    assert_allclose(ref, [math.log(0.3), math.log(0.3), math.log(0.7) + hit])
    # Exact in any order: the sum is the Beta-Bernoulli likelihood B(a + 1, b + 2) / B(a, b).
    a, b = 0.7, 0.3
    lik = math.lgamma(a + 1) + math.lgamma(b + 2) - math.lgamma(a + b + 3) - (
        math.lgamma(a) + math.lgamma(b) - math.lgamma(a + b))
    assert sum(got) - hit == pytest.approx(lik)


def test_track_rates_follow_births_and_deletions():
    r = TrackRates(prior_pings=2.0)
    r.add(3)
    r.count("k", np.array([0, 1, 2]), np.array([True, False, True]))
    r.keep(np.array([False, True, True]))
    r.add(1)
    assert_allclose(r.predictive("k", 0.5, np.arange(3)), [1.0 / 3.0, 2.0 / 3.0, 0.5])
    with pytest.raises(ValueError):
        TrackRates(prior_pings=0.0)


def test_option_changes_the_tracks_scores_on_a_scenario():
    """On a simulated multistatic run the option changes the tracker's output (it is wired)."""
    sc = simulate_varied(1000, target_pd=0.5, clutter_per_receiver=10)
    a = Tracker(track_pd_prior_pings=1.0).run(sc.detections).columns()
    b = Tracker().run(sc.detections).columns()
    assert len(a["track_id"]) != len(b["track_id"]) or not np.array_equal(a["status"], b["status"])


def test_cli_option_reaches_the_tracker_and_bad_value_exits_2(tmp_path, run_cli, monkeypatch):
    import fusion.active.tracker as tracker_module
    from fusion.io import write_table

    sc = simulate_varied(1001, target_pd=0.5, clutter_per_receiver=2)
    write_table(tmp_path / "d.csv", {k: v for k, v in sc.detections.columns.items()
                                      if k not in ("origin", "receiver")})
    seen = []

    class Spy(tracker_module.Tracker):
        def __init__(self, **kw):
            seen.append(kw.get("track_pd_prior_pings"))
            super().__init__(**kw)

    monkeypatch.setattr(tracker_module, "Tracker", Spy)
    code, _, err = run_cli("track", "--detections", tmp_path / "d.csv", "--out", tmp_path / "t.csv",
                           "--track-pd-prior-pings", "2")
    assert code == 0, err
    assert seen and seen[-1] == 2.0
    code, _, err = run_cli("track", "--detections", tmp_path / "d.csv", "--out", tmp_path / "u.csv",
                           "--track-pd-prior-pings", "0")
    assert code == 2 and "track-pd-prior-pings" in err
