"""Tests of high bearing-rate acquisition (best line through the IBW BTR)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.geometry import (
    beam_from_bearing,
    beam_rate_from_bearing_rate,
    bearing_from_beam,
    bearing_rate_from_beam_rate,
)
from fusion.io import Cube, write_cube
from fusion.passive.acquisition import (
    HAMMING_ENBW,
    Acquisition,
    ConstantRateFans,
    StraightLineFans,
    acquire,
    band_noise_level,
    beamwidth_deg,
    best_lines_in_fans,
    best_traces_in_fans,
    constant_rate_traces,
    expected_median_fraction,
    ibw_bins,
    matched_trace_score,
    normalize_spectra,
    refine_trace,
    slope_grid,
)
from fusion.simulate.cube import simulate_cube


def half_beamwidth_deg(theta_deg: float, wavelength: float, aperture: float) -> float:
    """Half the bearing width of the cosine interval cos(theta) +- 0.443 lambda / L."""
    w = 0.886 * wavelength / aperture
    u = math.cos(math.radians(theta_deg))
    return 0.5 * math.degrees(math.acos(max(-1, u - w / 2)) - math.acos(min(1, u + w / 2)))


# ------------------------------------------------------------------------------------------
# conversions (program segment 54, eqs. 5-11)
# ------------------------------------------------------------------------------------------
class TestConversions:
    def test_edge_beams(self):
        """Beam 0 is forward endfire (0), beam N-1 aft endfire (pi), the middle beam broadside."""
        assert bearing_from_beam(0, 64) == 0.0
        assert bearing_from_beam(63, 64) == pytest.approx(math.pi)
        assert bearing_from_beam(32, 65) == pytest.approx(math.pi / 2)
        assert beam_from_bearing(0.0, 64) == 0.0
        assert beam_from_bearing(math.pi, 64) == pytest.approx(63.0)

    def test_round_trip(self):
        """bearing -> beam -> bearing is the identity over [0, pi]."""
        theta = np.linspace(0.0, math.pi, 181)
        assert_allclose(bearing_from_beam(beam_from_bearing(theta, 64), 64), theta, atol=1e-7)

    def test_rates_match_numerical_derivative(self):
        """Beam rate <-> bearing rate agree with d(beam)/d(theta) by central differences."""
        rng = np.random.default_rng(0)
        for theta in rng.uniform(0.2, math.pi - 0.2, 20):
            h = 1e-6
            db_dtheta = (beam_from_bearing(theta + h, 64) - beam_from_bearing(theta - h, 64)) / (2 * h)
            rate = 0.01  # rad/s
            assert beam_rate_from_bearing_rate(theta, rate, 64) == pytest.approx(db_dtheta * rate)
            b = beam_from_bearing(theta, 64)
            assert bearing_rate_from_beam_rate(b, db_dtheta * rate, 64) == pytest.approx(rate)

    def test_edge_beam_rates_finite(self):
        """At the endfire beams the bearing rate stays finite (floored sine)."""
        for b in (0, 63):
            r = bearing_rate_from_beam_rate(b, 0.1, 64)
            assert np.isfinite(r) and r > 0


# ------------------------------------------------------------------------------------------
# normalisation (program segment 22)
# ------------------------------------------------------------------------------------------
class TestNormalize:
    @pytest.mark.parametrize("n", [3, 4, 9, 14, 15, 60])
    def test_expected_median_exponential_closed_form(self, n):
        """For exponential noise E[median] equals the harmonic-number order statistics formula."""
        h = np.concatenate([[0.0], np.cumsum(1.0 / np.arange(1, n + 1))])
        k = n // 2
        want = h[n] - h[n - (n + 1) // 2] if n % 2 else 0.5 * ((h[n] - h[n - k]) + (h[n] - h[n - k - 1]))
        assert expected_median_fraction(n, 2.0) == pytest.approx(want, rel=1e-9)

    def test_expected_median_gamma_monte_carlo(self):
        """For averaged looks (gamma, 8 dof) E[median] matches a Monte Carlo estimate."""
        rng = np.random.default_rng(1)
        x = rng.gamma(4.0, 0.25, size=(200_000, 14))
        assert expected_median_fraction(14, 8.0) == pytest.approx(np.median(x, axis=1).mean(), rel=3e-3)

    @pytest.mark.parametrize("pool", [None, 10])
    def test_unit_mean_on_coloured_noise(self, pool):
        """Noise whose level varies across beams and bins comes out with mean 1 in every beam."""
        rng = np.random.default_rng(2)
        level = np.exp(rng.normal(size=(1, 8, 1))) * np.linspace(1.0, 2.0, 24)[None, None, :]
        p = level * rng.exponential(size=(300, 8, 24))
        z = normalize_spectra(p, pool_scans=pool)
        assert_allclose(z.mean(axis=(0, 2)), 1.0, atol=0.05)

    def test_per_update_level_unbiased(self):
        """Per-update windows (pool_scans=1): the noise level estimate itself is unbiased."""
        rng = np.random.default_rng(5)
        p = 3.0 * rng.exponential(size=(4000, 2, 16))
        z = normalize_spectra(p, pool_scans=1, bins=[8])
        level = p[:, :, 8] / z[:, :, 0]
        assert level.mean() == pytest.approx(3.0, rel=0.02)

    def test_line_bin_and_gap_neighbours_unbiased(self):
        """A strong line is left out of its own and its gap neighbours' windows: those stay unbiased."""
        rng = np.random.default_rng(3)
        p = rng.exponential(size=(200, 4, 16))
        p[:, :, 8] += 100.0
        z = normalize_spectra(p, gap_bins=1)
        assert z[:, :, 8].mean() == pytest.approx(101.0, rel=0.05)
        assert z[:, :, [7, 9]].mean() == pytest.approx(1.0, abs=0.03)
        # bins with the line inside their window: the median moves by at most one rank
        others = np.delete(z, [7, 8, 9], axis=2)
        assert 0.8 < others.mean() < 1.0

    def test_subset_of_bins_equals_full(self):
        """Normalising only some bins gives exactly the corresponding bins of the full result."""
        p = np.random.default_rng(4).exponential(size=(10, 5, 16))
        assert_allclose(normalize_spectra(p, bins=[3, 7]), normalize_spectra(p)[:, :, [3, 7]])

    def test_bad_input(self):
        """Too few bins for a window, NaN, wrong shape raise ValueError."""
        with pytest.raises(ValueError, match="window"):
            normalize_spectra(np.ones((4, 4, 3)))
        bad = np.ones((4, 4, 16))
        bad[0, 0, 0] = np.nan
        with pytest.raises(ValueError, match="NaN"):
            normalize_spectra(bad)
        with pytest.raises(ValueError, match="shape"):
            normalize_spectra(np.ones((4, 16)))


