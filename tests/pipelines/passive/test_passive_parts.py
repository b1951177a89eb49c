"""Tests of the passive pipeline's parts: prior, measurement, starts, crossings."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import stats

from fusion.geometry import beamwidth_deg, bearing_from_beam
from fusion.passive.acquisition import Acquisition
from fusion.passive.smoothing import TrackPrior
from fusion.pipelines.passive.crossing import CrossingEpisode, CrossingResolver, EpisodeBook
from fusion.pipelines.passive.measure import LineStarter, PeakMeasurer
from fusion.pipelines.passive.tracks import AcquisitionPrior
from fusion.simulate.cube import simulate_cube

Q = math.radians(2.0 / 3600.0) ** 2  # rad^2/s^3: 2 deg/min^2 per 1 s scan
SIGMA = 0.015  # rad
PRIOR = TrackPrior(bearing=1.0, rate=5e-4, sigma_bearing=0.02, sigma_rate=3e-4)


def _bearings(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    return t, 1.0 + 6e-4 * t + 1e-6 * t**2 + SIGMA * rng.standard_normal(n)


def test_acquisition_prior_model():
    """The prior's sigmas follow the line-fit formulas; a walk off the click gives defaults."""
    sc = simulate_cube(seed=3, bearing0_deg=80.0, bearing_rate_deg_per_min=10.0, snr_db=9.0)
    res = Acquisition().acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    model = AcquisitionPrior()
    wl = 1500.0 / sc.click_freq
    p = model.prior(res, click_beam=sc.click_beam, n_beams=64, wavelength=wl, aperture=50.0,
                    scan_period=1.0)
    n = res.best_line.n_scans_used
    bw = math.radians(float(beamwidth_deg(res.bearing_deg, wavelength=wl, aperture=50.0)))
    s1 = bw / math.sqrt(2.0 * res.snr_ibw)
    assert p.bearing == pytest.approx(math.radians(res.bearing_deg))
    assert p.sigma_bearing == pytest.approx(s1 * math.sqrt((4 * n - 2) / (n * (n + 1))), rel=1e-6)
    assert p.sigma_rate == pytest.approx(s1 * math.sqrt(12 / (n * (n * n - 1))), rel=1e-6)
    far = model.prior(res, click_beam=sc.click_beam + 8, n_beams=64, wavelength=wl,
                      aperture=50.0, scan_period=1.0)
    assert far.bearing == pytest.approx(float(bearing_from_beam(sc.click_beam + 8, 64)))
    assert far.rate == 0.0
    assert far.sigma_rate == pytest.approx(math.radians(10.0) / 60.0)


def test_peak_measurer_known_answer():
    """A symmetric line between two beams is measured between them; the amplitude is the cell
    at the prediction; a stronger flank just outside the search is not a local peak."""
    row = np.ones(32)
    row[[14, 15]] = 11.0  # centroid of 13..15 weighted by power above 1 -> 14.5
    m = PeakMeasurer(beam_sigma=0.5)
    pred = float(bearing_from_beam(16.0, 32))
    out = m.measure(row, pred, search_beams=2)
    assert out.beam == pytest.approx(14.5)
    assert out.amplitude == 1.0
    assert out.residual_deg == pytest.approx(math.degrees(bearing_from_beam(14.5, 32) - pred))
    assert out.local_peak
    assert out.sigma == pytest.approx(0.5 * 2.0 / (31 * math.sin(pred)))
    flank = np.ones(32)
    flank[20:23] = [3.0, 5.0, 9.0]
    assert not m.measure(flank, float(bearing_from_beam(19.0, 32)), search_beams=2).local_peak


