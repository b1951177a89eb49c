"""Tests of factors.tdoa: TDOA factors (vector, weighted) and the one-source solve."""

import logging

import gtsam
import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.tdoa import (
    predicted_tdoas,
    solve_source,
    tdoa_vector_factor,
    weighted_tdoa_vector_factor,
)
from factors.testing import analytic_jacobians, numerical_jacobians

C = 1500.0  # m/s
P, S, B = gtsam.symbol("p", 0), gtsam.symbol("c", 0), gtsam.symbol("b", 0)
DELTA = 1e-6  # central-difference step, m (and m/s, s)
EPS = np.finfo(float).eps

#: A 1 km array with 1 km of vertical extent (m).
KM = np.array([[0, 0, 0], [1000, 0, -800], [0, 1000, -800], [1000, 1000, 0], [500, 500, -1000.0]])
#: The XAV large array (shared/realdata/xav_large_array/array.json), a 1.7 m frame, c = 1484 m/s.
XAV = np.array([[-0.858, -0.86, -0.671], [-0.858, -0.86, 0.479], [0.858, -0.86, -0.671],
                [0.028, 0.0, -0.002], [-0.858, 0.86, -0.671], [0.858, 0.86, 0.671]])
C_XAV = 1484.0


def _all_pairs(n):
    return np.array([(i, j) for i in range(n) for j in range(i + 1, n)])


def _values(p, speed=None, clocks=None):
    v = gtsam.Values()
    v.insert(P, gtsam.Point3(*p))
    if speed is not None:
        v.insert(S, np.array([speed]))
    if clocks is not None:
        v.insert(B, np.asarray(clocks, float))
    return v


def _unit_sphere(rng):
    d = rng.normal(size=3)
    return d / np.linalg.norm(d)


def _geometries(rng):
    """(label, sensors (n, 3) m, source (3,) m, c m/s): km arrays, XAV, near a sensor, planar."""
    out = []
    for _ in range(4):  # the km array, sources inside and up to 3 km outside
        out.append(("km inside", KM, rng.uniform(KM.min(0), KM.max(0)), C))
        out.append(("km outside", KM, KM.mean(0) + rng.uniform(1500, 3000) * _unit_sphere(rng), C))
    for _ in range(4):  # random kilometre arrays of 6-8 sensors
        s = rng.uniform(-1000, 1000, size=(int(rng.integers(6, 9)), 3))
        out.append(("random km", s, rng.uniform(-2000, 2000, size=3), rng.uniform(1450, 1550)))
    for _ in range(6):  # 1.7 m array, sources 1-2 m from its centre
        out.append(("xav", XAV, XAV.mean(0) + rng.uniform(1, 2) * _unit_sphere(rng), C_XAV))
    for k in (0, 3, 5):  # 1 cm from a sensor
        out.append(("near sensor", XAV, XAV[k] + 0.01 * _unit_sphere(rng), C_XAV))
        out.append(("near km sensor", KM, KM[k % 5] + 0.01 * _unit_sphere(rng), C))
    for _ in range(3):  # planar array (z = 0) and a source in its plane
        s = np.column_stack([rng.uniform(-100, 100, size=(5, 2)), np.zeros(5)])
        out.append(("planar", s, np.array([*rng.uniform(-150, 150, size=2), 0.0]), C))
    return out


def _mismatch(factor, values, t_scale, *, delta=DELTA):
    """Largest |analytic - central difference| / (atol + rtol |central difference|) over the
    factor's Jacobians (<= 1: they agree as ``assert_allclose`` with these tolerances says;
    NaN when either holds a NaN), rtol 1e-5 and atol at the round-off floor of the differences.

    `t_scale` bounds the magnitude of the terms summed in the error (e.g. d/c, s): their
    round-off, about eps * t_scale, divided by the step is what a central difference can resolve.
    """
    atol = 100 * EPS * t_scale / delta
    num = numerical_jacobians(factor, values, delta=delta)
    ana = analytic_jacobians(factor, values)
    return float(np.max([np.max(np.abs(ha - hn) / (atol + 1e-5 * np.abs(hn)), initial=0.0)
                         for ha, hn in zip(ana, num, strict=True)]))


def _one(noise, key, s, pair, tau, **kw):
    """The factor of one TDOA: a vector factor of one pair."""
    return tdoa_vector_factor(noise, key, s, [pair], [tau], **kw)