# ------------------------------------------------------------------------------------------
# fan search (program segments 46-48, rateest)
# ------------------------------------------------------------------------------------------
def rateest_loop(btr_rev, anchor, slopes, min_scans):
    """Literal loop transcription of the method's rateest (segments 62-70), rounding floor(x+.5)."""
    n_scans, n_beams = btr_rev.shape
    est, sav, used = 0.0, 0.0, 0
    for a in slopes:
        total, iscan = 0.0, 0
        while iscan < n_scans:
            ibeam = math.floor(a * iscan + anchor + 0.5)
            if ibeam >= n_beams or ibeam < 0:
                break
            total += btr_rev[iscan, ibeam]
            iscan += 1
        if iscan >= min_scans:
            cur = total / iscan
            if cur > sav:
                est, sav, used = a, cur, iscan
    return est, sav, used


@pytest.mark.parametrize("seed", range(6))
def test_fan_search_equals_brute_force(seed):
    """The vectorised fan search returns the loop implementation's slope, SPN and scans used."""
    rng = np.random.default_rng(seed)
    n_scans, n_beams = int(rng.integers(5, 14)), int(rng.integers(6, 16))
    btr = rng.exponential(size=(n_scans, n_beams))
    anchors = np.arange(n_beams)  # every fan, edges included
    # an irregular grid: positions a * k never land on exact half beams, where the loop's
    # floor(a k + anchor + 0.5) and the cached floor(a k + 0.5) + anchor may round apart
    slopes = slope_grid(-1.3 - rng.uniform(0, 0.01), 1.3, 0.05 + rng.uniform(0, 0.001))
    min_scans = int(rng.integers(2, n_scans + 1))
    fans = best_lines_in_fans(btr, anchors, slopes, min_scans=min_scans)
    for i, anc in enumerate(anchors):
        est, sav, used = rateest_loop(btr, int(anc), slopes, min_scans)
        assert fans.slope[i] == pytest.approx(est, abs=1e-12)
        assert fans.signal_plus_noise[i] == pytest.approx(sav, rel=1e-12)
        assert fans.n_used[i] == used
        assert bool(fans.found[i]) == (sav > 0)


