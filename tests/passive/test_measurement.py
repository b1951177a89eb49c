"""Tests of fusion.passive.measurement: one track's bearing measurement in one scan."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion.geometry import bearing_from_beam
from fusion.passive.measurement import PeakMeasurer


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


def test_innovation_gate_known_answer():
    """The innovation std is sqrt(P + sigma^2); the gate takes a local peak within `gate` of
    them and refuses one beyond it, or a flank (not a local peak) even at the prediction."""
    row = np.ones(32)
    row[[14, 15]] = 11.0
    m = PeakMeasurer(beam_sigma=0.5).measure(row, float(bearing_from_beam(16.0, 32)),
                                             search_beams=2)
    p = 0.02**2
    s = math.sqrt(p + m.sigma**2)
    assert m.innovation_std(p) == pytest.approx(s, rel=1e-15)
    assert m.in_gate(m.bearing + 2.9 * s, p, 3.0)
    assert not m.in_gate(m.bearing - 3.1 * s, p, 3.0)
    flank = np.ones(32)
    flank[20:23] = [3.0, 5.0, 9.0]
    f = PeakMeasurer(beam_sigma=0.5).measure(flank, float(bearing_from_beam(19.0, 32)),
                                             search_beams=2)
    assert not f.in_gate(f.bearing, p, 3.0)
