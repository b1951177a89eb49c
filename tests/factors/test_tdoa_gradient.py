"""Tests of factors.tdoa.gradient: travel times of a linear sound-speed profile, the factor's
Jacobians (central differences), and a solve the one-speed model cannot match."""

import gtsam
import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.tdoa.gradient import GradientTdoaModel, gradient_tdoa_factor, travel_times
from factors.testing import assert_jacobians
from fusion.simulate.whale_range.propagation import SoundSpeedProfile, segment_time

P, S = gtsam.symbol("p", 0), gtsam.symbol("c", 0)
#: Five hydrophones 1-20 m above a sloping floor at 1,500-1,600 m, 2-3 km apart (m, z up).
RANGE = np.array([[0, 0, -1590], [2500, 0, -1560], [0, 2600, -1575], [2400, 2500, -1530],
                  [1200, 1300, -1598.0]])
D_REF = 1570.0


def _pairs(n):
    return np.array([(i, j) for i in range(n) for j in range(i + 1, n)])


def _profile(c0=1475.0, g=0.0165):
    return SoundSpeedProfile("linear", {"c0": c0, "gradient": g}, max_depth_m=3000.0)


@pytest.mark.parametrize("source", [[900.0, 700.0, -950.0], [300.0, 2000.0, -1560.0],
                                    [1250.0, 1250.0, -1599.0], [-2000.0, 4000.0, -300.0]])
def test_direct_times_are_the_simulators_straight_ray_times(source):
    """Known answer: the simulator's quadrature of 1/c along the ray of a linear profile
    (including a source at a sensor's depth, the u -> 0 branch)."""
    prof = _profile()
    c_ref = 1475.0 + 0.0165 * D_REF
    t, _, _ = travel_times(source, RANGE, c_ref, 0.0165, D_REF)
    want = segment_time(np.array(source)[None], RANGE, prof)
    assert_allclose(t, want, rtol=1e-9)


def test_surface_image_time_is_the_reflected_ray_time():
    """An image sensor (z -> -z) stands for the ray bouncing off the surface: the sum of the
    two segments' times in the simulator's profile."""
    prof = _profile()
    src = np.array([700.0, 900.0, -800.0])
    image = RANGE * [1, 1, -1]
    t, _, _ = travel_times(src, image, 1475.0 + 0.0165 * D_REF, 0.0165, D_REF)
    for k, s in enumerate(RANGE):
        frac = -src[2] / (-src[2] - s[2])  # where the image ray crosses z = 0
        bounce = src + frac * (image[k] - src)
        bounce[2] = 0.0
        want = segment_time(src, bounce, prof) + segment_time(bounce, s, prof)
        assert_allclose(t[k], want, rtol=1e-9)


def test_no_gradient_is_the_constant_speed_model():
    src = np.array([900.0, 700.0, -950.0])
    t, _, _ = travel_times(src, RANGE, 1500.0, 0.0, D_REF)
    assert_allclose(t, np.linalg.norm(src - RANGE, axis=1) / 1500.0, rtol=1e-14)


def _values(p, speed=None):
    v = gtsam.Values()
    v.insert(P, gtsam.Point3(*p))
    if speed is not None:
        v.insert(S, np.asarray(speed, float))
    return v


@pytest.mark.parametrize("image", [False, True])
@pytest.mark.parametrize("g", [0.0165, 1e-9, -0.03])
def test_jacobians_match_central_differences(image, g):
    rng = np.random.default_rng(3)
    sensors = np.vstack([RANGE, RANGE[:2] * [1, 1, -1]]) if image else RANGE
    pairs = _pairs(len(sensors))
    for src in ([900.0, 700.0, -950.0], [1250.0, 1250.0, -1590.0], [3000.0, -500.0, -200.0]):
        taus = rng.normal(0, 1e-3, len(pairs))
        w = rng.uniform(0.2, 1.0, len(pairs))
        f = gradient_tdoa_factor(gtsam.noiseModel.Isotropic.Sigma(len(pairs), 1e-5), P,
                                 sensors, pairs, taus, d_ref=D_REF, weights=w, speed_key=S)
        # steps: 1 mm, 1 mm/s; g's step 1e-7 1/s (relative Jacobian scale)
        assert_jacobians(f, _values(src, [1500.0, g]), delta=1e-4, rtol=1e-5, atol=1e-9)
        fixed = gradient_tdoa_factor(gtsam.noiseModel.Isotropic.Sigma(len(pairs), 1e-5), P,
                                     sensors, pairs, taus, d_ref=D_REF, speed=[1500.0, g])
        assert_jacobians(fixed, _values(src), delta=1e-4, rtol=1e-5, atol=1e-9)


def test_gradient_jacobian_by_small_steps():
    """The g column alone, with a step suited to g (1e-7 1/s)."""
    pairs = _pairs(5)
    model = GradientTdoaModel.build(RANGE, pairs, np.zeros(10), D_REF)
    p = np.array([900.0, 700.0, -950.0])
    sp = np.array([1500.0, 0.016])
    _, _, h_s = model.residual(p, sp, jacobian=True)
    e = 1e-7
    num = (model.residual(p, sp + [0, e])[0] - model.residual(p, sp - [0, e])[0]) / (2 * e)
    assert_allclose(h_s[:, 1], num, rtol=1e-6, atol=1e-12)


def _solve(taus, speed_key_prior=None, fixed=None):
    pairs = _pairs(5)
    graph = gtsam.NonlinearFactorGraph()
    v = gtsam.Values()
    v.insert(P, gtsam.Point3(1000.0, 1000.0, -1200.0))
    noise = gtsam.noiseModel.Isotropic.Sigma(10, 1e-7)
    if fixed is not None:
        graph.add(gradient_tdoa_factor(noise, P, RANGE, pairs, taus, d_ref=D_REF, speed=fixed))
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(1e-14)
    params.setAbsoluteErrorTol(1e-30)
    return np.asarray(gtsam.LevenbergMarquardtOptimizer(graph, v, params).optimize()
                      .atPoint3(P))


def test_a_linear_profile_is_matched_by_its_model_not_by_one_speed():
    """Delays of the simulator's linear profile: the gradient model at the true profile puts the
    source back (< 1 cm); the best single speed (the profile's mean along the paths) does not."""
    prof = _profile()
    src = np.array([900.0, 700.0, -950.0])
    pairs = _pairs(5)
    t = segment_time(src[None], RANGE, prof)
    taus = t[pairs[:, 0]] - t[pairs[:, 1]]
    p = _solve(taus, fixed=[1475.0 + 0.0165 * D_REF, 0.0165])
    assert np.linalg.norm(p - src) < 0.01
    c_eff = float(np.mean(np.linalg.norm(src - RANGE, axis=1) / t))
    q = _solve(taus, fixed=[c_eff, 0.0])
    assert np.linalg.norm(q - src) > 0.5  # 0.91 m


def test_bad_inputs():
    pairs = _pairs(5)
    noise = gtsam.noiseModel.Isotropic.Sigma(10, 1e-5)
    with pytest.raises(ValueError, match="exactly one"):
        gradient_tdoa_factor(noise, P, RANGE, pairs, np.zeros(10), d_ref=D_REF)
    with pytest.raises(ValueError, match="c_ref"):
        gradient_tdoa_factor(noise, P, RANGE, pairs, np.zeros(10), d_ref=D_REF, speed=[-1, 0])
    with pytest.raises(ValueError, match="dimension"):
        gradient_tdoa_factor(gtsam.noiseModel.Isotropic.Sigma(3, 1e-5), P, RANGE, pairs,
                             np.zeros(10), d_ref=D_REF, speed=[1500, 0])