def test_regression_beam_trace_short_min_scans_index_error():
    """Regression: steep straight lines (min_scans < numscans) no longer index past the padded BTR
    (IndexError); the fan search still equals the loop, and acquire(trace="beam") runs."""
    rng = np.random.default_rng(7)
    n_scans, n_beams, min_scans = 12, 10, 2
    btr = rng.exponential(size=(n_scans, n_beams))
    max_slope = (n_beams - 1) / (min_scans - 1)  # the default fan: steep lines leave early
    slopes = slope_grid(-max_slope - 0.013, max_slope, 0.25 + 0.0007)
    fans = best_lines_in_fans(btr, np.arange(n_beams), slopes, min_scans=min_scans)
    for anc in range(n_beams):
        est, sav, used = rateest_loop(btr, anc, slopes, min_scans)
        assert fans.slope[anc] == pytest.approx(est, abs=1e-12)
        assert fans.signal_plus_noise[anc] == pytest.approx(sav, rel=1e-12)
        assert fans.n_used[anc] == used
    sc = simulate_cube(seed=3, bearing0_deg=60.0, bearing_rate_deg_per_min=30.0, snr_db=6.0)
    res = Acquisition(trace="beam", min_scans=10).acquire(sc.cube, beam=sc.click_beam,
                                                          freq_hz=sc.click_freq)
    assert not res.default_used and res.best_line.trace == "beam"
    assert res.bearing_rate_deg_per_min == pytest.approx(30.0, rel=0.25)


def test_fan_search_edge_rule():
    """With minscan = numscans a line leaving the BTR is never chosen; a shorter minscan allows it."""
    btr = np.ones((10, 8))
    # a bright trace from beam 1 (latest) going off the edge toward beam -2 in the past
    for k in range(10):
        b = round(1 - 0.3 * k)
        if b >= 0:
            btr[k, b] = 9.0
    slopes = slope_grid(-1.0, 1.0, 0.1)
    full = best_lines_in_fans(btr, [1], slopes, min_scans=10)
    short = best_lines_in_fans(btr, [1], slopes, min_scans=3)
    assert full.n_used[0] == 10 and full.signal_plus_noise[0] < 9.0
    # lines that follow the trace off the edge now qualify: mean 9, cut before 10 scans; of the
    # equally bright ones the first in slope order wins (the method's strict ">")
    assert short.signal_plus_noise[0] == pytest.approx(9.0)
    assert short.n_used[0] < 10
    assert short.slope[0] == pytest.approx(-0.5)


# ------------------------------------------------------------------------------------------
# constant-bearing-rate traces (the fans' lines in cosine-spaced beams) and their refinement
# ------------------------------------------------------------------------------------------
def test_constant_rate_traces_follow_the_bearing():
    """Positions are beam_from_bearing of theta_end - rate * t; the trace is cut outside [0, pi]."""
    end = beam_from_bearing(math.radians(100.0), 64)
    rate = math.radians(30.0) / 60.0
    pos, n_used = constant_rate_traces(end, rate, n_scans=60, n_beams=64, scan_period=1.0)
    want = beam_from_bearing(math.radians(100.0) - rate * np.arange(60), 64)
    assert_allclose(pos, want, atol=1e-9)
    assert int(n_used) == 60
    # from 10 deg, going back in time at +30 deg/min the bearing crosses 0 after 20 s
    _, cut = constant_rate_traces(beam_from_bearing(math.radians(10.0), 64), rate, n_scans=60,
                                  n_beams=64, scan_period=1.0)
    assert int(cut) == 21


