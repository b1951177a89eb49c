"""Tests of the click band estimated from an averaged click (step 32)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from fusion.clicks.band import (
    DEFAULT_BAND_HZ,
    MIN_BAND_WIDTH_HZ,
    NYQUIST_FRACTION,
    click_band,
    detection_band,
)
from fusion.simulate.whale_range.types import ClickWaveform

FS = 96_000.0


def _hann_tone(f0: float, duration_s: float) -> np.ndarray:
    """``cos^2(pi t / D) cos(2 pi f0 t)`` on ``|t| <= D / 2``, sampled at FS."""
    half = int(round(0.5 * duration_s * FS))
    t = np.arange(-half, half + 1) / FS
    return np.cos(np.pi * t / duration_s) ** 2 * np.cos(2 * np.pi * f0 * t)


@pytest.mark.parametrize(("f0", "duration_s"), [(30_000.0, 1e-3), (30_000.0, 0.5e-3),
                                                 (20_000.0, 0.75e-3)])
def test_hann_tone_band_is_the_analytic_minus_10_db_band(f0, duration_s):
    """The Hann window's spectrum is ``sinc(x) / (1 - x^2)`` with ``x = (f - f0) D``: its
    energy falls 10 dB at ``x = 1.2558`` (solved here independently), so the band of a Hann
    tone is ``f0 -+ 1.2558 / D``."""
    x = brentq(lambda v: (np.sinc(v) / (1.0 - v * v)) ** 2 - 0.1, 0.3, 1.9)
    assert x == pytest.approx(1.2558, abs=1e-4)
    lo, hi = click_band(_hann_tone(f0, duration_s), FS)
    assert lo == pytest.approx(f0 - x / duration_s, abs=5.0)
    assert hi == pytest.approx(f0 + x / duration_s, abs=5.0)


def test_sweep_band_lies_inside_its_sweep_and_grows_with_the_drop():
    """A Hann-tapered 25-45 kHz upsweep: the taper trims the ends, so the -10 dB band lies
    inside 25-45 kHz and covers most of it; a deeper drop gives a wider band."""
    click = ClickWaveform(25_000.0, 45_000.0, 250e-6).replica(FS)
    lo, hi = click_band(click, FS)
    assert 25_000.0 < lo < 30_000.0 and 40_000.0 < hi < 45_000.0
    lo6, hi6 = click_band(click, FS, drop_db=6.0)
    lo20, hi20 = click_band(click, FS, drop_db=20.0)
    assert lo20 < lo < lo6 and hi6 < hi < hi20


def test_band_is_bounded_below_nyquist():
    """A sweep up to 47.5 kHz at 96 kHz: the upper edge stops at 0.95 of 48 kHz."""
    lo, hi = click_band(ClickWaveform(40_000.0, 47_500.0, 300e-6).replica(FS), FS)
    assert hi == pytest.approx(NYQUIST_FRACTION * 0.5 * FS)
    assert 35_000.0 < lo < 42_000.0


def test_detection_band_keeps_the_methods_width():
    """A narrow band is widened about its centre to the default band's width, and shifted
    down where it would pass the Nyquist bound; a wide band is kept."""
    assert MIN_BAND_WIDTH_HZ == DEFAULT_BAND_HZ[1] - DEFAULT_BAND_HZ[0]
    tone = _hann_tone(30_000.0, 0.5e-3)
    lo, hi = click_band(tone, FS)
    wlo, whi = detection_band(tone, FS)
    assert whi - wlo == pytest.approx(MIN_BAND_WIDTH_HZ)
    assert 0.5 * (wlo + whi) == pytest.approx(0.5 * (lo + hi))
    high = ClickWaveform(40_000.0, 46_000.0, 300e-6).replica(FS)
    assert detection_band(high, FS) == pytest.approx(
        (NYQUIST_FRACTION * 0.5 * FS - MIN_BAND_WIDTH_HZ, NYQUIST_FRACTION * 0.5 * FS))
    wide = _hann_tone(28_000.0, 0.08e-3)  # a 0.08 ms click: about 31 kHz wide
    assert click_band(wide, FS)[1] - click_band(wide, FS)[0] > MIN_BAND_WIDTH_HZ
    assert detection_band(wide, FS) == click_band(wide, FS)
    assert detection_band(tone, FS, min_width_hz=0.0) == (lo, hi)


@pytest.mark.parametrize(("samples", "kwargs"), [
    (np.zeros(10), {}), (np.ones((3, 3)), {}), (np.ones(10), {"drop_db": 0.0}),
    (np.ones(10), {"nyquist_fraction": 1.0}), (np.array([1.0, np.nan, 1.0]), {})])
def test_bad_input_is_refused(samples, kwargs):
    with pytest.raises(ValueError):
        click_band(samples, FS, **kwargs)
