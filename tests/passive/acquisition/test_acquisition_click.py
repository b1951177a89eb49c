"""Acquisition with an imperfect click and unknown noise statistics; varied cubes."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import stats

from fusion.io import read_json
from fusion.passive.acquisition import Acquisition
from fusion.passive.acquisition.normalise import estimate_noise_dof, expected_median_fraction
from fusion.simulate.cube import simulate_cube, write_scenario
from fusion.simulate.cube_varied import simulate_varied_cube


def _one_bin_off(sc, step):
    """The exact click's frequency moved by `step` bins."""
    k = int(np.argmin(np.abs(sc.cube.freqs - sc.click_freq))) + step
    return float(sc.cube.freqs[k])


@pytest.mark.parametrize("looks", [1, 2, 4])
def test_noise_dof_estimate_known_answers(looks):
    """Averaged looks of exponential noise: about 2 x looks degrees of freedom (within 10 %),
    whatever the level of each beam and bin."""
    rng = np.random.default_rng(looks)
    level = 10.0 ** rng.uniform(-2, 2, (1, 32, 16))
    x = rng.gamma(looks, 1.0 / looks, size=(60, 32, 16)) * level
    assert estimate_noise_dof(x) == pytest.approx(2.0 * looks, rel=0.1)


def test_noise_dof_estimate_matches_the_median_fraction():
    """The estimate's gamma has the observed median-to-mean ratio: the normaliser's factor for
    a large sample equals that ratio."""
    rng = np.random.default_rng(7)
    x = rng.gamma(1.0, 1.0, (60, 64, 16)) * rng.gamma(5.0, 0.2, (60, 64, 16))  # heavy tails
    dof = estimate_noise_dof(x)
    ratio = float(np.median(x / x.mean(axis=0)))
    assert stats.gamma.ppf(0.5, dof / 2, scale=2 / dof) == pytest.approx(ratio, abs=1e-3)
    assert expected_median_fraction(1001, dof) == pytest.approx(ratio, abs=0.02)
    assert dof < 2.0                       # heavier tailed than one look


def test_noise_dof_estimate_bad_input():
    """Wrong shape, no bin left, too few scans raise ValueError."""
    with pytest.raises(ValueError, match="shape"):
        estimate_noise_dof(np.ones((10, 4)))
    with pytest.raises(ValueError, match="outside exclude_bins"):
        estimate_noise_dof(np.ones((10, 4, 2)), exclude_bins=[0, 1])


@pytest.mark.parametrize("step", [-1, 1])
def test_click_one_bin_off_finds_the_line(step):
    """A click one bin off the line: with the default tolerance the line's band is found
    (same band and rate as the exact click); without it the method sees noise only."""
    sc = simulate_cube(seed=21, bearing0_deg=70.0, bearing_rate_deg_per_min=30.0, snr_db=12.0,
                       line_offset_bins=0.0)
    exact = Acquisition().acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    off = Acquisition().acquire(sc.cube, beam=sc.click_beam, freq_hz=_one_bin_off(sc, step))
    assert not exact.default_used and not off.default_used
    assert off.ibw_bins == exact.ibw_bins
    assert off.bearing_rate_deg_per_min == pytest.approx(exact.bearing_rate_deg_per_min)
    assert abs(off.bearing_rate_deg_per_min - 30.0) < 3.0
    strict = Acquisition(freq_tolerance_bins=0).acquire(sc.cube, beam=sc.click_beam,
                                                        freq_hz=_one_bin_off(sc, step))
    assert strict.default_used


def test_click_one_beam_and_one_bin_off():
    """One beam and one bin off at 6 dB per bin: within half a beamwidth and 25 % in rate."""
    sc = simulate_cube(seed=5, bearing0_deg=100.0, bearing_rate_deg_per_min=-25.0, snr_db=6.0)
    res = Acquisition().acquire(sc.cube, beam=sc.click_beam + 1, freq_hz=_one_bin_off(sc, 1))
    assert not res.default_used
    assert abs(res.bearing_rate_deg_per_min + 25.0) <= 0.25 * 25.0
    assert abs(res.bearing_deg - sc.latest_bearing_deg) < 2.0


def test_tolerance_zero_is_the_method_on_exact_clicks():
    """On the exact click the tolerance can only add bands: with the line in the clicked bin the
    result equals the method's (tolerance 0), given the same noise statistics."""
    sc = simulate_cube(seed=3, bearing0_deg=60.0, bearing_rate_deg_per_min=30.0, snr_db=9.0,
                       line_offset_bins=0.0, freq_spread_hz=0.0)
    a = Acquisition(noise_dof=2.0).acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    b = Acquisition(noise_dof=2.0, freq_tolerance_bins=0).acquire(
        sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    assert a.ibw_bins == b.ibw_bins
    assert a.to_json() == b.to_json()


@pytest.mark.parametrize("kwargs, match", [({"freq_tolerance_bins": -1}, "freq_tolerance"),
                                           ({"freq_tolerance_bins": 1.5}, "freq_tolerance"),
                                           ({"noise_dof": 0.0}, "noise_dof")])
def test_bad_click_options(kwargs, match):
    """Negative or fractional tolerances and non-positive dof raise ValueError."""
    with pytest.raises(ValueError, match=match):
        Acquisition(**kwargs)


def test_varied_cube_draws_and_local_snr():
    """Varied cubes: draws within their ranges; the line's cells exceed the local noise by the
    per-bin SNR (noise-level shape divided out, averaged over seeds)."""
    ratios = []
    for seed in range(6):
        sc = simulate_varied_cube(seed, snr_db=10.0)
        p = sc.parameters
        assert 150 <= p["line_freq_hz"] <= 800 and 1 <= p["n_averages"] <= 4
        assert abs(p["bearing_rate_deg_per_min"]) <= 40 and -3 <= p["level_slope_db"] <= 3
        assert np.all((sc.bearing_deg >= 9.99) & (sc.bearing_deg <= 170.01))
        power = sc.cube.power
        k = int(np.argmin(np.abs(sc.cube.freqs - p["line_freq_hz"])))
        beams = np.round(sc.beam_track).astype(int)
        on = power[np.arange(power.shape[0]), beams, k]
        # local noise: the same beams two bins away on either side (slope across the band)
        far = 0.5 * (power[np.arange(power.shape[0]), beams, k - 3]
                     + power[np.arange(power.shape[0]), beams, k + 3])
        ratios.append(np.mean(on) / np.mean(far))
    # 10 dB on the peak of the lobe and the line's share of its bin: well above 1 + 3
    assert np.mean(ratios) > 4.0
    a = simulate_varied_cube(3, snr_db=3.0).cube.power
    assert np.array_equal(a, simulate_varied_cube(3, snr_db=3.0).cube.power)


def test_varied_cube_scenario_file(tmp_path):
    """write_scenario(vary=True) writes the exact click and the draws."""
    write_scenario(tmp_path, seed=4, vary=True)
    truth = read_json(tmp_path / "truth.json")
    assert truth["vary"] is True and "n_averages" in truth["parameters"]
    sc = simulate_varied_cube(4)
    assert truth["click_beam"] == sc.click_beam
    assert_allclose(truth["click_freq"], sc.click_freq)