def rateest_trace_loop(btr_rev, anchor, rates, min_scans, period):
    """Loop form of rateest with the line replaced by a constant-bearing-rate trace (nearest beam)."""
    n_scans, n_beams = btr_rev.shape
    theta_end = math.acos(1 - 2 * anchor / (n_beams - 1))
    est, sav, used = 0.0, 0.0, 0
    for w in rates:
        total, iscan = 0.0, 0
        while iscan < n_scans:
            theta = theta_end - w * iscan * period
            if theta < -1e-12 or theta > math.pi + 1e-12:
                break
            fbeam = (n_beams - 1) * (1 - math.cos(theta)) / 2
            total += btr_rev[iscan, min(math.floor(fbeam + 0.5), n_beams - 1)]
            iscan += 1
        if iscan >= min_scans and total / iscan > sav:
            est, sav, used = w, total / iscan, iscan
    return est, sav, used


@pytest.mark.parametrize("seed", range(4))
def test_trace_fan_search_equals_loop(seed):
    """The vectorised trace fans return the loop's rate, SPN and scans used."""
    rng = np.random.default_rng(seed)
    n_scans, n_beams = int(rng.integers(5, 14)), int(rng.integers(6, 16))
    btr = rng.exponential(size=(n_scans, n_beams))
    rates = np.linspace(-0.4, 0.4, 57) + rng.uniform(0, 1e-3)
    min_scans = int(rng.integers(2, n_scans + 1))
    fans = best_traces_in_fans(btr, np.arange(n_beams), rates, scan_period=1.0, min_scans=min_scans)
    for i in range(n_beams):
        est, sav, used = rateest_trace_loop(btr, i, rates, min_scans, 1.0)
        assert fans.rate_rad_s[i] == pytest.approx(est, abs=1e-12)
        assert fans.signal_plus_noise[i] == pytest.approx(sav, rel=1e-12)
        assert fans.n_used[i] == used


def test_matched_score_peaks_on_the_true_trace_at_the_edge():
    """Noise-free, the matched score of a trace near endfire is largest on the true trace."""
    sc = simulate_cube(seed=2, bearing0_deg=168.0, bearing_rate_deg_per_min=-3.0, snr_db=20.0,
                       noise=False)
    btr_rev = sc.cube.power[::-1, :, int(np.argmin(np.abs(sc.cube.freqs - sc.click_freq)))]
    rate = math.radians(-3.0) / 60.0
    end = np.asarray(sc.beam_track)[-1]
    ends = end + np.linspace(-0.5, 0.5, 11)[:, None] + 0 * np.arange(11)[None, :]
    ends = np.clip(ends, 0, 63)
    rates = rate + np.linspace(-0.002, 0.002, 11)[None, :] + 0 * ends
    pos, nu = constant_rate_traces(ends, rates, n_scans=60, n_beams=64, scan_period=1.0)
    s = matched_trace_score(btr_rev, pos, nu, lobe_beams=0.1 * 63 / 2, noise_level=1.0)
    i, j = np.unravel_index(np.argmax(s), s.shape)
    assert abs(ends[i, j] - end) <= 0.1 and abs(rates[i, j] - rate) <= 0.0004


@pytest.mark.parametrize(("b0", "rate", "tol_rate", "tol_brg"), [
    (70.0, 40.0, 0.2, 0.1),      # ends near broadside (109 deg)
    (110.0, -40.0, 0.2, 0.1),    # ends near broadside (71 deg)
    (50.0, -40.0, 0.5, 0.4),     # ends near forward endfire (10.7 deg)
    (130.0, 40.0, 0.5, 0.4),     # ends near aft endfire (169.3 deg)
])
def test_known_answer_noise_free_constant_rate(b0, rate, tol_rate, tol_brg):
    """A noise-free 40 deg/min target: bearing rate and bearing within tight tolerances."""
    sc = simulate_cube(seed=3, bearing0_deg=b0, bearing_rate_deg_per_min=rate, snr_db=10.0,
                       noise=False)
    res = Acquisition(normalize=False).acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    assert not res.default_used and res.best_line.refined and res.best_line.trace == "bearing"
    assert res.bearing_rate_deg_per_min == pytest.approx(rate, abs=tol_rate)
    assert res.bearing_deg == pytest.approx(sc.latest_bearing_deg, abs=tol_brg)
    # the drawn trace is the trace of the estimate, chronological, ending at the end beam
    bl = res.best_line
    assert bl.beams.size == bl.n_scans_used == 60 and bl.beams[-1] == pytest.approx(bl.end_beam)