def test_line_starter_threshold_and_exclusion():
    """The threshold is the gamma quantile of a noise mean; a planted line is proposed unless a
    track holds it."""
    st = LineStarter(window_scans=20, false_alarm=1e-3)
    assert st.threshold == pytest.approx(stats.gamma.isf(1e-3, 20, scale=1 / 20))
    rng = np.random.default_rng(0)
    hist = rng.exponential(size=(20, 48, 16))
    hist[:, 30, 7] += 4.0
    lobes = np.full(16, 2.8)
    got = st.candidates(hist, held=[], lobe_beams=lobes)
    assert (got[0].beam, got[0].bin) == (30, 7)
    assert all(c.mean_power > st.threshold for c in got)
    held = st.candidates(hist, held=[(31.0, 8)], lobe_beams=lobes)
    assert all((c.beam, c.bin) != (30, 7) for c in held)
    with pytest.raises(ValueError, match="history"):
        st.candidates(hist[:5], held=[], lobe_beams=lobes)


def test_episode_book_opens_on_merge_and_closes_when_apart():
    """An episode opens when the pair's peaks merge (before its planned start) and closes
    after the crossing once they are apart for `clear_scans` scans."""
    book = EpisodeBook(separation_lobes=1.5, min_half_s=3.0, max_span_s=100.0, clear_scans=3)
    book.schedule((1, 2), now=0.0, t_cross=50.0, rate_diff=1e-3, beamwidth=0.01)  # half 15 s
    lobes = {1: 2.0, 2: 2.0}
    book.observe(10.0, {1: 10.0, 2: 20.0}, lobes)
    assert book.member_of(1) is None
    book.observe(11.0, {1: 10.0, 2: 12.0}, lobes)  # merged: opens early
    assert book.member_of(2) is not None and book.member_of(2).t_open == 11.0
    for t in range(12, 60):
        book.observe(float(t), {1: 15.0, 2: 15.0} if t < 52 else {1: 10.0, 2: 20.0}, lobes)
        due = book.close_due(float(t), ended=set())
        if due:
            break
    assert t == 54 and due[0].members == [1, 2] and due[0].t_close == 54.0
    assert book.episodes == []


def _crossing_episode(rng: np.random.Generator, *, unlabeled_swap: bool = False):
    """Two straight tracks crossing at t = 50 s with one detection per track and scan."""
    t_all = np.arange(0.0, 100.0)
    a = 1.0 + 0.002 * (t_all - 50.0)
    b = 1.0 - 0.002 * (t_all - 50.0)
    s = 0.003
    ep = CrossingEpisode(members=[3, 7], t_open=30.0, t_close=80.0, t_cross=50.0)
    ep.context = {3: [(t, a[int(t)] + s * rng.standard_normal(), s) for t in t_all[10:30]],
                  7: [(t, b[int(t)] + s * rng.standard_normal(), s) for t in t_all[10:30]]}
    for t in t_all[30:80]:
        k = int(t)
        for z in (a[k], b[k]):
            ep.detections.append((t, z + s * rng.standard_normal(), s))
        ep.predictions.setdefault(3, []).append((t, a[k], 2 * s))
        ep.predictions.setdefault(7, []).append((t, b[k], 2 * s))
    return ep, a, b


def test_resolver_assigns_detections_to_their_tracks():
    """Past the crossing, every detection assigned to a track lies on that track's line."""
    ep, a, b = _crossing_episode(np.random.default_rng(1))
    res, assigned = CrossingResolver().resolve(ep, scan_period=1.0, q=1e-9)
    assert set(assigned) == {3, 7} and res.tracks == (3, 7)
    assert res.method in ("multitrack", "nearest")
    for m, line in ((3, a), (7, b)):
        times, z, _ = assigned[m]
        late = times > 60.0
        assert late.sum() >= 15
        assert_allclose(z[late], line[times[late].astype(int)], atol=0.02)


def test_resolver_falls_back_to_predictions():
    """Without context bearings the multi-track match is impossible: nearest assignment."""
    ep, a, _ = _crossing_episode(np.random.default_rng(2))
    ep.context = {}
    res, assigned = CrossingResolver().resolve(ep, scan_period=1.0, q=1e-9)
    assert res.method == "nearest"
    times, z, _ = assigned[3]
    assert_allclose(z, a[times.astype(int)], atol=0.02)

