"""Tests of the tracker amplitude/residual simulator."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from fusion.io import read_amplitudes, read_table
from fusion.passive.quality import TrackQualityIndicator
from fusion.passive.tracker import cell_power_statistics
from fusion.simulate import get_writer
from fusion.simulate.amplitudes import (
    CONDITIONS,
    VARIED_RANGES,
    condition_snr_db,
    draw_amplitudes,
    draw_residuals,
    simulate_amplitudes,
    varied_settings,
)


@pytest.mark.parametrize(("snr_db", "looks"), [(-np.inf, 1), (0.0, 1), (10.0, 1), (6.0, 3)])
def test_amplitude_moments(snr_db, looks):
    """Cell powers have mean 1 + snr and variance (1 + 2 snr) / L."""
    a = draw_amplitudes(np.full(200_000, snr_db), rng=np.random.default_rng(1), n_looks=looks)
    mean, std = cell_power_statistics(snr_db, n_looks=looks)
    assert_allclose(a.mean(), mean, rtol=0.01)
    assert_allclose(a.std(), std, rtol=0.02)


def test_noise_alone_is_exponential():
    """With one look and no signal the cell power is exponential of mean 1."""
    a = draw_amplitudes(np.full(100_000, -np.inf), rng=np.random.default_rng(2))
    for q in (0.1, 0.5, 0.9):
        assert_allclose(np.quantile(a, q), -np.log(1 - q), rtol=0.03)


def test_residual_spread_shrinks_with_snr():
    """Residual std is sqrt(floor^2 + spread^2 / (1 + snr)) plus the bias."""
    rng = np.random.default_rng(3)
    for snr_db in (-np.inf, 6.0, 15.0):
        r = draw_residuals(np.full(100_000, snr_db), rng=rng, bias_deg=1.0)
        s = 10 ** (snr_db / 10)
        assert_allclose(r.std(), np.sqrt(0.55**2 + 3.35**2 / (1 + s)), rtol=0.02)
        assert_allclose(r.mean(), 1.0, atol=0.03)


def test_near_threshold_snrs_zero_the_llrs():
    """near_strong and near_lost SNRs give zero-mean LLR_1 and LLR_0 respectively."""
    tqi = TrackQualityIndicator()
    c, o = tqi.design_mean, tqi.design_std
    p = c / o
    s1 = 10 ** (condition_snr_db("near_strong") / 10)
    s0 = 10 ** (condition_snr_db("near_lost") / 10)
    assert_allclose(p[1] * (s1 / o[1] - 0.85 * p[1]), 0.0, atol=1e-12)
    assert_allclose(p[0] * (s0 / o[0] - 0.5 * p[0]), 0.0, atol=1e-12)
    with pytest.raises(ValueError, match="unknown condition"):
        condition_snr_db("weak")


def test_scenario_structure_and_seed():
    """Every track starts strong, segments differ from their neighbours, same seed same data."""
    a = simulate_amplitudes(seed=4, n_tracks=5)
    b = simulate_amplitudes(seed=4, n_tracks=5)
    assert_array_equal(a.amplitude, b.amplitude)
    assert a.n_tracks == 5
    assert set(a.condition) <= set(CONDITIONS)
    for tid in range(5):
        rows = a.track_id == tid
        cond, seg = a.condition[rows], a.segment[rows]
        assert cond[0] == "strong"
        firsts = cond[np.r_[True, np.diff(seg) != 0]]
        assert np.all(firsts[1:] != firsts[:-1])
        assert np.all(np.diff(a.time[rows]) > 0)
    lost = a.condition == "lost"
    if lost.any():
        assert np.all(np.isneginf(a.snr_db[lost]))
    c = simulate_amplitudes(seed=5, n_tracks=5)
    assert not np.array_equal(a.amplitude[:10], c.amplitude[:10])


def test_write_scenario_is_readable(tmp_path):
    """fusion simulate amplitudes writes a valid amplitudes file and a matching truth file."""
    paths = get_writer("amplitudes")(tmp_path, seed=0)
    assert {p.name for p in paths} == {"amplitudes.csv", "truth.csv"}
    amp = read_amplitudes(tmp_path / "amplitudes.csv")
    truth = read_table(tmp_path / "truth.csv", required=("track_id", "time", "condition",
                                                         "snr_linear"), text=("condition",))
    assert len(amp) == len(truth)
    assert_allclose(amp["time"], truth["time"])
    assert np.all(truth["snr_linear"][truth["condition"] == "lost"] == 0)


def test_bad_options():
    """Bad sizes raise ValueError."""
    with pytest.raises(ValueError, match="n_tracks"):
        simulate_amplitudes(seed=0, n_tracks=0)
    with pytest.raises(ValueError, match="segment_updates"):
        simulate_amplitudes(seed=0, segment_updates=(5, 2))
    with pytest.raises(ValueError, match="n_looks"):
        draw_amplitudes([1.0], rng=np.random.default_rng(0), n_looks=0)


@pytest.mark.parametrize("seed", range(3))
def test_varied_scenario_follows_documented_ranges(seed):
    """A varied scenario's period, segment lengths, strong SNRs and biases lie in VARIED_RANGES."""
    st = varied_settings(seed)
    r = VARIED_RANGES
    assert r["update_period_s"][0] <= st["update_period_s"] <= r["update_period_s"][1]
    sc = simulate_amplitudes(**st)
    for tid in np.unique(sc.track_id):
        rows = sc.track_id == tid
        assert_allclose(np.diff(sc.time[rows]), st["update_period_s"], rtol=1e-9)
        lengths = np.bincount(sc.segment[rows]) * st["update_period_s"]
        assert np.all(lengths >= r["segment_s"][0] - st["update_period_s"])
        assert np.all(lengths <= r["segment_s"][1] + st["update_period_s"])
    strong = np.isin(sc.condition, ("strong", "manoeuvre"))
    assert np.all((sc.snr_db[strong] >= 12.0) & (sc.snr_db[strong] <= 25.0))
    assert np.unique(sc.snr_db[strong]).size > 1  # drawn per segment


def test_write_varied_scenario(tmp_path):
    """`fusion simulate amplitudes --vary` writes updates at the drawn period."""
    get_writer("amplitudes")(tmp_path, seed=1, vary=True)
    amp = read_amplitudes(tmp_path / "amplitudes.csv")
    step = np.diff(amp["time"][amp["track_id"] == 0])
    assert_allclose(step, varied_settings(1)["update_period_s"], rtol=1e-5)