def _noisy_taus(rng, p, s, pairs, c, sigma):
    return predicted_tdoas(p, s, pairs, c=c) + rng.normal(0.0, sigma, size=len(pairs))


def test_jacobians_one_pair_and_vector_many_geometries():
    """One-pair (every pair) and all-pair vector factor Jacobians equal central differences, fixed speed."""
    rng = np.random.default_rng(11)
    found = []
    for label, s, p, c in _geometries(rng):
        pairs = _all_pairs(len(s))
        taus = _noisy_taus(rng, p, s, pairs, c, 1e-4)
        t_scale = np.linalg.norm(p - s, axis=1).max() / c + 1e-3
        noise = gtsam.noiseModel.Isotropic.Sigma(len(pairs), 1e-5)
        f = tdoa_vector_factor(noise, P, s, pairs, taus, c=c)
        found.append((label, "vector", _mismatch(f, _values(p), t_scale)))
        for (i, j), tau in zip(pairs, taus, strict=True):
            f = _one(gtsam.noiseModel.Isotropic.Sigma(1, 1e-5), P, s, (i, j), tau, c=c)
            found.append((label, (i, j), _mismatch(f, _values(p), t_scale)))
    assert all(m <= 1.0 for *_, m in found), [x for x in found if not x[-1] <= 1.0]


def test_jacobians_with_unknown_speed_and_clocks():
    """Jacobians by position, sound speed and clock offsets equal central differences."""
    rng = np.random.default_rng(12)
    found = []
    for label, s, p, c in _geometries(rng):
        n = len(s)
        pairs = _all_pairs(n)
        taus = _noisy_taus(rng, p, s, pairs, c, 1e-4)
        clocks = rng.normal(0.0, 1e-3, size=n)
        t_scale = np.linalg.norm(p - s, axis=1).max() / c + 1e-2
        noise = gtsam.noiseModel.Isotropic.Sigma(len(pairs), 1e-5)
        for speed_key, clock_key in ((S, None), (None, B), (S, B)):
            v = _values(p, c if speed_key else None, clocks if clock_key else None)
            kw = {"c": None if speed_key else c, "speed_key": speed_key, "clock_key": clock_key}
            k = int(rng.integers(len(pairs)))
            f = _one(gtsam.noiseModel.Unit.Create(1), P, s, pairs[k], taus[k], **kw)
            key = (label, speed_key is not None, clock_key is not None)
            found.append((key, _mismatch(tdoa_vector_factor(noise, P, s, pairs, taus, **kw), v,
                                         t_scale)))
            found.append((key, _mismatch(f, v, t_scale)))
    assert all(m <= 1.0 for _, m in found), [x for x in found if not x[1] <= 1.0]


def test_speed_and_clock_jacobians_have_their_closed_form():
    """dr/dc = -(d_i - d_j)/c^2 and dr/db = +1 at i, -1 at j (against a direct formula)."""
    rng = np.random.default_rng(13)
    s = XAV
    pairs = _all_pairs(6)
    p = XAV.mean(0) + 1.5 * _unit_sphere(rng)
    f = tdoa_vector_factor(gtsam.noiseModel.Unit.Create(15), P, s, pairs, np.zeros(15),
                           speed_key=S, clock_key=B)
    h_p, h_c, h_b = analytic_jacobians(f, _values(p, C_XAV, np.zeros(6)))
    d = np.linalg.norm(p - s, axis=1)
    u = (p - s) / d[:, None]
    assert_allclose(h_p, (u[pairs[:, 0]] - u[pairs[:, 1]]) / C_XAV, rtol=1e-12)
    assert_allclose(h_c[:, 0], -(d[pairs[:, 0]] - d[pairs[:, 1]]) / C_XAV**2, rtol=1e-12)
    expect_b = np.zeros((15, 6))
    expect_b[np.arange(15), pairs[:, 0]] = 1.0
    expect_b[np.arange(15), pairs[:, 1]] = -1.0
    assert_allclose(h_b, expect_b, atol=0)


