"""Tests of fusion.localization.retime.retime_owned: each TDOA moved to its owner's emission."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from numpy.testing import assert_allclose

from fusion.localization.retime import emission_shift, retime_owned

SENSORS = np.array([[0.0, 0.0, -100.0], [800.0, 0.0, -120.0], [0.0, 900.0, -90.0],
                    [700.0, 650.0, -110.0]])
PAIRS = np.array([[0, 1], [0, 2], [1, 3], [2, 3], [1, 2]])


def _fix(position, weights, paths):
    return SimpleNamespace(position=np.asarray(position, float), weights=np.asarray(weights, float),
                           paths=np.asarray(paths))


def test_each_tdoa_follows_the_source_that_owns_it():
    """TDOAs owned by source A (largest weight) move by A's emission shift, those of B by B's;
    reflected paths (1, 3) use the surface image only when a surface is given; rate 0 moves
    nothing."""
    a, b = [200.0, 300.0, -500.0], [900.0, 100.0, -300.0]
    out = SimpleNamespace(sources=(
        _fix(a, [0.9, 0.8, 0.1, 0.2, 0.6], [0, 1, 0, 0, 3]),
        _fix(b, [0.1, 0.1, 0.7, 0.6, 0.3], [0, 0, 2, 1, 0])))
    taus = np.array([0.01, -0.02, 0.03, 0.005, -0.01])
    rate = np.array([1e-3, -2e-3, 5e-4, 1e-3, 2e-3])
    got = retime_owned(out, taus, rate, PAIRS, SENSORS, 1500.0, None)
    own_a, own_b = np.array([0, 1, 4]), np.array([2, 3])
    assert_allclose(got[own_a] - taus[own_a], emission_shift(
        rate[own_a], PAIRS[own_a, 0], [False] * 3, a, SENSORS, 1500.0), rtol=1e-12)
    assert_allclose(got[own_b] - taus[own_b], emission_shift(
        rate[own_b], PAIRS[own_b, 0], [False] * 2, b, SENSORS, 1500.0), rtol=1e-12)
    surf = retime_owned(out, taus, rate, PAIRS, SENSORS, 1500.0, 0.0)
    assert_allclose(surf[own_a] - taus[own_a], emission_shift(
        rate[own_a], PAIRS[own_a, 0], [False, True, True], a, SENSORS, 1500.0, 0.0), rtol=1e-12)
    assert_allclose(surf[own_b] - taus[own_b], emission_shift(
        rate[own_b], PAIRS[own_b, 0], [False, True], b, SENSORS, 1500.0, 0.0), rtol=1e-12)
    assert not np.allclose(surf, got)
    assert_allclose(retime_owned(out, taus, np.zeros(5), PAIRS, SENSORS, 1500.0, 0.0), taus,
                    rtol=0, atol=0)
