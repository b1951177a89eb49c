"""Issue 20: the SNR's likelihood ratio in the track score (``snr_evidence``) and a new track's
starting score from its detection's features (``birth_evidence``)."""

from __future__ import annotations

import math

import numpy as np
from numpy.testing import assert_allclose

from fusion.active.track_score import TrackScorer
from fusion.active.tracker import Ping, Tracker

KEY = (0.0, 0.0, 5000.0, 0.0)


def _scan(sc: TrackScorer, snr, *, hits=(), dets=(), confirmed=(), track_xy=None):
    n = len(snr)
    t = len(confirmed)
    return sc.scan_delta(
        KEY, xy=np.column_stack([np.arange(n) * 10.0, np.zeros(n)]),
        cov=np.broadcast_to(np.eye(2) * 1e4, (n, 2, 2)), scores=None, hotspots=None,
        track_xy=np.zeros((t, 2)) if track_xy is None else track_xy,
        hits=np.asarray(hits, np.int64), dets=np.asarray(dets, np.int64),
        log_pdf=np.full(len(hits), -13.0), confirmed=np.asarray(confirmed, bool),
        snr_db=np.asarray(snr, float))


def test_snr_ratio_is_zero_until_confirmed_tracks_teach_then_known_answer():
    """Prior f_T = f_C: no evidence at first. After 30 detections at 11 dB (bin 5) and a
    confirmed track's 10 hits at 21 dB (bin 10), by hand: f_C(bin) = (1 + n_bin) / (20 + N),
    f_T = (20 f_C + t_bin) / (20 + T)."""
    sc = TrackScorer(detection_probability=0.7, clutter_intensity=1e-7, snr_evidence=True)
    assert_allclose(sc.snr_delta([11.0, 21.0, 35.0]), 0.0, atol=1e-12)
    _scan(sc, [11.0] * 30)
    for _ in range(10):     # one confirmed track takes a 21-dB detection on each scan
        _scan(sc, [21.0], hits=[0], dets=[0], confirmed=[True])
    n_all = np.zeros(20)
    n_all[5], n_all[10] = 30, 10
    f_c = (1 + n_all) / (20 + 40)
    t = np.zeros(20)
    t[10] = 10
    f_t = (20 * f_c + t) / 30
    assert_allclose(sc.snr_delta([11.0, 21.0]), [math.log(f_t[5] / f_c[5]), math.log(f_t[10] / f_c[10])])
    assert sc.snr_delta([21.0])[0] > 0.5 > -0.3 > sc.snr_delta([11.0])[0]


def test_scan_delta_adds_the_snr_ratio_only_with_the_option():
    """With snr_evidence a hit's delta is the kinematic one plus snr_delta (misses unchanged);
    without, the kinematic one."""
    for on in (True, False):
        sc = TrackScorer(detection_probability=0.7, clutter_intensity=1e-7, snr_evidence=on)
        _scan(sc, [11.0] * 30)
        for _ in range(10):
            _scan(sc, [21.0], hits=[0], dets=[0], confirmed=[True])
        expect_lr = sc.snr_delta([21.0])[0] if on else 0.0
        d = _scan(sc, [21.0, 11.0], hits=[0], dets=[0], confirmed=[False, False])
        kin = math.log(0.7) - 13.0 - math.log(1e-7)
        assert_allclose(d, [kin + expect_lr, math.log(0.3)])
        assert (abs(expect_lr) > 0.5) == on


def _tracker(**kw) -> Tracker:
    return Tracker(position_errors="isotropic", position_sigma_m=50.0, noise="fixed",
                   detection_probability=0.8, clutter_intensity=1e-9, hold_stationary=False,
                   reject_platform_fixed=False, shadow=False, **kw)


def test_birth_evidence_starts_a_track_at_its_detections_feature_ratio():
    """A high classifier score starts a track above 0 and a low one below: the scorer's
    score_delta (plus snr_delta with snr_evidence) of the detection, with the histograms as
    they stand after the ping's scan (births come after it); without the option at 0."""
    ping = Ping(0, 0.0, [[0.0, 0.0], [9000.0, 0.0]],
                {"score": np.array([0.95, 0.05]), "snr_db": np.array([20.0, 11.0])})
    for kw in ({"birth_evidence": True}, {"birth_evidence": True, "snr_evidence": True}, {}):
        tr = _tracker(**kw)
        tr.step(ping)
        assert tr._llr.shape == (2,)
        if not kw:
            assert_allclose(tr._llr, 0.0)
            continue
        assert_allclose(tr._llr, tr.scorer.birth_delta(2, ping.clues["score"], ping.clues["snr_db"]))
        assert_allclose(tr._llr, tr.scorer.score_delta(ping.clues["score"]))  # SNR: no teacher yet
        assert tr._llr[0] > 0.1 and tr._llr[1] < -2.0


def test_birth_evidence_without_clues_starts_at_zero():
    """Detections with neither a score nor an SNR (e.g. radar positions only): births at 0."""
    tr = _tracker(birth_evidence=True, snr_evidence=True)
    tr.step(Ping(0, 0.0, [[0.0, 0.0], [9000.0, 0.0]], {}))
    assert_allclose(tr._llr, [0.0, 0.0])