def test_jacobians_weighted_and_robust():
    """Weighted (weights in [-0.2, 1]) and Huber-robust weighted Jacobians equal central differences."""
    rng = np.random.default_rng(14)
    huber = gtsam.noiseModel.mEstimator.Huber.Create(1.345)
    found = []
    for label, s, p, c in _geometries(rng):
        n = len(s)
        pairs = _all_pairs(n)
        m = len(pairs)
        sigmas = rng.uniform(5e-6, 5e-5, size=m)
        taus = _noisy_taus(rng, p, s, pairs, c, 5e-5)  # residuals of 0-10 sigma: both Huber regions
        w = rng.uniform(-0.2, 1.0, size=m)
        clocks = rng.normal(0.0, 1e-3, size=n)
        t_scale = (np.linalg.norm(p - s, axis=1).max() / c + 1e-2) / sigmas.min()
        noise = gtsam.noiseModel.Diagonal.Sigmas(sigmas)
        for robust in (None, huber):
            f = weighted_tdoa_vector_factor(noise, P, s, pairs, taus, w, c=c, robust=robust)
            found.append((label, _mismatch(f, _values(p), t_scale)))
            f = weighted_tdoa_vector_factor(noise, P, s, pairs, taus, w, speed_key=S, robust=robust)
            found.append((label, _mismatch(f, _values(p, c), t_scale)))
        f = weighted_tdoa_vector_factor(noise, P, s, pairs, taus, w, speed_key=S, clock_key=B)
        found.append((label, _mismatch(f, _values(p, c, clocks), t_scale)))
        if t_scale < 1e4:  # robust with clocks: a clock step must be << sigma (Huber's kink)
            f = weighted_tdoa_vector_factor(noise, P, s, pairs, taus, w, speed_key=S, clock_key=B,
                                            robust=huber)
            found.append((label, _mismatch(f, _values(p, c, clocks), t_scale, delta=1e-9)))
    assert all(m <= 1.0 for _, m in found), [x for x in found if not x[1] <= 1.0]


def test_zero_error_at_truth_every_form():
    """With true TDOAs (clock offsets included) every form has zero error at the true state."""
    rng = np.random.default_rng(15)
    for _label, s, p, c in _geometries(rng):
        n, pairs = len(s), _all_pairs(len(s))
        clocks = rng.normal(0.0, 1e-3, size=n)
        taus = predicted_tdoas(p, s, pairs, c=c, clock_offsets=clocks)
        t_scale = np.linalg.norm(p - s, axis=1).max() / c + 1e-2
        unit = gtsam.noiseModel.Unit.Create(len(pairs))
        v = _values(p, c, clocks)
        f = tdoa_vector_factor(unit, P, s, pairs, taus, speed_key=S, clock_key=B)
        assert_allclose(f.unwhitenedError(v), 0.0, atol=10 * EPS * t_scale)
        f = _one(gtsam.noiseModel.Unit.Create(1), P, s, pairs[0], taus[0], c=c, clock_key=B)
        assert_allclose(f.unwhitenedError(v), 0.0, atol=10 * EPS * t_scale)
        w = np.ones(len(pairs))
        f = weighted_tdoa_vector_factor(unit, P, s, pairs, taus, w, speed_key=S, clock_key=B,
                                        robust=gtsam.noiseModel.mEstimator.Huber.Create(1.0))
        assert_allclose(f.unwhitenedError(v), 0.0, atol=10 * EPS * t_scale)


def test_vector_error_equals_stacked_one_pair_errors_and_direct_formula():
    """The vector factor's error is the stack of one-pair errors and of a direct numpy formula."""
    rng = np.random.default_rng(16)
    for _label, s, p, c in _geometries(rng):
        pairs = _all_pairs(len(s))
        taus = _noisy_taus(rng, p, s, pairs, c, 1e-4)
        v = _values(p + rng.normal(size=3))
        sigmas = rng.uniform(1e-5, 1e-4, size=len(pairs))
        vec = tdoa_vector_factor(gtsam.noiseModel.Diagonal.Sigmas(sigmas), P, s, pairs, taus, c=c)
        stack = [_one(gtsam.noiseModel.Isotropic.Sigma(1, sg), P, s, pq, t, c=c)
                 for pq, t, sg in zip(pairs, taus, sigmas, strict=True)]
        e = vec.unwhitenedError(v)
        assert_allclose(e, np.concatenate([f.unwhitenedError(v) for f in stack]), rtol=0, atol=0)
        q = np.asarray(v.atPoint3(P))
        direct = [(np.linalg.norm(q - s[i]) - np.linalg.norm(q - s[j])) / c - t
                  for (i, j), t in zip(pairs, taus, strict=True)]
        assert_allclose(e, direct, rtol=1e-9, atol=1e-15)
        assert_allclose(vec.error(v), sum(f.error(v) for f in stack), rtol=1e-12)