@pytest.mark.parametrize(("b0", "rate"), [
    (70.0, 40.0), (50.0, -40.0), (130.0, 40.0), (12.0, 0.3), (60.0, 2.0), (150.0, -1.5),
    (100.0, 10.0), (25.0, -5.0), (165.0, 3.0), (90.0, 0.0),
])
def test_refinement_never_worse_than_coarse_noise_free(b0, rate):
    """Noise-free: the refined rate and bearing are never worse than the coarse fan search's."""
    sc = simulate_cube(seed=4, bearing0_deg=b0, bearing_rate_deg_per_min=rate, snr_db=10.0,
                       noise=False)
    kw = {"beam": sc.click_beam, "freq_hz": sc.click_freq}
    fine = Acquisition(normalize=False).acquire(sc.cube, **kw)
    coarse = Acquisition(normalize=False, refine=False).acquire(sc.cube, **kw)
    truth = sc.latest_bearing_deg
    assert abs(fine.bearing_rate_deg_per_min - rate) <= abs(coarse.bearing_rate_deg_per_min - rate) + 1e-6
    assert abs(fine.bearing_deg - truth) <= abs(coarse.bearing_deg - truth) + 1e-6
    assert abs(fine.bearing_rate_deg_per_min - rate) <= 0.35
    # the SPN (and so the SNR and the default rule) is the fan search's, untouched by refinement
    assert fine.snr_ibw == coarse.snr_ibw
    assert fine.best_line.coarse_end_beam == coarse.best_line.end_beam


def test_refine_trace_score_never_decreases():
    """The refined matched score is at least the starting trace's, also on noise."""
    rng = np.random.default_rng(7)
    btr = rng.exponential(size=(60, 64))
    for end, rate in ((10.0, 0.004), (40.0, -0.002), (1.0, 0.0)):
        ref = refine_trace(btr, end, rate, scan_period=1.0, min_scans=60, lobe_beams=3.15,
                           noise_level=1.0)
        assert ref.score >= ref.start_score


# ------------------------------------------------------------------------------------------
# whole acquisition
# ------------------------------------------------------------------------------------------
#: the method's literal straight lines on a fine slope grid
LITERAL = {"normalize": False, "trace": "beam", "slope_step": 0.05, "max_slope": 1.2}


def _straight_line_cube(slope_per_scan: float, end_beam: int, *, level: float = 5.0) -> Cube:
    """Noise-free normalised cube: ones, and a line of `level` in bin 2 along a straight beam track."""
    n_scans, n_beams = 30, 40
    power = np.ones((n_scans, n_beams, 5))
    for s in range(n_scans):
        b = math.floor(end_beam + slope_per_scan * (s - (n_scans - 1)) + 0.5)
        power[s, b, 2] = level
    return Cube(power=power, freqs=100.0 + np.arange(5.0), scan_period=2.0, aperture=30.0,
                sound_speed=1500.0)


def test_known_answer_straight_line():
    """A noise-free straight trace gives its slope, end beam, SPN 5, noise 1, SNR 4 exactly."""
    cube = _straight_line_cube(0.4, 25)
    res = Acquisition(**LITERAL).acquire(cube, beam=25, freq_hz=102.0)
    bl = res.best_line
    assert bl.anchor_beam == 25 and bl.end_scan == 29 and bl.start_scan == 0
    assert bl.beam_rate_per_scan == pytest.approx(0.4)
    assert bl.signal_plus_noise == pytest.approx(5.0)
    assert res.band_noise_level == pytest.approx(1.0)
    assert res.snr_ibw == pytest.approx(4.0)
    assert not res.default_used
    mid = 25 - 0.4 * 29 / 2
    want = math.degrees(bearing_rate_from_beam_rate(mid, 0.4 / 2.0, 40)) * 60.0
    assert res.bearing_rate_deg_per_min == pytest.approx(want)
    assert res.bearing_deg == pytest.approx(math.degrees(bearing_from_beam(25, 40)))
    # eq. 4: SNR(1 Hz) = snr_ibw * nbins_ibw * dfbin * 1.3
    assert res.snr_db == pytest.approx(10 * math.log10(4.0 * 1 * 1.0 * HAMMING_ENBW))


