"""Tests of fusion.passive.acquisition.prior: the prior of a track started by an acquisition."""

from __future__ import annotations

import math

import pytest

from fusion.geometry import beamwidth_deg, bearing_from_beam
from fusion.passive.acquisition import Acquisition, AcquisitionPrior
from fusion.simulate.cube import simulate_cube


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