def test_weighted_with_unit_weights_equals_unweighted_whitened():
    """All weights 1: error and linearization equal the unweighted factor's whitened ones."""
    rng = np.random.default_rng(17)
    for _label, s, p, c in _geometries(rng)[::3]:
        pairs = _all_pairs(len(s))
        taus = _noisy_taus(rng, p, s, pairs, c, 1e-4)
        noise = gtsam.noiseModel.Diagonal.Sigmas(rng.uniform(1e-5, 1e-4, size=len(pairs)))
        plain = tdoa_vector_factor(noise, P, s, pairs, taus, speed_key=S)
        weighted = weighted_tdoa_vector_factor(noise, P, s, pairs, taus, np.ones(len(pairs)),
                                               speed_key=S)
        v = _values(p + rng.normal(size=3), c)
        assert_allclose(weighted.unwhitenedError(v), plain.whitenedError(v), rtol=1e-12)
        assert_allclose(weighted.error(v), plain.error(v), rtol=1e-12)
        a_w, b_w = weighted.linearize(v).jacobian()
        a_p, b_p = plain.linearize(v).jacobian()
        assert_allclose(a_w, a_p, rtol=1e-12)
        assert_allclose(b_w, b_p, rtol=1e-12)


def test_weights_are_read_live():
    """Updating the weight array in place changes the cost to sum_k w_k e_k^2 / 2 (w < 0 as 0)."""
    rng = np.random.default_rng(18)
    pairs = _all_pairs(5)
    taus = _noisy_taus(rng, [300, 600, -400], KM, pairs, C, 1e-3)
    noise = gtsam.noiseModel.Isotropic.Sigma(10, 1e-4)
    w = np.ones(10)
    f = weighted_tdoa_vector_factor(noise, P, KM, pairs, taus, w, c=C)
    e = tdoa_vector_factor(noise, P, KM, pairs, taus, c=C).whitenedError(_values([300, 600, -400]))
    for _ in range(3):
        w[:] = rng.uniform(-0.5, 1.0, size=10)
        assert_allclose(f.error(_values([300, 600, -400])), 0.5 * np.sum(np.maximum(w, 0) * e**2),
                        rtol=1e-12)


def test_fixed_speed_weighted_error_is_the_models_arithmetic():
    """At a known speed without a robust loss the weighted factor returns, bit for bit, the
    model's residual and Jacobian scaled by sqrt(w) / sigma, also after in-place weight updates."""
    from factors.tdoa.model import TdoaModel

    rng = np.random.default_rng(24)
    for _, s, p, c in _geometries(rng):
        pairs = _all_pairs(len(s))
        m = len(pairs)
        sigmas = rng.uniform(5e-6, 5e-5, size=m)
        taus = _noisy_taus(rng, p, s, pairs, c, 5e-5)
        w = rng.uniform(-0.2, 1.0, size=m)
        f = weighted_tdoa_vector_factor(gtsam.noiseModel.Diagonal.Sigmas(sigmas), P, s, pairs,
                                        taus, w, c=c)
        model = TdoaModel.build(s, pairs, taus)
        for k in range(3):
            if k:
                w[:] = rng.uniform(-0.2, 1.0, size=m)
            x = p + rng.normal(size=3)
            r, h_p, _ = model.residual(np.asarray(gtsam.Point3(*x)), c, jacobian=True)
            scale = np.sqrt(np.maximum(w, 0.0))
            inv_sigma = np.diag(gtsam.noiseModel.Diagonal.Sigmas(sigmas).R())
            assert np.array_equal(f.unwhitenedError(_values(x)), scale * (r * inv_sigma))
            a, _ = f.linearize(_values(x)).jacobian()
            assert np.array_equal(a, (scale * inv_sigma)[:, None] * h_p)


