"""Smoothed click maps: normalisation, the fast construction, correlation peaks and SCM2."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.fft
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from fusion.clicks import _scm_grid
from fusion.clicks.scm import (
    ClickMapCorrelator,
    ScmConfig,
    scm1,
    scm1_spectrum,
    scm2,
    scm2_many,
    window_weight,
)
from fusion.clicks.types import ChannelClicks
from fusion.geometry import SensorArray

CFG = ScmConfig()
FS, N, T = CFG.fs_hz, CFG.n_samples, CFG.window_s


def literal_spectrum(times: np.ndarray, t0: float, *, windowed: bool) -> np.ndarray:
    """Eq. 3 (or 5) summed term by term over every bin k = -N/2 .. N/2 - 1 (full FFT order)."""
    k = np.fft.fftfreq(N, 1.0 / N)  # signed bin numbers
    shading = np.where(np.abs(k) < N / 8, 0.5 * (1 + np.cos(np.pi * k / (N / 8))), 0.0)
    w = np.fft.ifft(shading).real
    c = 1.0 / np.sqrt(np.sum(w**2))  # eq. 4
    t = times - t0
    a = np.exp(-((t - T / 2) ** 4) / (T / 4) ** 4) if windowed else np.ones(t.size)
    return c * shading * (a[:, None] * np.exp(-2j * np.pi * np.outer(t * FS, k) / N)).sum(axis=0)


def test_config_defaults_follow_the_text():
    """N = 36000 samples, shading zero at N/8, pulse 16 samples wide zero to zero."""
    assert CFG.n_samples == 36000
    assert CFG.half_width_bins == 4500
    assert_allclose(CFG.pulse_halfwidth_s * FS, 8.0)
    assert_allclose(CFG.pulse_peak, 1 / np.sqrt(6), rtol=1e-12)  # c w0 = (1/8) / sqrt(3/32)


@pytest.mark.parametrize("windowed", [False, True])
def test_fast_spectrum_equals_literal_eq3_eq5(windowed):
    """Gridded SCM1 spectra and time series equal the term-by-term eq. 3 / eq. 5 to 1e-9."""
    rng = np.random.default_rng(3)
    t0 = 100.0
    # fractional times anywhere, including within a pulse width of both window edges (wrap)
    times = np.sort(np.r_[t0 + rng.uniform(0, T, 60), t0 + 1e-4, t0 + T - 2e-4])
    full = literal_spectrum(times, t0, windowed=windowed)
    fast = scm1_spectrum([times], t0_s=t0, windowed=windowed)[0]
    assert_allclose(fast, full[: N // 2 + 1], rtol=0, atol=1e-9 * np.abs(full).max())
    series = scm1([times], t0_s=t0, windowed=windowed)[0]
    assert_allclose(series, np.fft.ifft(full).real, rtol=0, atol=1e-9)


def test_clicks_outside_the_window_are_ignored():
    """Clicks before t0 or at/after t0 + T leave the SCM1 unchanged."""
    inside = np.array([101.0, 105.5])
    both = np.r_[99.0, inside, 112.0, 130.0]
    assert_allclose(scm1_spectrum([both], t0_s=100.0), scm1_spectrum([inside], t0_s=100.0))


@pytest.mark.parametrize("t_click", [0.5, 6.0, 6.00012345, 11.7])
def test_single_click_autocorrelation_is_one(t_click):
    """(1/N) sum |X_k|^2 of one click is exactly 1 wherever it lies (eq. 4)."""
    x = scm1_spectrum([[t_click]], t0_s=0.0)[0]
    energy = (np.abs(x[0]) ** 2 + 2 * np.sum(np.abs(x[1:]) ** 2)) / N  # no Nyquist content
    assert_allclose(energy, 1.0, atol=1e-9)


def test_centred_click_correlation_peak_is_one():
    """A click at T/2 on both channels: eq. 6 is 1 at tau = 0 (window weight 1)."""
    cor = ClickMapCorrelator(min_peak=0.5)
    res = cor.correlate_times([[6.0], [6.0]], t0_s=0.0, max_delay_s=[1.0])
    assert_allclose(res.values[0, res.lags_s.size // 2], 1.0, atol=1e-9)
    assert_allclose([res.peaks[0].tau_s, res.peaks[0].value], [0.0, 1.0], atol=1e-9)


@pytest.mark.parametrize("delay", [0.2345678, -0.8765432, 0.0011])
def test_identical_trains_peak_at_the_delay_with_value_n(delay):
    """n clicks on i and the same clicks on j earlier by d: peak at tau = t_i - t_j = d, value ~ n."""
    rng = np.random.default_rng(7)
    ti = np.sort(5.0 + np.cumsum(rng.uniform(0.3, 0.45, 5)))  # near the window centre
    res = ClickMapCorrelator().correlate_times([ti, ti - delay], t0_s=0.0, max_delay_s=[2.0])
    best = res.peaks[0]
    assert best.pair == (0, 1)
    assert abs(best.tau_s - delay) * FS < 0.01  # parabolic interpolation on the 3 kHz grid
    # value = sum of the window weights of the matched clicks (each <= 1)
    assert_allclose(best.value, window_weight(ti, T).sum(), rtol=1e-4)
    assert 4.5 < best.value <= 5.0
    swapped = ClickMapCorrelator().correlate_times([ti - delay, ti], t0_s=0.0, max_delay_s=[2.0])
    assert abs(swapped.peaks[0].tau_s + delay) * FS < 0.01


@settings(max_examples=25, deadline=None)
@given(delay=st.floats(-1.0, 1.0), shift=st.floats(-1.0, 1.0))
def test_tdoa_antisymmetric_in_pair_order(delay, shift):
    """Pair (j, i) finds minus the TDOA of pair (i, j) (both trains well inside the window)."""
    ti = 6.0 + shift + np.arange(4) * 0.4
    cor = ClickMapCorrelator(max_peaks=1)
    a = cor.correlate_times([ti, ti - delay], t0_s=0.0, max_delay_s=[2.0], pairs=[(0, 1), (1, 0)])
    ij, ji = a.peaks_of((0, 1))[0], a.peaks_of((1, 0))[0]
    assert abs(ij.tau_s + ji.tau_s) * FS < 0.01


def test_peaks_beyond_the_physical_delay_are_excluded():
    """A train matched at a delay larger than d_ij / c gives no candidate; one inside does."""
    pos = np.array([[0.0, 0.0, -1500.0], [750.0, 0.0, -1500.0], [0.0, 900.0, -1500.0]])
    sensors = SensorArray(pos, 1500.0)  # |s0 - s1| / c = 0.5 s, |s0 - s2| / c = 0.6 s
    t = 5.0 + np.arange(6) * 0.37
    clicks = [t, t - 0.7, t - 0.3]  # pair (0, 1) at 0.7 s: impossible; (0, 2) at 0.3 s: possible
    res = ClickMapCorrelator().correlate(clicks, t0_s=0.0, sensors=sensors)
    assert_allclose(res.max_delay_s[:2], [0.5 * 1.05 + 0.002, 0.6 * 1.05 + 0.002])
    assert all(abs(p.tau_s) <= 0.527 for p in res.peaks_of((0, 1)))
    assert not any(abs(p.tau_s - 0.7) < 0.01 for p in res.peaks_of((0, 1)))
    assert abs(res.peaks_of((0, 2))[0].tau_s - 0.3) < 1e-4
    # the correlation itself does have the impossible peak
    k = np.argmin(np.abs(res.lags_s - 0.7))
    assert res.values[0, k] > 4.0


def test_min_peak_and_max_peaks():
    """A single matched click is no candidate (value <= 1); at most max_peaks per pair."""
    one = ClickMapCorrelator().correlate_times([[6.0], [5.9]], t0_s=0.0, max_delay_s=[1.0])
    assert one.peaks == ()
    ti = 5.0 + np.arange(8) * 0.3  # periodic: many ICI-alias peaks
    many = ClickMapCorrelator(max_peaks=2).correlate_times([ti, ti - 0.1], t0_s=0.0,
                                                           max_delay_s=[3.0])
    assert len(many.peaks) == 2
    assert many.peaks[0].value >= many.peaks[1].value
    assert abs(many.peaks[0].tau_s - 0.1) < 1e-4


def test_channel_clicks_input_equals_time_arrays():
    """ChannelClicks and plain arrays of their times give the same correlation."""
    t = 5.0 + np.arange(5) * 0.37
    cc = [ChannelClicks(0, t, np.ones(5), np.full(5, 3e4)), ChannelClicks(1, t - 0.05, np.ones(5),
                                                                            np.full(5, 3e4))]
    cor = ClickMapCorrelator()
    a = cor.correlate_times(cc, t0_s=0.0, max_delay_s=[1.0])
    b = cor.correlate_times([c.times_s for c in cc], t0_s=0.0, max_delay_s=[1.0])
    assert_allclose(a.values, b.values)


def test_scm2_click_times_match_input_clicks():
    """SCM2 at the true delay peaks at sensor i's click times and matches the right pairs."""
    rng = np.random.default_rng(11)
    ti = np.sort(0.5 + np.cumsum(rng.uniform(0.3, 0.45, 25)))  # whale A on sensor i
    tau = 0.41234
    tj_a = ti - tau + rng.normal(0, 2e-5, ti.size)  # 20 us detection jitter
    tj_other = np.sort(rng.uniform(0.5, 11.5, 20))  # another source on sensor j only
    tj = np.sort(np.r_[tj_a, tj_other])
    keep = np.abs(tj_other[:, None] + tau - ti[None, :]).min(axis=0) > 0.01  # no chance matches
    res = scm2(ti, tj, tau, t0_s=0.0, pair=(2, 4))
    assert res.pair == (2, 4) and res.series.shape == (N,)
    ti_k = ti[keep]
    found = res.click_times_s[np.abs(res.click_times_s[:, None] - ti_k).min(axis=1) < 1e-3]
    assert found.size == ti_k.size
    assert_allclose(np.sort(found), ti_k, atol=2e-5 + 1e-3 / FS)
    assert_allclose(res.peak_values[np.isin(res.click_times_s, found)], 1.0, atol=0.01)
    # matched pairs: i click n with its own j click
    matched = dict(zip(res.index_i.tolist(), res.index_j.tolist(), strict=True))
    for n in np.flatnonzero(keep):
        assert_allclose(tj[matched[n]], tj_a[n])
    assert len(set(res.index_j.tolist())) == res.index_j.size