def test_anchor_within_tolerance_of_click():
    """A click one beam off still finds the trace through a neighbouring anchor beam."""
    cube = _straight_line_cube(-0.3, 20)
    res = Acquisition(**LITERAL).acquire(cube, beam=21, freq_hz=102.0)
    assert res.beam_tolerance >= 2 and 20 in res.anchor_beams
    assert res.best_line.anchor_beam == 20
    assert res.best_line.beam_rate_per_scan == pytest.approx(-0.3)


def test_lag_correction():
    """The lag moves the bearing by rate x lag; zero rate leaves it unchanged."""
    cube = _straight_line_cube(0.4, 25)
    base = Acquisition(**LITERAL).acquire(cube, beam=25, freq_hz=102.0)
    lagged = Acquisition(**LITERAL, lag_s=6.0).acquire(
        cube, beam=25, freq_hz=102.0)
    assert lagged.bearing_uncorrected_deg == pytest.approx(base.bearing_deg)
    assert lagged.bearing_deg == pytest.approx(
        base.bearing_deg + base.bearing_rate_deg_per_min / 60.0 * 6.0)


@pytest.mark.parametrize(("seed", "b0", "rate"), [(1, 50.0, 35.0), (2, 130.0, -35.0), (3, 75.0, 20.0)])
def test_known_answer_high_rate(seed, b0, rate):
    """A high-rate line at 10 dB per bin: rate within 25 %, bearing within half a beamwidth."""
    sc = simulate_cube(seed=seed, bearing0_deg=b0, bearing_rate_deg_per_min=rate, snr_db=10.0)
    res = Acquisition().acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    assert not res.default_used
    assert res.bearing_rate_deg_per_min == pytest.approx(rate, rel=0.25)
    hb = half_beamwidth_deg(sc.latest_bearing_deg, 5.0, 50.0)
    assert abs(res.bearing_deg - sc.latest_bearing_deg) <= hb


def test_known_answer_zero_rate():
    """A stationary line at broadside at 10 dB: rate within 2 deg/min, bearing near 90 deg."""
    sc = simulate_cube(seed=4, bearing0_deg=90.0, bearing_rate_deg_per_min=0.0, snr_db=10.0)
    res = Acquisition().acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    assert not res.default_used
    assert abs(res.bearing_rate_deg_per_min) <= 2.0
    assert abs(res.bearing_deg - 90.0) <= half_beamwidth_deg(90.0, 5.0, 50.0)


def test_lagged_scenario_corrected():
    """With a 4 s display lag at 35 deg/min the correction moves the bearing toward the truth."""
    sc = simulate_cube(seed=6, bearing0_deg=55.0, bearing_rate_deg_per_min=35.0, snr_db=10.0,
                       lag_s=4.0)
    plain = Acquisition().acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    fixed = Acquisition(lag_s=4.0).acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    step = fixed.bearing_deg - plain.bearing_deg
    assert step == pytest.approx(plain.bearing_rate_deg_per_min * 4.0 / 60.0)
    assert step > 0


def test_defaults_on_noise_only_cube():
    """Noise only: defaults (rate 0, clicked beam's bearing, eq. 4 of the default SNR)."""
    sc = simulate_cube(seed=5, snr_db=-200.0)
    res = Acquisition().acquire(sc.cube, beam=20, freq_hz=float(sc.cube.freqs[8]))
    assert res.default_used
    assert res.snr_ibw <= 1.0
    assert res.bearing_rate_deg_per_min == 0.0
    assert res.bearing_deg == pytest.approx(math.degrees(bearing_from_beam(20, 64)))
    assert res.snr_db == pytest.approx(10 * math.log10(1.0 * 1 * 1.0 * 1.3))
    assert res.to_json()["default_used"] is True


def test_same_input_same_output_and_function_form():
    """Deterministic, and acquire() equals Acquisition().acquire()."""
    sc = simulate_cube(seed=8, bearing0_deg=60.0, bearing_rate_deg_per_min=25.0)
    a = Acquisition(ibw_hz=3.0).acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    b = acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq, ibw_hz=3.0)
    assert a.to_json() == b.to_json()
    assert np.array_equal(a.btr, b.btr)
    assert a.ibw_bins == tuple(ibw_bins(sc.cube.freqs, sc.click_freq, 3.0)) and len(a.ibw_bins) == 3