def test_zero_weight_removes_a_tdoa():
    """Weight 0 on a corrupted TDOA: its residual is 0 and the optimum equals the fit without it."""
    rng = np.random.default_rng(19)
    pairs = _all_pairs(5)
    truth = np.array([300.0, 600.0, -400.0])
    taus = _noisy_taus(rng, truth, KM, pairs, C, 2e-5)
    taus[4] += 5e-3  # a TDOA of another source
    w = np.ones(10)
    w[4] = 0.0
    f = weighted_tdoa_vector_factor(gtsam.noiseModel.Isotropic.Sigma(10, 2e-5), P, KM, pairs, taus,
                                    w, c=C)
    assert f.unwhitenedError(_values(truth + 10.0))[4] == 0.0
    start = truth + [200.0, -150.0, 100.0]
    p_w, _, _ = solve_source(KM, pairs, taus, 2e-5, c=C, initial=start, weights=w)
    keep = np.arange(10) != 4
    p_k, _, _ = solve_source(KM, pairs[keep], taus[keep], 2e-5, c=C, initial=start)
    assert_allclose(p_w, p_k, atol=1e-9)
    p_all, _, _ = solve_source(KM, pairs, taus, 2e-5, c=C, initial=start)
    assert np.linalg.norm(p_all - truth) > 10 * np.linalg.norm(p_w - truth)  # the weight mattered


def _starts(rng, truth, sensors):
    size = np.ptp(sensors, axis=0).max()
    return [sensors.mean(0), truth + 0.3 * size * _unit_sphere(rng)]


def test_converges_km_array_from_poor_starts():
    """5-sensor km array: from the centroid and from 30 % of the array size off, to 1e-6 m."""
    rng = np.random.default_rng(20)
    pairs = _all_pairs(5)
    for _ in range(12):
        truth = rng.uniform(KM.min(0), KM.max(0))
        taus = predicted_tdoas(truth, KM, pairs, c=C)
        for start in _starts(rng, truth, KM):
            p, cov, info = solve_source(KM, pairs, taus, 1e-5, c=C, initial=start)
            assert_allclose(p, truth, atol=1e-6)
            assert info.observable and info.residual_rms_s < 1e-12
            assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_converges_xav_array_from_poor_starts():
    """6-sensor 1.7 m array, sources 1-2 m away: from the centroid and 30 % off, to 1e-6 m."""
    rng = np.random.default_rng(21)
    pairs = _all_pairs(6)
    for _ in range(12):
        truth = XAV.mean(0) + rng.uniform(1.0, 2.0) * _unit_sphere(rng)
        taus = predicted_tdoas(truth, XAV, pairs, c=C_XAV)
        for start in _starts(rng, truth, XAV):
            p, _, info = solve_source(XAV, pairs, taus, 2e-5, c=C_XAV, initial=start)
            assert_allclose(p, truth, atol=1e-6)
            assert info.observable


def test_covariance_is_inverse_fisher_information():
    """Marginals covariance = (J^T Sigma^-1 J)^-1 with J from a direct formula at the solution."""
    rng = np.random.default_rng(22)
    pairs = _all_pairs(5)
    sigmas = rng.uniform(1e-5, 5e-5, size=10)
    truth = np.array([400.0, 300.0, -500.0])
    taus = predicted_tdoas(truth, KM, pairs, c=C)
    p, cov, info = solve_source(KM, pairs, taus, sigmas, c=C, initial=KM.mean(0))
    u = (p - KM) / np.linalg.norm(p - KM, axis=1)[:, None]
    jac = (u[pairs[:, 0]] - u[pairs[:, 1]]) / C
    fisher = jac.T @ (jac / sigmas[:, None] ** 2)
    assert_allclose(cov, np.linalg.inv(fisher), rtol=1e-8)
    assert_allclose(info.information, fisher, rtol=1e-8)
    assert_allclose(info.min_eigenvalue, np.linalg.eigvalsh(fisher)[0], rtol=1e-8)


def test_robust_huber_resists_one_corrupted_tdoa():
    """Huber per TDOA: one 100-sigma TDOA barely moves the fit (unlike least squares), and the
    optimum equals that of one-pair factors with GTSAM's own Robust(Huber) noise models."""
    rng = np.random.default_rng(23)
    pairs = _all_pairs(5)
    sigma = 2e-5
    truth = np.array([350.0, 650.0, -450.0])
    taus = _noisy_taus(rng, truth, KM, pairs, C, sigma)
    taus[2] += 100 * sigma
    huber = gtsam.noiseModel.mEstimator.Huber.Create(1.345)
    start = KM.mean(0)
    p_r, _, info = solve_source(KM, pairs, taus, sigma, c=C, initial=start, robust=huber)
    p_ls, _, _ = solve_source(KM, pairs, taus, sigma, c=C, initial=start)
    p_clean, _, _ = solve_source(KM, np.delete(pairs, 2, 0), np.delete(taus, 2), sigma, c=C,
                                 initial=start)
    assert np.linalg.norm(p_r - truth) < 0.25  # CRB here: about 0.06 m
    assert np.linalg.norm(p_r - p_clean) < 0.5 * np.linalg.norm(p_ls - p_clean)
    res = _optimize(_one_pair_graph(KM, pairs, taus, sigma, C, huber), start)
    assert_allclose(p_r, res.atPoint3(P), atol=1e-6)
    assert info.observable