def test_scm2_is_the_product_of_shifted_scm1s():
    """SCM2 equals SCM1_i(t) * SCM1_j(t - tau) / p0^2 computed from the literal eq. 3."""
    ti, tj, tau = np.array([2.0, 4.1, 7.3]), np.array([1.5, 3.62, 9.0]), 0.4871
    res = scm2(ti, tj, tau, t0_s=0.0)
    a = np.fft.ifft(literal_spectrum(ti, 0.0, windowed=False)).real
    b = np.fft.ifft(literal_spectrum(tj + tau, 0.0, windowed=False)).real
    assert_allclose(res.series, a * b / CFG.pulse_peak**2, atol=1e-9)
    assert_allclose(res.times_s[:2], [0.0, 1.0 / FS])


@pytest.mark.parametrize("tau", [0.9731, -1.2345, 2.5])
def test_scm2_across_the_window_edges_equals_literal_maps(tau):
    """Clicks the delay moves out of the window (and in from outside it) are dropped (added):
    the SCM2 equals the literal eq. 3 product of the clicks inside the window after the delay."""
    rng = np.random.default_rng(5)
    t0 = 50.0
    ti = np.sort(t0 + rng.uniform(0.0, T, 30))
    tj = np.sort(t0 + rng.uniform(-3.0, T + 3.0, 45))  # some outside the window, both sides
    res = scm2(ti, tj, tau, t0_s=t0)
    shifted = tj + tau
    inside = shifted[(shifted >= t0) & (shifted < t0 + T)]
    a = np.fft.ifft(literal_spectrum(ti[(ti >= t0) & (ti < t0 + T)], t0, windowed=False)).real
    b = np.fft.ifft(literal_spectrum(inside, t0, windowed=False)).real
    assert_allclose(res.series, a * b / CFG.pulse_peak**2, atol=1e-9)


