"""Issue 20: births in a coasting confirmed track's gate and successors confirmed sooner
(:mod:`fusion.active.births`)."""

from __future__ import annotations

import copy

import numpy as np

from fusion.active.births import birth_blockers, successor_flags
from fusion.active.kalman import cv_model, kf_predict
from fusion.active.tracker import Ping, Tracker

DT = 60.0


def _ping(k: int, xy, score: float = 0.1) -> Ping:
    xy = np.atleast_2d(np.asarray(xy, float))
    return Ping(k, DT * k, xy, {"score": np.full(len(xy), score)})


def _tracker(**kw) -> Tracker:
    return Tracker(position_errors="isotropic", position_sigma_m=50.0, noise="fixed",
                   detection_probability=0.8, clutter_intensity=1e-9, hold_stationary=False,
                   reject_platform_fixed=False, shadow=False, speed_sigma_mps=3.0,
                   confirmed_edge_likelihood=0.25, **kw)


def _confirmed(tr: Tracker) -> Tracker:
    """Five pings of a target at 3 m/s east: one confirmed track."""
    for k in range(5):
        tr.step(Ping(k, DT * k, [[180.0 * k, 0.0]], {"score": [0.9]}))
    assert [lc.status for lc in tr._life] == ["confirmed"]
    return tr


def _edge_detection(tr: Tracker, k: int) -> np.ndarray:
    """A detection inside the confirmed track's 99 % gate (d2 = 7.5) but beyond its edge
    likelihood (0.25 here: d2 = 2.8): it ranks below the threshold and the track does not take
    it."""
    F, Q = cv_model(DT, tr.accel_psd)
    x, P = kf_predict(tr._x, tr._P, F, Q)
    S = P[0, :2, :2] + np.eye(2) * 50.0**2
    return x[0, :2] + np.linalg.cholesky(S) @ np.array([0.0, np.sqrt(7.5)])


def test_birth_blockers_and_successor_flags():
    hit = np.array([True, False, False, False])
    conf = np.array([True, True, False, True])
    assert birth_blockers(hit, conf, coast_gate_births=False).all()
    assert birth_blockers(hit, conf, coast_gate_births=True).tolist() == [True, False, True, False]
    gated = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0]], bool)
    assert successor_flags(gated, hit, conf, np.array([0, 1, 2])).tolist() == [False, True, False]


def test_a_detection_in_a_coasting_gate_starts_a_track_only_with_the_option():
    base = _confirmed(_tracker())
    z = _edge_detection(base, 5)
    for births, want in ((False, 1), (True, 2)):
        tr = copy.deepcopy(base)
        tr.coast_gate_births = births
        res = tr.step(_ping(5, z))
        assert res.track_id.size == want
        assert res.status[0] == "confirmed" and res.detection[0] == -1   # the track coasts


def test_a_successor_starts_with_its_score_and_needs_one_hit_fewer():
    base = _confirmed(_tracker(coast_gate_births=True))
    z = _edge_detection(base, 5)
    plain, succ = copy.deepcopy(base), copy.deepcopy(base)
    succ.successor_llr = 3.0
    for tr in (plain, succ):
        tr.step(_ping(5, z))
    assert plain._llr[1] == 0.0 and not plain._succ[1]
    assert succ._llr[1] == 3.0 and succ._succ[1]
    # Its second hit (3 m/s north from the birth, away from the old track) confirms the
    # successor, not the plain birth.
    z2 = z + np.array([0.0, 180.0])
    r_plain = plain.step(_ping(6, [z2, [-9000.0, 9000.0]], 0.9))
    r_succ = succ.step(_ping(6, [z2, [-9000.0, 9000.0]], 0.9))
    assert r_plain.status[1] == "tentative"
    assert r_succ.status[1] == "confirmed"