def test_estimates_sound_speed():
    """Unknown speed (6 sensors): noise-free TDOAs at c = 1500 from a 1450 m/s start recover both."""
    s = np.vstack([KM, [[200.0, 800.0, -300.0]]])
    pairs = _all_pairs(6)
    rng = np.random.default_rng(24)
    for _ in range(5):
        truth = rng.uniform(KM.min(0), KM.max(0))
        taus = predicted_tdoas(truth, s, pairs, c=C)
        p, cov, info = solve_source(s, pairs, taus, 1e-5, c=1450.0, initial=s.mean(0),
                                    estimate_speed=True)
        assert_allclose(p, truth, atol=1e-6)
        assert_allclose(info.speed, C, atol=1e-6)
        assert info.observable and 0 < info.speed_std < 1.0
        fixed_cov = solve_source(s, pairs, taus, 1e-5, c=C, initial=truth)[1]
        assert np.trace(cov) > np.trace(fixed_cov)  # an unknown speed costs position accuracy


def test_clock_offsets_calibrated_from_several_sources():
    """Six sources share a clock variable (offset of sensor 0 fixed by a prior): all recovered."""
    rng = np.random.default_rng(25)
    pairs = _all_pairs(5)
    clocks = np.concatenate([[0.0], rng.normal(0.0, 2e-3, size=4)])
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    sources = [rng.uniform(KM.min(0), KM.max(0)) for _ in range(6)]
    for k, truth in enumerate(sources):
        taus = predicted_tdoas(truth, KM, pairs, c=C, clock_offsets=clocks)
        key = gtsam.symbol("x", k)
        graph.add(tdoa_vector_factor(gtsam.noiseModel.Isotropic.Sigma(10, 1e-5), key, KM, pairs,
                                     taus, c=C, clock_key=B))
        values.insert(key, gtsam.Point3(*(truth + 300.0 * _unit_sphere(rng))))
    graph.add(gtsam.PriorFactorVector(B, np.zeros(5),
                                      gtsam.noiseModel.Diagonal.Sigmas([1e-9, 1.0, 1.0, 1.0, 1.0])))
    values.insert(B, np.zeros(5))
    res = gtsam.LevenbergMarquardtOptimizer(graph, values, _lm_params()).optimize()
    assert_allclose(res.atVector(B), clocks, atol=1e-10)
    for k, truth in enumerate(sources):
        assert_allclose(res.atPoint3(gtsam.symbol("x", k)), truth, atol=1e-5)


def test_unobservable_geometry_is_reported_not_raised(caplog):
    """Planar array, source in its plane: the side of the plane is unfixed; info says so, cov NaN."""
    rng = np.random.default_rng(26)
    s = np.column_stack([rng.uniform(-100, 100, size=(5, 2)), np.zeros(5)])
    pairs = _all_pairs(5)
    truth = np.array([30.0, -40.0, 0.0])
    taus = predicted_tdoas(truth, s, pairs, c=C)
    with caplog.at_level(logging.WARNING, logger="factors.tdoa"):
        p, cov, info = solve_source(s, pairs, taus, 1e-5, c=C, initial=[0.0, 0.0, 0.0])
    assert not info.observable and "not observable" in caplog.text
    assert abs(info.weakest_direction[2]) > 0.999
    assert info.condition_number > 1e8
    assert np.all(np.isnan(cov))
    assert_allclose(p, truth, atol=1e-6)
    p, cov, info = solve_source(s, pairs, taus, 1e-5, c=C, initial=[10.0, 10.0, 0.0],
                                estimate_speed=True)
    assert not info.observable and np.isnan(info.speed_std)