def test_beamwidth_and_noise_level_helpers():
    """Beamwidth at broadside is 2 asin(0.443 lambda / L), at endfire acos(1 - 0.443 lambda / L)
    (the lobe clipped at cos = 1), element-wise on arrays; noise level skips the trace."""
    assert beamwidth_deg(90.0, wavelength=5.0, aperture=50.0) == pytest.approx(
        2 * math.degrees(math.asin(0.0443)))
    assert beamwidth_deg(0.0, wavelength=5.0, aperture=50.0) == pytest.approx(
        math.degrees(math.acos(1 - 0.0443)))
    brg = np.array([0.0, 30.0, 90.0, 150.0, 180.0])
    assert_allclose(beamwidth_deg(brg, wavelength=5.0, aperture=50.0),
                    [beamwidth_deg(b, wavelength=5.0, aperture=50.0) for b in brg], rtol=1e-15)
    btr = np.ones((6, 12))
    btr[:, 5] = 50.0
    assert band_noise_level(btr, 5, 0.0, exclude_beams=1.0) == pytest.approx(1.0)


@pytest.mark.parametrize(("options", "fans"), [
    ({"trace": "beam", "rate_at": "latest", "slope_step": 0.01},
     StraightLineFans(rate_at="latest", slope_step=0.01)),
    ({"sampling": "linear", "refine_span_beams": 1.5},
     ConstantRateFans(sampling="linear", refine_span_beams=1.5)),
    ({"refine": False}, ConstantRateFans(refine=False)),
])
def test_fan_strategy_parts_equal_the_options(options, fans):
    """A FanStrategy passed as ``fans`` gives the same result as the equivalent options."""
    sc = simulate_cube(seed=5, bearing0_deg=70.0, bearing_rate_deg_per_min=-25.0, snr_db=6.0)
    click = {"beam": sc.click_beam, "freq_hz": sc.click_freq}
    a = Acquisition(min_scans=40, **options).acquire(sc.cube, **click)
    b = Acquisition(min_scans=40, fans=fans).acquire(sc.cube, **click)
    assert a.to_json() == b.to_json()
    assert a.best_line.refined == b.best_line.refined
    assert_allclose(a.best_line.beams, b.best_line.beams, rtol=0, atol=0)


def test_fans_and_trace_options_are_exclusive():
    """``fans`` with a trace option, or something that is not a FanStrategy, is refused."""
    with pytest.raises(ValueError, match="either fans or the options rate_at, trace"):
        Acquisition(fans=StraightLineFans(), trace="beam", rate_at="latest")
    with pytest.raises(ValueError, match="FanStrategy"):
        Acquisition(fans="beam")
    with pytest.raises(ValueError, match="max_slope"):
        StraightLineFans(max_slope=0.0)
    with pytest.raises(ValueError, match="sampling"):
        ConstantRateFans(sampling="cubic")


class TestBadInput:
    @pytest.fixture
    def cube(self):
        return simulate_cube(seed=9).cube

    @pytest.mark.parametrize("beam", [-1, 64, 2.5])
    def test_beam_outside(self, cube, beam):
        """A beam outside the cube or not an integer raises ValueError."""
        with pytest.raises(ValueError, match="beam"):
            Acquisition().acquire(cube, beam=beam, freq_hz=float(cube.freqs[3]))

    @pytest.mark.parametrize("freq", [10.0, 1e4, float("nan")])
    def test_frequency_outside(self, cube, freq):
        """A frequency outside the cube's band raises ValueError."""
        with pytest.raises(ValueError, match="frequency"):
            Acquisition().acquire(cube, beam=3, freq_hz=freq)

    def test_not_a_cube_and_bad_shapes(self):
        """Not a Cube, a 2-D power array, NaN power: ValueError."""
        with pytest.raises(ValueError, match="Cube"):
            Acquisition().acquire(np.ones((4, 4, 4)), beam=0, freq_hz=1.0)
        with pytest.raises(ValueError, match="shape"):
            Cube(power=np.ones((4, 4)), freqs=[1.0], scan_period=1.0, aperture=1.0)
        p = np.ones((4, 4, 4))
        p[1, 1, 1] = np.nan
        with pytest.raises(ValueError, match="NaN"):
            Cube(power=p, freqs=[1.0, 2, 3, 4], scan_period=1.0, aperture=1.0)

    @pytest.mark.parametrize(
        ("kwargs", "match"),
        [({"ibw_hz": -1.0}, "ibw_hz"), ({"min_scans": 1}, "min_scans"),
         ({"rate_at": "start"}, "rate_at"), ({"slope_step": 0.0}, "slope_step"),
         ({"trace": "curve"}, "trace"), ({"sampling": "cubic"}, "sampling"),
         ({"slope_step": 0.1}, "slope_step"), ({"trace": "beam", "refine": True}, "refine"),
         ({"trace": "beam", "max_rate_deg_per_min": 60.0}, "max_rate"),
         ({"refine_span_beams": -1.0}, "refine_span_beams")],
    )
    def test_bad_options(self, kwargs, match):
        """Bad constructor options raise ValueError naming the option."""
        with pytest.raises(ValueError, match=match):
            Acquisition(**kwargs)


