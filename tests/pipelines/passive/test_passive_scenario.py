"""Tests of the multi-target passive cube simulator behind the pipeline's tests and benchmark."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.geometry import beam_from_bearing
from fusion.io import read_cube, read_json, read_table
from fusion.simulate.passive import (
    FADE_DEPTH_DB,
    LineTarget,
    random_targets,
    simulate_passive,
    write_scenario,
)

CROSS = (LineTarget(70.0, 8.0, 300.0, 20.0), LineTarget(110.0, -8.0, 300.0, 20.0))


def test_truth_and_crossing_time():
    """Bearings move at their rates; the one crossing is found once, at 150 s (90 deg)."""
    sc = simulate_passive(seed=0, targets=CROSS, n_scans=260, n_bins=16)
    assert_allclose(sc.bearing_deg[:, 0], 70.0 + 8.0 * sc.time / 60.0)
    assert len(sc.crossings) == 1
    a, b, tc = sc.crossings[0]
    assert (a, b) == (0, 1) and tc == pytest.approx(150.0)
    assert sc.clicks[1] == (int(np.floor(beam_from_bearing(np.radians(sc.bearing_deg[59, 1]), 64)
                                         + 0.5)), float(sc.cube.freqs[4]), 59.0)


def test_noise_free_cube_peaks_on_each_line():
    """Without noise each scan's line bin peaks at both lines' beams while they are apart."""
    sc = simulate_passive(seed=0, targets=CROSS, n_scans=100, n_bins=16, noise=False)
    row = sc.cube.power[10, :, 4]
    for i in range(2):
        b = beam_from_bearing(np.radians(sc.bearing_deg[10, i]), 64)
        peak = int(np.argmax(np.where(np.abs(np.arange(64) - b) < 3, row, 0.0)))
        assert abs(peak - b) <= 0.5 + 1e-9
    assert sc.cube.power.min() >= 1.0


def test_noise_alone_has_unit_mean():
    """A cube of absent lines is exponential noise of mean 1."""
    quiet = (LineTarget(90.0, 0.0, 300.0, 10.0, fade_start_s=-2.0, fade_end_s=-1.0),)
    p = simulate_passive(seed=1, targets=quiet, n_scans=60, n_bins=16).cube.power
    assert p.mean() == pytest.approx(1.0, abs=4.0 / np.sqrt(p.size))
    assert p.var() == pytest.approx(1.0, abs=0.05)


def test_fade_profile_and_gone_time():
    """A fade drops the SNR linearly by FADE_DEPTH_DB, then the line is absent."""
    tg = LineTarget(90.0, 0.0, 300.0, 9.0, fade_start_s=100.0, fade_end_s=130.0)
    t = np.array([50.0, 100.0, 115.0, 130.0, 131.0])
    assert_allclose(tg.snr_db_at(t)[:4], [9.0, 9.0, 9.0 - FADE_DEPTH_DB / 2, 9.0 - FADE_DEPTH_DB])
    assert tg.snr_db_at(t)[4] == -np.inf
    assert tg.gone_s == pytest.approx(100.0 + 30.0 * 9.0 / FADE_DEPTH_DB)
    with pytest.raises(ValueError, match="fade_start_s"):
        LineTarget(90.0, 0.0, 300.0, 9.0, fade_start_s=10.0)


def test_random_targets_layout():
    """Crossing pairs share a bin and cross inside the run; every line stays in 15-165 deg."""
    freqs = 296.0 + np.arange(32)
    tg = random_targets(np.random.default_rng(3), n_targets=8, n_crossing_pairs=3, n_fading=1,
                        duration_s=400.0, freqs=freqs)
    sc = simulate_passive(seed=3, targets=tg, n_scans=400)
    pairs = {(a, b) for a, b, _ in sc.crossings}
    assert {(0, 1), (2, 3), (4, 5)} <= pairs
    assert np.all((sc.bearing_deg >= 15.0) & (sc.bearing_deg <= 165.0))
    assert np.isfinite(sc.gone_s).sum() == 1
    with pytest.raises(ValueError, match="slots"):
        random_targets(np.random.default_rng(3), n_targets=30, n_crossing_pairs=0, n_fading=0,
                       duration_s=400.0, freqs=freqs)


def test_write_scenario_reads_back(tmp_path):
    """The written cube, clicks and truth read back and match one another."""
    paths = write_scenario(tmp_path, seed=2)
    assert {p.name for p in paths} == {"cube.npz", "clicks.csv", "truth.json"}
    cube = read_cube(tmp_path / "cube.npz")
    clicks = read_table(tmp_path / "clicks.csv", required=("time", "beam", "freq"),
                        integer=("beam",))
    truth = read_json(tmp_path / "truth.json")
    assert cube.power.shape == (400, 64, 32)
    assert len(clicks) == len(truth["targets"]) == 6
    assert len(truth["crossings"]) >= 2
    again = simulate_passive(seed=2)
    assert_allclose(cube.power, again.cube.power)