def test_too_few_tdoas_raise():
    """Fewer independent TDOAs (of positive weight) than unknowns raise ValueError."""
    s = KM[:4]
    with pytest.raises(ValueError, match="3 unknowns need at least 3 independent TDOAs, got 2"):
        solve_source(s, [[0, 1], [1, 2], [0, 2]], [0.0, 0.0, 0.0], 1e-5, c=C, initial=[0, 0, 0])
    with pytest.raises(ValueError, match="4 unknowns need at least 4 independent TDOAs, got 3"):
        solve_source(s, _all_pairs(4), np.zeros(6), 1e-5, c=C, initial=[0, 0, 0],
                     estimate_speed=True)
    with pytest.raises(ValueError, match="got 2"):
        solve_source(s, [[0, 1], [0, 2], [0, 3]], np.zeros(3), 1e-5, c=C, initial=[0, 0, 0],
                     weights=[1.0, 0.0, 1.0])


def test_bad_input():
    """Malformed options raise ValueError naming the problem."""
    pairs, taus = _all_pairs(5), np.zeros(10)
    unit10 = gtsam.noiseModel.Unit.Create(10)
    with pytest.raises(ValueError, match="exactly one of c"):
        tdoa_vector_factor(unit10, P, KM, pairs, taus)
    with pytest.raises(ValueError, match="exactly one of c"):
        tdoa_vector_factor(unit10, P, KM, pairs, taus, c=C, speed_key=S)
    with pytest.raises(ValueError, match="dimension"):
        tdoa_vector_factor(gtsam.noiseModel.Unit.Create(3), P, KM, pairs, taus, c=C)
    with pytest.raises(ValueError, match="keys must differ"):
        tdoa_vector_factor(unit10, P, KM, pairs, taus, speed_key=P)
    with pytest.raises(ValueError, match=r"shape \(m, 2\)"):
        _one(gtsam.noiseModel.Unit.Create(1), P, KM, (0, 1, 2), 0.0, c=C)
    with pytest.raises(ValueError, match="positive"):
        _one(gtsam.noiseModel.Unit.Create(1), P, KM, (0, 1), 0.0, c=0.0)
    with pytest.raises(ValueError, match="float64"):
        weighted_tdoa_vector_factor(unit10, P, KM, pairs, taus, [1.0] * 10, c=C)
    with pytest.raises(ValueError, match=r"shape \(10,\)"):
        weighted_tdoa_vector_factor(unit10, P, KM, pairs, taus, np.ones(9), c=C)
    robust = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(1.0), unit10)
    with pytest.raises(ValueError, match="robust="):
        weighted_tdoa_vector_factor(robust, P, KM, pairs, taus, np.ones(10), c=C)
    cov = np.eye(10) + 0.1
    with pytest.raises(ValueError, match="diagonal"):
        weighted_tdoa_vector_factor(gtsam.noiseModel.Gaussian.Covariance(cov), P, KM, pairs, taus,
                                    np.ones(10), c=C)
    with pytest.raises(ValueError, match="sigmas"):
        solve_source(KM, pairs, taus, 0.0, c=C, initial=[0, 0, 0])
    with pytest.raises(ValueError, match="initial"):
        solve_source(KM, pairs, taus, 1e-5, c=C, initial=[0, 0])
    with pytest.raises(ValueError, match="weights"):
        solve_source(KM, pairs, taus, 1e-5, c=C, initial=[0, 0, 0], weights=np.ones(3))
    f = tdoa_vector_factor(unit10, P, KM, pairs, taus, c=C, clock_key=B)
    with pytest.raises(ValueError, match="offsets for 5 sensors"):
        f.unwhitenedError(_values([0, 0, 0], clocks=np.zeros(4)))


def _lm_params():
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(1e-12)
    params.setAbsoluteErrorTol(1e-20)
    return params


def _optimize(graph, start):
    values = gtsam.Values()
    values.insert(P, gtsam.Point3(*start))
    return gtsam.LevenbergMarquardtOptimizer(graph, values, _lm_params()).optimize()


def _one_pair_graph(s, pairs, taus, sigma, c, robust=None):
    """One one-pair factor per TDOA, each with its own (optionally robust) 1-D noise."""
    graph = gtsam.NonlinearFactorGraph()
    noise = gtsam.noiseModel.Isotropic.Sigma(1, sigma)
    if robust is not None:
        noise = gtsam.noiseModel.Robust.Create(robust, noise)
    for pq, tau in zip(pairs, taus, strict=True):
        graph.add(_one(noise, P, s, pq, tau, c=c))
    return graph