class TestCli:
    def test_prints_json(self, tmp_path, run_cli):
        """``fusion acquire`` prints the four keys of the file-format contract."""
        sc = simulate_cube(seed=10, bearing0_deg=60.0, bearing_rate_deg_per_min=30.0, snr_db=10.0)
        write_cube(tmp_path / "c.npz", sc.cube)
        code, out, err = run_cli("acquire", "--cube", tmp_path / "c.npz", "--beam", sc.click_beam,
                                 "--freq-hz", sc.click_freq, "--display-lag-s", "1.0")
        assert code == 0, err
        got = json.loads(out)
        assert sorted(got) == ["bearing_deg", "bearing_rate_deg_per_min", "default_used", "snr_db"]
        assert got["bearing_rate_deg_per_min"] == pytest.approx(30.0, rel=0.25)

    @pytest.mark.parametrize(("args", "options"), [
        (("--trace", "beam", "--rate-at", "latest", "--min-scans", "30"),
         {"trace": "beam", "rate_at": "latest", "min_scans": 30}),
        (("--trace", "beam", "--pool-scans", "5"), {"trace": "beam", "pool_scans": 5}),
        (("--pool-scans", "1",), {"pool_scans": 1}),
    ])
    def test_trace_options_reach_the_acquisition(self, tmp_path, run_cli, args, options):
        """--trace, --rate-at and --pool-scans give the library's result for those options."""
        sc = simulate_cube(seed=12, bearing0_deg=50.0, bearing_rate_deg_per_min=35.0, snr_db=8.0)
        write_cube(tmp_path / "c.npz", sc.cube)
        code, out, err = run_cli("acquire", "--cube", tmp_path / "c.npz", "--beam", sc.click_beam,
                                 "--freq-hz", sc.click_freq, *args)
        assert code == 0, err
        want = Acquisition(**options).acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
        assert json.loads(out) == pytest.approx(want.to_json(), rel=1e-12)
        assert want.to_json() != Acquisition().acquire(
            sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq).to_json()

    def test_rate_at_needs_the_beam_trace(self, tmp_path, run_cli):
        """--rate-at without --trace beam: exit 2 with one line naming the option."""
        write_cube(tmp_path / "c.npz", simulate_cube(seed=11).cube)
        code, out, err = run_cli("acquire", "--cube", tmp_path / "c.npz", "--beam", "3",
                                 "--freq-hz", "300", "--rate-at", "latest")
        assert code == 2 and out == ""
        assert len(err.strip().splitlines()) == 1 and "--rate-at" in err

    @pytest.mark.parametrize("args", [("--beam", "99", "--freq-hz", "300"),
                                      ("--beam", "3", "--freq-hz", "5")])
    def test_bad_click_exit_2(self, tmp_path, run_cli, args):
        """A click outside the cube: exit 2, one line on stderr, nothing on stdout."""
        write_cube(tmp_path / "c.npz", simulate_cube(seed=11).cube)
        code, out, err = run_cli("acquire", "--cube", tmp_path / "c.npz", *args)
        assert code == 2 and out == ""
        assert len(err.strip().splitlines()) == 1 and "c.npz" in err

    def test_missing_file_exit_2(self, tmp_path, run_cli):
        """A missing cube: exit 2, one line."""
        code, out, err = run_cli("acquire", "--cube", tmp_path / "no.npz", "--beam", "1",
                                 "--freq-hz", "300")
        assert code == 2 and len(err.strip().splitlines()) == 1
