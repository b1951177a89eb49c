"""Tests of the varied multistatic scenarios and of the identity-switch count."""

from __future__ import annotations

import numpy as np
import pytest

from fusion.io import read_json
from fusion.metrics.multistatic import identity_switches, score_tracks
from fusion.simulate.multistatic import simulate_multistatic, write_scenario


def _excess(xy, src, rcv):
    return (np.hypot(*(xy - src).T) + np.hypot(*(xy - rcv).T) - np.hypot(*(rcv - src)))


def test_draws_lie_in_their_ranges_and_repeat():
    """Receivers, probabilities, errors, clutter rates and SNRs lie in the documented ranges;
    the same seed gives the same table."""
    for seed in range(6):
        sc = simulate_multistatic(seed=seed, vary=True)
        p = sc.parameters
        assert 2 <= p["n_receivers"] == len(sc.receivers) <= 5
        assert all(0.4 <= x <= 0.9 for x in p["target_pd"])
        assert all(50 <= x <= 200 for x in p["sigma_normal_m"])
        assert np.all((np.array(p["hotspot_pd"]) >= 0.6) & (np.array(p["hotspot_pd"]) <= 0.95))
        assert np.all((np.array(p["hotspot_snr_db"]) >= 15) & (np.array(p["hotspot_snr_db"]) <= 28))
        assert all(2 <= x <= 15 for x in p["clutter_per_receiver"])
        speed = np.hypot(sc.truth["vx"], sc.truth["vy"])
        assert np.all((speed > 2.9 * 0.5144) & (speed < 8.1 * 0.5144))
    a, b = simulate_multistatic(seed=3, vary=True), simulate_multistatic(seed=3, vary=True)
    for k in a.detections.columns:
        np.testing.assert_array_equal(a.detections[k], b.detections[k])


def test_direct_blast_hides_every_echo_near_the_baseline():
    """No echo of any origin reaches a receiver with a range-sum excess below the blanking
    distance (judged at the true position: the target's and hotspots' ones, clutter as drawn)."""
    for seed in range(4):
        sc = simulate_multistatic(seed=seed, vary=True)
        d = sc.detections
        m = d["origin"] == "clutter"
        for j, rcv in enumerate(sc.receivers):
            mm = m & (d["receiver"] == j)
            xy = np.column_stack([d["x"][mm], d["y"][mm]])
            assert np.all(_excess(xy, sc.source, rcv) >= 1000.0)


def test_target_errors_follow_the_drawn_ellipse_frame():
    """Target echo errors along the bistatic-ellipse normal have the receiver's drawn standard
    deviation (pooled over seeds: ratio within 20 %), across it about 1 deg x range."""
    ratios_n, ratios_t = [], []
    for seed in range(30):
        sc = simulate_multistatic(seed=seed, vary=True)
        d = sc.detections
        tgt = d["origin"] == "target"
        for j, rcv in enumerate(sc.receivers):
            m = tgt & (d["receiver"] == j)
            if m.sum() < 3:
                continue
            k = d["event"][m]
            p = np.column_stack([sc.truth["x"][k], sc.truth["y"][k]])
            e = np.column_stack([d["x"][m], d["y"][m]]) - p
            es = (p - sc.source) / np.linalg.norm(p - sc.source, axis=1, keepdims=True)
            er = (p - rcv) / np.linalg.norm(p - rcv, axis=1, keepdims=True)
            n = (es + er) / np.linalg.norm(es + er, axis=1, keepdims=True)
            t = np.column_stack([-n[:, 1], n[:, 0]])
            rng_r = np.linalg.norm(p - rcv, axis=1)
            ratios_n.append(np.sum(e * n, axis=1) / sc.parameters["sigma_normal_m"][j])
            ratios_t.append(np.sum(e * t, axis=1) / (rng_r * np.radians(1.0)))
    assert np.std(np.concatenate(ratios_n)) == pytest.approx(1.0, rel=0.2)
    assert np.std(np.concatenate(ratios_t)) == pytest.approx(1.0, rel=0.2)


def test_write_scenario_vary_records_the_draws(tmp_path):
    """write_scenario(vary=True) writes the detections in the formats and the draws as truth."""
    write_scenario(tmp_path, seed=2, vary=True)
    truth = read_json(tmp_path / "truth.json")
    assert truth["vary"] is True and truth["parameters"]["n_receivers"] == len(truth["receivers"])


def test_identity_switches_known_answers():
    """One track throughout: 0; handed over to a second track and back: 2; gaps do not reset."""
    one = [np.array([7])] * 4
    assert identity_switches(one, [np.array([1.0])] * 4) == 0
    ids = [np.array([1]), np.array([2]), np.array([]), np.array([1])]
    assert identity_switches(ids, [np.array([5.0]), np.array([5.0]), np.array([]),
                                   np.array([5.0])]) == 2


def test_score_tracks_counts_switches():
    """Two tracks on the truth, one after the other: coverage 1, no false track, one switch."""
    sc = simulate_multistatic(seed=0, n_pings=8)
    ev = np.arange(8)
    cols = {"track_id": np.where(ev < 4, 0, 1), "event": ev, "x": sc.truth["x"],
            "y": sc.truth["y"], "status": np.array(["confirmed"] * 8)}
    s = score_tracks(cols, sc.truth)
    assert (s.coverage, s.false_tracks, s.identity_switches) == (1.0, 0, 1)
