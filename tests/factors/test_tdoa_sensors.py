"""Tests of factors.tdoa.sensors: travel times with the sensors as variables, their Jacobians
(central differences), the time symmetry the sensor derivative rests on, and a solve that
recovers a sensor's survey error."""

import gtsam
import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.tdoa.gradient import travel_times
from factors.tdoa.sensors import sensor_offset_tdoa_factor, sensor_times
from factors.testing import assert_jacobians

P, C = gtsam.symbol("p", 0), gtsam.symbol("c", 0)
#: Five hydrophones 1-20 m above a sloping floor, 2-3 km apart (m, z up).
RANGE = np.array([[0, 0, -1590], [2500, 0, -1560], [0, 2600, -1575], [2400, 2500, -1530],
                  [1200, 1300, -1598.0]])
OFFSETS = [gtsam.symbol("o", q) for q in range(5)]
IMAGES = np.vstack([RANGE, RANGE * [1, 1, -1]])
PAIRS = np.array([(0, 1), (0, 2), (0, 3), (0, 4), (1, 2), (5, 6), (0, 7), (8, 4), (9, 1)])


@pytest.mark.parametrize("source", [[900.0, 700.0, -950.0], [-2000.0, 4000.0, -300.0]])
@pytest.mark.parametrize("g", [0.0, 0.0165])
def test_time_from_sensor_to_source_is_the_time_back(source, g):
    """The symmetry the sensor derivative rests on: T(p -> s) = T(s -> p) and the image's
    T(p -> s') = T(s -> p')."""
    p = np.array(source)
    t, _, _ = travel_times(p, IMAGES, 1500.0, g, 1200.0)
    for k, s in enumerate(IMAGES):
        back = (travel_times(s * [1, 1, -1], (p * [1, 1, -1])[None], 1500.0, g, 1200.0)
                if k >= 5 else travel_times(s, p[None], 1500.0, g, 1200.0))[0][0]
        assert_allclose(back, t[k], rtol=1e-12)


@pytest.mark.parametrize("speed", [[1500.0], [1510.0, 0.0165]])
def test_jacobians_match_central_differences(speed):
    rng = np.random.default_rng(3)
    p = np.array([900.0, 700.0, -950.0])
    off = rng.normal(0.0, 2.0, (5, 3))
    t, _, _, _ = sensor_times(p, IMAGES + np.vstack([off, off * [1, 1, -1]]), speed, 1200.0)
    taus = t[PAIRS[:, 0]] - t[PAIRS[:, 1]] + rng.normal(0, 1e-4, len(PAIRS))
    f = sensor_offset_tdoa_factor(gtsam.noiseModel.Isotropic.Sigma(len(PAIRS), 1e-5), P, C,
                                  OFFSETS, IMAGES, PAIRS, taus, n_real=5, d_ref=1200.0,
                                  weights=rng.uniform(0.5, 1.0, len(PAIRS)))
    v = gtsam.Values()
    v.insert(P, p + [3.0, -2.0, 5.0])
    v.insert(C, np.array(speed, float) + [4.0, 0.001][:len(speed)])
    for q in range(5):
        v.insert(OFFSETS[q], off[q] + rng.normal(0, 1.0, 3))
    assert_jacobians(f, v, delta=1e-4, rtol=1e-4, atol=1e-10)


def test_offset_absent_from_a_factor_that_does_not_use_its_sensor():
    pairs = np.array([(0, 1), (0, 2), (1, 2)])
    f = sensor_offset_tdoa_factor(gtsam.noiseModel.Isotropic.Sigma(3, 1e-5), P, C, OFFSETS,
                                  RANGE, pairs, np.zeros(3), n_real=5)
    assert list(f.keys()) == [P, C, *OFFSETS[:3]]


def test_zero_offsets_give_the_fixed_sensor_residuals():
    p = np.array([900.0, 700.0, -950.0])
    t, _, _ = travel_times(p, IMAGES, 1500.0, 0.0, 0.0)
    taus = t[PAIRS[:, 0]] - t[PAIRS[:, 1]] - 1e-4
    f = sensor_offset_tdoa_factor(gtsam.noiseModel.Isotropic.Sigma(len(PAIRS), 1.0), P, C,
                                  OFFSETS, IMAGES, PAIRS, taus, n_real=5)
    v = gtsam.Values()
    v.insert(P, p)
    v.insert(C, np.array([1500.0]))
    for k in OFFSETS:
        v.insert(k, np.zeros(3))
    assert_allclose(f.unwhitenedError(v), np.full(len(PAIRS), 1e-4), atol=1e-12)