def test_scm2_many_equals_one_scm2_per_candidate():
    """The batch gives, candidate by candidate, the SCM2 of scm2() (series, peaks, matches)."""
    rng = np.random.default_rng(8)
    base = np.sort(rng.uniform(0.0, 12.0, 30))
    times = [base + rng.normal(0, 2e-5, 30) - d for d in (0.0, 0.31, -0.52)]
    times = [np.sort(np.r_[t, rng.uniform(0.0, 12.0, 10)]) for t in times]
    pairs = [(0, 1), (0, 2), (1, 2), (2, 0), (0, 1)]
    taus = [0.31, -0.52, -0.83, 0.52, 1.7]
    many = scm2_many(times, pairs, taus, t0_s=0.0)
    assert len(many) == 5
    for res, (i, j), tau in zip(many, pairs, taus, strict=True):
        one = scm2(times[i], times[j], tau, t0_s=0.0, pair=(i, j))
        assert res.pair == (i, j) and res.tau_s == tau
        assert_allclose(res.series, one.series, rtol=0, atol=1e-12)
        assert_allclose(res.click_times_s, one.click_times_s, rtol=0, atol=1e-12)
        assert np.array_equal(res.index_i, one.index_i) and np.array_equal(res.index_j, one.index_j)
    assert many[0].index_i.size >= 25 and many[4].index_i.size <= 3  # true delay vs. none


