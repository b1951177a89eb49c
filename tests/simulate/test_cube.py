"""Tests of the simulated beam/frequency/time cube."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.io import read_cube, read_json
from fusion.simulate.cube import simulate_cube, write_scenario


def test_beam_track_follows_cosine_spacing():
    """The shown bearings map to beams by b = (N - 1)(1 - cos theta) / 2 at a constant rate."""
    sc = simulate_cube(seed=1, n_beams=48, bearing0_deg=40.0, bearing_rate_deg_per_min=30.0)
    t = np.arange(60) * 1.0
    theta = np.radians(40.0 + 30.0 * t / 60.0)
    assert_allclose(sc.bearing_deg, np.degrees(theta), atol=1e-9)
    assert_allclose(sc.beam_track, 47 * (1.0 - np.cos(theta)) / 2.0, atol=1e-9)


def test_line_peaks_on_the_beam_track():
    """At high SNR the line's bin peaks, scan by scan, on the beam nearest the cosine-spaced track."""
    sc = simulate_cube(seed=2, bearing0_deg=50.0, bearing_rate_deg_per_min=-25.0, snr_db=60.0,
                       line_offset_bins=0.0, freq_spread_hz=0.0)
    line_bin = int(np.argmin(np.abs(sc.cube.freqs - sc.line_freq_hz)))
    peak = np.argmax(sc.cube.power[:, :, line_bin], axis=1)
    assert np.all(np.abs(peak - sc.beam_track) <= 0.5 + 1e-9)
    assert sc.click_beam == int(np.floor(sc.beam_track[-1] + 0.5))
    assert sc.click_freq == pytest.approx(sc.cube.freqs[line_bin])


def test_noise_only_cells_have_unit_mean():
    """Without a line every cell is exponential of mean 1 (variance 1); averaged looks: variance 1/m."""
    sc = simulate_cube(seed=3, snr_db=-200.0)
    p = sc.cube.power
    assert p.mean() == pytest.approx(1.0, abs=4.0 / np.sqrt(p.size))
    assert p.var() == pytest.approx(1.0, abs=0.05)
    sc4 = simulate_cube(seed=3, snr_db=-200.0, n_averages=4)
    assert sc4.cube.power.mean() == pytest.approx(1.0, abs=4.0 * 0.5 / np.sqrt(p.size))
    assert sc4.cube.power.var() == pytest.approx(0.25, abs=0.02)


def test_signal_cell_mean_is_one_plus_snr():
    """On the steered beam with the line in one bin, the cell mean is 1 + S (per-bin SNR S)."""
    sc = simulate_cube(seed=4, n_scans=400, bearing0_deg=90.0, bearing_rate_deg_per_min=0.0,
                       snr_db=3.0, line_offset_bins=0.0, freq_spread_hz=0.0, n_beams=65)
    cell = sc.cube.power[:, 32, 8]  # beam 32 of 65 looks at broadside; the line in bin 8
    assert cell.mean() == pytest.approx(1.0 + 10 ** 0.3, rel=0.12)


def test_lag_delays_the_shown_bearing():
    """With a lag the spectra show the bearing lag seconds earlier."""
    sc = simulate_cube(seed=5, bearing0_deg=60.0, bearing_rate_deg_per_min=30.0, lag_s=4.0)
    assert_allclose(sc.shown_bearing_deg, sc.bearing_deg - 2.0, atol=1e-9)  # 30 deg/min * 4 s


def test_same_seed_same_cube():
    """Seeded: the same arguments give the same cube, another seed another."""
    a = simulate_cube(seed=7).cube.power
    assert np.array_equal(a, simulate_cube(seed=7).cube.power)
    assert not np.array_equal(a, simulate_cube(seed=8).cube.power)


def test_write_scenario_round_trip(tmp_path):
    """write_scenario writes a readable cube and a truth file consistent with it."""
    paths = write_scenario(tmp_path, seed=11)
    assert sorted(p.name for p in paths) == ["cube.npz", "truth.json"]
    cube = read_cube(tmp_path / "cube.npz")
    truth = read_json(tmp_path / "truth.json")
    assert cube.power.shape == (60, 64, 16)
    assert abs(truth["bearing_rate_deg_per_min"]) == 35.0
    assert 0 <= truth["click_beam"] < 64
    assert truth["click_freq"] in cube.freqs
    assert len(truth["bearing_per_scan_deg"]) == 60


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_beams": 0}, "n_beams"),
        ({"scan_period_s": 0.0}, "scan_period_s"),
        ({"snr_db": float("nan")}, "snr_db"),
        ({"line_offset_bins": 0.7}, "line_offset_bins"),
        ({"lag_s": -1.0}, "lag_s"),
    ],
)
def test_bad_arguments_raise(kwargs, match):
    """Bad sizes or parameters raise ValueError naming the argument."""
    with pytest.raises(ValueError, match=match):
        simulate_cube(seed=0, **kwargs)
