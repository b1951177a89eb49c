"""Tests of the multistatic scenario simulator (fusion.simulate.multistatic)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.io import read_detections, read_json, read_table
from fusion.metrics.multistatic import score_tracks
from fusion.simulate.multistatic import (
    bistatic_position,
    simulate_multistatic,
    write_scenario,
)


def test_bistatic_position_inverts_range_sum_and_bearing():
    """The solved position reproduces the range sum and the receiver bearing."""
    rng = np.random.default_rng(0)
    s = rng.uniform(-5000, 5000, (50, 2))
    r = rng.uniform(-5000, 5000, (50, 2))
    p = rng.uniform(-9000, 9000, (50, 2))
    rho = np.linalg.norm(p - s, axis=1) + np.linalg.norm(p - r, axis=1)
    th = np.arctan2(p[:, 0] - r[:, 0], p[:, 1] - r[:, 1])
    assert_allclose(bistatic_position(s, r, rho, th), p, atol=1e-6)


def test_same_seed_same_scenario_and_origins():
    """Seeded: identical tables; origins, clue ranges and ping count as specified."""
    a = simulate_multistatic(seed=11)
    b = simulate_multistatic(seed=11)
    for k in a.detections.columns:
        np.testing.assert_array_equal(a.detections[k], b.detections[k])
    d = a.detections
    assert set(np.unique(d["origin"])) <= {"target", "hotspot", "clutter"}
    assert len(a.truth) == 22 and 2 <= len(a.receivers) <= 4
    assert 60 <= a.ping_interval_s <= 120
    assert np.all((d["score"] >= 0) & (d["score"] <= 1))
    assert np.all((d["aspect_deg"] >= 0) & (d["aspect_deg"] <= 180))
    speed = np.hypot(a.truth["vx"], a.truth["vy"])
    assert np.all((speed > 2.9 * 0.5144) & (speed < 8.1 * 0.5144))


def test_clue_statistics_over_seeds():
    """Target scores beat clutter on average (overlapping); hotspot SNR above clutter SNR."""
    tables = [simulate_multistatic(seed=s).detections for s in range(5)]
    o = np.concatenate([t["origin"] for t in tables])
    score = np.concatenate([t["score"] for t in tables])
    snr = np.concatenate([t["snr_db"] for t in tables])
    assert score[o == "target"].mean() > score[o == "clutter"].mean() + 0.2
    assert score[o == "target"].min() < score[o == "clutter"].max()
    assert snr[o == "hotspot"].mean() > snr[o == "clutter"].mean() + 5
    # Target echoes near specular are stronger than off specular.
    a = np.concatenate([t["aspect_deg"] for t in tables])
    tgt = o == "target"
    assert snr[tgt & (np.abs(a - 90) < 15)].mean() > snr[tgt & (np.abs(a - 90) > 45)].mean()


def test_write_scenario_files(tmp_path):
    """Files in the formats: detections readable by read_detections, truth per ping."""
    paths = write_scenario(tmp_path, seed=2)
    assert {p.name for p in paths} == {"detections.csv", "truth.csv", "origins.csv", "truth.json"}
    d = read_detections(tmp_path / "detections.csv")
    for c in ("snr_db", "score", "aspect_deg", "src_x", "rcv_y"):
        assert c in d
    truth = read_table(tmp_path / "truth.csv", required=("event", "time", "x", "y", "vx", "vy"))
    assert len(truth) == 22
    assert read_json(tmp_path / "truth.json")["kind"] == "multistatic"


def test_score_tracks_known_answer():
    """A track on the truth covers every ping; one far away is a false track."""
    sc = simulate_multistatic(seed=0, n_pings=6)
    ev = np.arange(6)
    cols = {
        "track_id": np.r_[np.zeros(6, int), np.ones(6, int)], "event": np.r_[ev, ev],
        "x": np.r_[sc.truth["x"], sc.truth["x"] + 5000], "y": np.r_[sc.truth["y"], sc.truth["y"]],
        "status": np.array(["confirmed"] * 12),
    }
    s = score_tracks(cols, sc.truth)
    assert s.coverage == 1.0 and s.false_tracks == 1 and s.confirmed_tracks == 2


def test_bad_arguments():
    """Too few pings or receivers raise ValueError."""
    with pytest.raises(ValueError, match="n_pings"):
        simulate_multistatic(seed=0, n_pings=1)
    with pytest.raises(ValueError, match="n_receivers"):
        simulate_multistatic(seed=0, n_receivers=0)