def test_bad_inputs_raise():
    """Invalid options and inputs raise ValueError naming the problem."""
    with pytest.raises(ValueError, match="shading_width"):
        ScmConfig(shading_width=0.7)
    with pytest.raises(ValueError, match="fs_hz"):
        ScmConfig(fs_hz=-1.0)
    with pytest.raises(ValueError, match="max_peaks"):
        ClickMapCorrelator(max_peaks=0)
    with pytest.raises(ValueError, match="finite"):
        scm1_spectrum([[np.nan]], t0_s=0.0)
    with pytest.raises(ValueError, match="level"):
        scm2([1.0], [1.0], 0.0, t0_s=0.0, level=0.0)
    with pytest.raises(ValueError, match="pairs for"):
        scm2_many([[1.0], [1.0]], [(0, 1)], [0.1, 0.2], t0_s=0.0)
    with pytest.raises(ValueError, match="index"):
        scm2_many([[1.0], [1.0]], [(0, 2)], [0.1], t0_s=0.0)
    sensors = SensorArray(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]))
    with pytest.raises(ValueError, match="click channels"):
        ClickMapCorrelator().correlate([[1.0]], t0_s=0.0, sensors=sensors)
    with pytest.raises(ValueError, match="pairs"):
        ClickMapCorrelator().correlate([[1.0]] * 3, t0_s=0.0, sensors=sensors, pairs=[(0, 0)])


def test_drift_compensation_gathers_a_drifting_delay():
    """A delay drifting 1.2 ms/s through a 12 s window: the method text's correlation (no
    drift) smears it over ~14 ms and keeps a fraction of the clicks; under the drift grid the
    peak holds them all, at the delay of the window centre, with the drift found."""
    from fusion.clicks.scm import ClickMapCorrelator, drift_grid

    rng = np.random.default_rng(3)
    ti = np.cumsum(rng.uniform(0.33, 0.41, 40)) - 1.0
    ti = ti[(ti > 0.2) & (ti < 11.8)]
    tau_c, rate = 0.8123, 1.2e-3
    tj = ti - (tau_c + rate * (ti - 6.0))
    plain = ClickMapCorrelator().correlate_times([ti, tj], t0_s=0.0, max_delay_s=[1.0])
    comp = ClickMapCorrelator(rates=drift_grid()).correlate_times([ti, tj], t0_s=0.0,
                                                                  max_delay_s=[1.0])
    best = comp.peaks[0]
    assert best.rate == pytest.approx(rate, abs=2.1e-4)
    assert best.tau_s == pytest.approx(tau_c, abs=3e-4)
    assert best.value > 1.8 * plain.peaks[0].value  # the clicks gathered, not a fraction
    none = ClickMapCorrelator(rates=drift_grid(0.0))
    assert none.rates == (0.0,)
    assert [p.tau_s for p in none.correlate_times([ti, tj], t0_s=0.0, max_delay_s=[1.0]).peaks] \
        == [p.tau_s for p in plain.peaks]
    with pytest.raises(ValueError, match="rates"):
        ClickMapCorrelator(rates=())


def test_cached_map_rows_are_the_rows_of_a_fresh_batch():
    """The row cache of the SCM1 maps (one window's correlation and SCM2s read the same
    channels many times) gives each channel's spectrum and series bit for bit as a batch of
    other channels computed afresh would."""
    rng = np.random.default_rng(5)
    t0 = 100.0
    tl = [np.sort(t0 + rng.uniform(-0.5, T + 0.5, 40)) for _ in range(4)]
    _scm_grid._ROWS.clear()
    first = _scm_grid.window_maps(tl[:2], t0_s=t0, config=CFG, windowed=True)
    again = _scm_grid.window_maps(tl[1:], t0_s=t0, config=CFG)  # row tl[1] from the cache
    assert any(k[3] == tl[1].tobytes() for k in _scm_grid._ROWS)
    fresh = _scm_grid._spectra([tl[3], tl[1], tl[2]] + tl[:2], [False] * 3 + [True] * 2,
                               t0_s=t0, config=CFG)
    assert np.array_equal(again.plain, fresh[[1, 2, 0]])
    assert np.array_equal(first.windowed, fresh[3:])
    assert np.array_equal(again.series, scipy.fft.irfft(fresh[[1, 2, 0]], N, axis=-1))
    assert_allclose(again.plain[0], literal_spectrum(tl[1][(tl[1] >= t0) & (tl[1] < t0 + T)], t0,
                                                     windowed=False)[: CFG.n_bins], atol=1e-9)
