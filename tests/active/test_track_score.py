"""Tests of the track score (fusion.active.track_score) and of the tracker parts it works with."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.active.clutter import Hotspots
from fusion.active.kalman import fuse_positions, kf_update
from fusion.active.track_score import TrackScorer
from fusion.active.types import Ping, receiver_groups

KEY = (0.0, 0.0, 5000.0, 0.0)


def test_hit_and_miss_known_answers():
    """Given P_D and lambda: a hit adds ln P_D + ln N - ln lambda, a miss ln(1 - P_D)."""
    sc = TrackScorer(detection_probability=0.8, clutter_intensity=2e-7)
    assert_allclose(sc.hit_delta(KEY, [-12.0], [2e-7]), math.log(0.8) - 12.0 - math.log(2e-7))
    assert_allclose(sc.miss_delta(KEY), math.log(0.2))
    assert_allclose(sc.observe(KEY, [[0.0, 0.0], [1.0, 1.0]], None), 2e-7)


def test_detection_probability_estimate():
    """With no counts P_D is the Beta(7, 3) prior mean 0.7; 90 hits in 100 confirmed pings give
    (7 + 90) / (10 + 100); receivers are counted apart."""
    sc = TrackScorer()
    assert sc.pd(KEY) == pytest.approx(0.7)
    sc.count_confirmed(KEY, 90, 100)
    assert sc.pd(KEY) == pytest.approx(97 / 110)
    assert sc.pd((1.0, 1.0, 1.0, 1.0)) == pytest.approx(0.7)
    sc.reset()
    assert sc.pd(KEY) == pytest.approx(0.7)


def test_no_miss_penalty_in_the_blind_zone():
    """Once a receiver has reported echoes with range-sum excess >= 2 km, a track whose excess
    is below that scores 0 for a miss there, one outside ln(1 - P_D)."""
    sc = TrackScorer(detection_probability=0.6, clutter_intensity=1e-7)
    # receiver 5 km east of the source; echoes 3 km north of the midpoint: excess ~2.8 km
    sc.observe(KEY, [[2500.0, 3000.0], [2500.0, -3000.0]], None)
    near = [2500.0, 500.0]      # excess ~0.1 km: hidden by the direct blast
    far = [2500.0, 6000.0]
    assert_allclose(sc.miss_delta(KEY, [near, far]), [0.0, math.log(0.4)])
    assert_allclose(sc.miss_delta(None, [near]), [math.log(0.4)])


def test_score_evidence_prefers_high_scores_and_learns_the_clutter():
    """After many low-score detections, a high score adds to the track score and a low one
    subtracts; without score evidence the scan deltas are the kinematic ones."""
    rng = np.random.default_rng(0)
    sc = TrackScorer(detection_probability=0.7, clutter_intensity=1e-7)
    xy = rng.uniform(-5000, 5000, (200, 2))
    scores = rng.beta(2, 5, 200)
    sc.scan_delta(KEY, xy=xy, cov=np.broadcast_to(np.eye(2) * 1e4, (200, 2, 2)), scores=scores,
                  hotspots=None, track_xy=np.zeros((0, 2)), hits=np.zeros(0, np.int64),
                  dets=np.zeros(0, np.int64), log_pdf=np.zeros(0), confirmed=np.zeros(0, bool))
    lr = sc.score_delta([0.9, 0.1])
    assert lr[0] > 1.0 and lr[1] < -0.5
    plain = TrackScorer(detection_probability=0.7, clutter_intensity=1e-7, score_evidence=False)
    d = plain.scan_delta(KEY, xy=xy[:2], cov=np.broadcast_to(np.eye(2) * 1e4, (2, 2, 2)),
                         scores=np.array([0.9, 0.1]), hotspots=None,
                         track_xy=np.array([[0.0, 9000.0], [0.0, 9000.0]]),
                         hits=np.array([0]), dets=np.array([1]), log_pdf=np.array([-13.0]),
                         confirmed=np.zeros(2, bool))
    assert_allclose(d, [math.log(0.7) - 13.0 - math.log(1e-7), math.log(0.3)])


def test_hotspot_adds_its_echo_rate_to_the_intensity():
    """A hotspot echoing once per ping (10 echoes in 10 pings, one receiver) adds
    N(x; c, C + R) to lambda: at its centre 1 / (2 pi sqrt|C + R|)."""
    sc = TrackScorer(detection_probability=0.7)
    C = np.array([[200.0**2, 0.0], [0.0, 100.0**2]])
    spots = Hotspots(np.array([[1000.0, 1000.0]]), C[None], 3.0, np.array([10]), np.array([10]),
                     10)
    R = np.eye(2) * 50.0**2
    plain = sc.observe(KEY, [[1000.0, 1000.0]], R[None])
    sc.reset()
    with_hot = sc.observe(KEY, [[1000.0, 1000.0]], R[None], hotspots=spots)
    S = C + R
    assert_allclose(with_hot - plain, 1.0 / (2 * np.pi * np.sqrt(np.linalg.det(S))), rtol=1e-9)


def test_bad_options():
    """Inconsistent thresholds and out-of-range settings raise ValueError."""
    with pytest.raises(ValueError, match="delete_llr"):
        TrackScorer(confirm_llr=1.0, delete_llr=2.0)
    with pytest.raises(ValueError, match="detection_probability"):
        TrackScorer(detection_probability=1.0)
    with pytest.raises(ValueError, match="clutter_intensity"):
        TrackScorer(clutter_intensity=0.0)


def test_fused_position_equals_sequential_updates():
    """A Kalman update with the information-weighted fusion of simultaneous detections equals
    the updates with each detection in turn."""
    rng = np.random.default_rng(2)
    x = rng.normal(0, 1000, (1, 4))
    A = rng.normal(0, 1, (4, 4))
    P = (A @ A.T * 1e4 + np.eye(4))[None]
    z = rng.normal(0, 500, (3, 2))
    R = np.stack([np.diag(rng.uniform(50, 300, 2) ** 2) for _ in range(3)])
    xs, Ps = x, P
    for k in range(3):
        xs, Ps = kf_update(xs, Ps, z[k:k + 1], R[k:k + 1])
    zf, C = fuse_positions(z, R)
    xf, Pf = kf_update(x, P, zf[None], C[None])
    assert_allclose(xf, xs, rtol=1e-8, atol=1e-6)
    assert_allclose(Pf, Ps, rtol=1e-8, atol=1e-6)


def test_receiver_groups_split_by_geometry():
    """Detections group by source/receiver geometry in order of appearance; without positions
    one group with key None."""
    geo = {"src_x": [0, 0, 0, 0], "src_y": [0, 0, 0, 0], "rcv_x": [5, 9, 5, 9],
           "rcv_y": [0, 0, 0, 0]}
    ping = Ping(0, 0.0, np.zeros((4, 2)), geo)
    groups = receiver_groups(ping)
    assert [k for k, _ in groups] == [(0.0, 0.0, 5.0, 0.0), (0.0, 0.0, 9.0, 0.0)]
    assert [i.tolist() for _, i in groups] == [[0, 2], [1, 3]]
    assert [(k, i.tolist()) for k, i in receiver_groups(Ping(0, 0.0, np.zeros((2, 2))))] == \
        [(None, [0, 1])]


def test_leave_one_out_intensity_equals_estimate_without_the_detection():
    """With ``leave_one_out`` the clutter intensity at a detection of the ping is the kernel
    estimate of the other remembered detections (cross-check: an estimator fed everything
    but that detection), not raised by the detection's own kernel; without it the detection's
    own kernel is added (on the first pings many times the clutter around it)."""
    from fusion.active.clutter.intensity import ClutterIntensity

    rng = np.random.default_rng(7)
    pings = [rng.uniform(-10000, 10000, (4, 2)) for _ in range(5)]     # sparse clutter
    key = None
    loo = TrackScorer(leave_one_out=True)
    plain = TrackScorer()
    for xy in pings[:-1]:
        loo.observe(key, xy, None)
        plain.observe(key, xy, None)
    last = pings[-1]
    lam_loo = loo.observe(key, last, None)
    lam_plain = plain.observe(key, last, None)
    for j in range(last.shape[0]):
        ref = ClutterIntensity()
        for xy in pings[:-1]:
            ref.update(xy)
        ref.update(np.delete(last, j, axis=0))
        expected = ref.intensity(last[j:j + 1])[0]
        assert lam_loo[j] == pytest.approx(expected, rel=0.05, abs=2e-9)
        # the detection's own kernel, 1 / (5 pings 2 pi 1000^2) = 3.2e-8 (to the grid's binning,
        # a few per cent), dominates sparse clutter
        assert lam_plain[j] - lam_loo[j] == pytest.approx(1 / (5 * 2 * np.pi * 1e6), rel=0.1)
        assert lam_plain[j] > 3 * lam_loo[j]


def test_leave_track_out_intensity_equals_estimate_without_the_tracks_detections():
    """With ``leave_track_out`` the clutter intensity at a track's hit is the kernel estimate of
    the remembered detections other than the track's own (this one and its earlier ones; cross-
    check: an estimator fed everything but them); a track's earlier echoes on another receiver
    or forgotten by the estimator are not taken out."""
    from fusion.active.clutter.intensity import ClutterIntensity

    rng = np.random.default_rng(11)
    clutter = [rng.uniform(-10000, 10000, (4, 2)) for _ in range(5)]
    target = np.array([[100.0 * k, 50.0 * k] for k in range(5)])     # a target's echoes
    pings = [np.vstack([c, t[None]]) for c, t in zip(clutter, target, strict=True)]
    key = (0.0, 0.0, 5000.0, 0.0)
    scorer = TrackScorer(leave_track_out=True, detection_probability=0.5)
    plain = TrackScorer(detection_probability=0.5)
    own = []
    for xy in pings[:-1]:
        scorer.observe(key, xy, None)
        plain.observe(key, xy, None)
        assert scorer.last_added.all()
        own.append((scorer.last_update, *xy[-1]))
    last = pings[-1]
    j = last.shape[0] - 1
    common = dict(key=key, xy=last, cov=np.zeros((5, 2, 2)) + np.eye(2) * 1e4, scores=None,
                  hotspots=None, track_xy=last[j:j + 1], hits=np.array([0]), dets=np.array([j]),
                  log_pdf=np.array([-12.0]), confirmed=np.array([False]))
    d_out = scorer.scan_delta(**common, own=[np.array(own)])[0]
    d_plain = plain.scan_delta(**common)[0]
    ref = ClutterIntensity()
    for xy in pings[:-1]:
        ref.update(xy[:-1])
    ref.update(last[:-1])
    lam_ref = ref.intensity(last[j:j + 1])[0]
    # score = ln P_D + log_pdf - ln lambda: recover lambda from each score
    lam_out = math.exp(math.log(0.5) - 12.0 - d_out)
    lam_plain = math.exp(math.log(0.5) - 12.0 - d_plain)
    assert lam_out == pytest.approx(lam_ref, rel=0.05, abs=2e-9)
    assert lam_plain > 5 * lam_out                  # the track's own path dominates
    # forgotten detections (older than memory_pings updates) are not subtracted
    est = scorer._intensity[key]
    assert est.kernel_intensity(last[j], np.array(own)[:, 1:], np.array(own)[:, 0] - 20) == 0.0
