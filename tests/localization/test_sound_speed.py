"""A recording's sound speed estimated on one factor graph from its fixes."""

import numpy as np
import pytest
from scipy.optimize import least_squares, minimize_scalar

from factors.tdoa.model import predicted_tdoas
from fusion.localization.retime import emission_shift
from fusion.localization.sound_speed import (
    FixTdoas,
    estimate_sound_speed,
    path_sensors,
    refit_fix,
)

SENSORS = np.array([[0.0, 0, -1500], [3200, 150, -1610], [1500, 2900, -1550],
                    [-1800, 1400, -1480], [400, -2500, -1590], [2600, -1800, -1530]])
SOURCES = np.array([[800.0, 600, -900], [1200, 1500, -700], [-300, 400, -1100],
                    [2000, -500, -800], [500, 2000, -600]])
ALL_PAIRS = np.array([(i, j) for i in range(6) for j in range(i + 1, 6)])


def _fixes(c_true, c_start, noise_s=0.0, seed=0):
    """Fixes whose TDOAs hold at `c_true`, each started from its solution at `c_start`."""
    rng = np.random.default_rng(seed)
    out = []
    for p in SOURCES:
        taus = predicted_tdoas(p, SENSORS, ALL_PAIRS, c=c_true) + rng.normal(0, noise_s, 15)
        start = least_squares(lambda q, t=taus: (predicted_tdoas(q, SENSORS, ALL_PAIRS, c=c_start)
                                                 - t) * 1e6, p).x
        out.append(FixTdoas(SENSORS, ALL_PAIRS, taus, np.full(15, max(noise_s, 1e-7)),
                            np.ones(15), start))
    return out


def test_speed_and_fixes_recovered_from_a_wrong_start():
    fixes = _fixes(1487.0, 1500.0)
    assert np.linalg.norm(fixes[0].position - SOURCES[0]) > 3.0  # the wrong speed moves fixes
    est = estimate_sound_speed(fixes, nominal_mps=1500.0)
    assert est.speed_mps == pytest.approx(1487.0, abs=1e-4)
    np.testing.assert_allclose(est.positions, SOURCES, atol=1e-3)
    assert est.n_fixes == 5 and est.n_tdoas == 75


def test_matches_an_independent_least_squares_with_noise():
    fixes = _fixes(1491.0, 1500.0, noise_s=2e-7, seed=3)
    est = estimate_sound_speed(fixes, nominal_mps=1500.0, prior_sigma_mps=1e6)

    def res(x):
        c = x[-1]
        return np.concatenate([(predicted_tdoas(x[3 * k:3 * k + 3], SENSORS, ALL_PAIRS, c=c)
                                - f.taus) / f.sigmas for k, f in enumerate(fixes)])

    x0 = np.concatenate([*[f.position for f in fixes], [1500.0]])
    ref = least_squares(res, x0, x_scale=np.r_[np.full(15, 1.0), 1.0], xtol=1e-14, ftol=1e-14)
    assert est.speed_mps == pytest.approx(ref.x[-1], abs=1e-3)
    np.testing.assert_allclose(est.positions.ravel(), ref.x[:-1], atol=2e-3)
    # the speed's sigma from the marginal covers the error and is no larger than a metre a second
    assert abs(est.speed_mps - 1491.0) < 4 * est.sigma_mps < 1.0


def test_sensor_jackknife_widens_the_sigma_when_a_sensor_is_misplaced():
    fixes = _fixes(1487.0, 1500.0, noise_s=1e-7, seed=1)
    moved = SENSORS.copy()
    moved[2] += [3.0, -2.0, 2.5]  # a survey error the file does not know
    fixes = [FixTdoas(moved, f.pairs, f.taus, f.sigmas, f.weights, f.position) for f in fixes]
    plain = estimate_sound_speed(fixes, nominal_mps=1500.0)
    jack = estimate_sound_speed(fixes, nominal_mps=1500.0, n_real_sensors=6)
    assert jack.speed_mps == plain.speed_mps
    assert jack.sigma_mps > 1.3 * plain.sigma_mps
    assert abs(jack.speed_mps - 1487.0) < 3 * jack.sigma_mps


def test_too_few_fixes_and_absurd_speeds_are_refused():
    fixes = _fixes(1487.0, 1500.0)
    with pytest.raises(ValueError, match="at least 3"):
        estimate_sound_speed(fixes[:2], nominal_mps=1500.0)
    far = [FixTdoas(f.sensors, f.pairs, f.taus * 1.5, f.sigmas, f.weights, f.position)
           for f in fixes]
    with pytest.raises(ValueError, match="outside 1,300-1,800"):
        estimate_sound_speed(far, nominal_mps=1500.0, prior_sigma_mps=1e6)


def test_refit_at_the_estimated_speed_lands_on_the_source():
    fix = _fixes(1487.0, 1500.0)[1]
    p, cov = refit_fix(fix, 1487.0)
    np.testing.assert_allclose(p, SOURCES[1], atol=1e-4)
    assert np.all(np.isfinite(cov)) and np.all(np.linalg.eigvalsh(cov) > 0)
    p2, cov2 = refit_fix(fix, 1487.0, variance_factor=4.0)
    np.testing.assert_allclose(cov2, 4.0 * cov, rtol=1e-9)


def test_three_tdoas_of_three_sensors_leave_a_fix_unfixed():
    pairs = np.array([[0, 1], [0, 2], [1, 2]])
    taus = predicted_tdoas(SOURCES[0], SENSORS, pairs, c=1500.0)
    fix = FixTdoas(SENSORS, pairs, taus, np.full(3, 1e-6), np.ones(3), SOURCES[0] + 5.0)
    _, cov = refit_fix(fix, 1500.0)
    assert not np.all(np.isfinite(cov)) or np.linalg.cond(cov) > 1e8


def _reflected_length(p, s, surface_z=0.0):
    """Brute force: the shortest path from p to s touching the plane z = surface_z."""
    def length(t):
        b = p[:2] + t * (s[:2] - p[:2])
        q = np.array([b[0], b[1], surface_z])
        return np.linalg.norm(q - p) + np.linalg.norm(s - q)
    return minimize_scalar(length, bounds=(0, 1), method="bounded",
                           options={"xatol": 1e-12}).fun


def test_path_sensors_read_each_path_as_a_straight_one():
    pairs = np.array([[0, 1], [0, 1], [2, 3], [4, 5]])
    paths = np.array([0, 1, 2, 3])
    s2, q2 = path_sensors(SENSORS, pairs, paths)
    np.testing.assert_array_equal(q2, [[0, 1], [6, 7], [2, 9], [10, 5]])
    np.testing.assert_allclose(s2[6:], SENSORS * [1, 1, -1])
    p = SOURCES[0]
    length = {0: lambda i: np.linalg.norm(p - SENSORS[i]),
              1: lambda i: _reflected_length(p, SENSORS[i])}
    kinds = {0: (0, 0), 1: (1, 1), 2: (0, 1), 3: (1, 0)}
    for (i, j), h, (a, b) in zip(pairs, paths, q2, strict=True):
        ki, kj = kinds[int(h)]
        brute = length[ki](i) - length[kj](j)
        assert np.linalg.norm(p - s2[a]) - np.linalg.norm(p - s2[b]) == pytest.approx(brute,
                                                                                       abs=1e-6)
    with pytest.raises(ValueError, match="path pair"):
        path_sensors(SENSORS, pairs, [0, 1, 2, 4])


def test_emission_shift_is_the_drift_over_the_arrival_offset():
    rates = np.array([1e-3, -2e-3, 5e-4])
    first = np.array([0, 3, 1])
    p = SOURCES[2]
    r = np.linalg.norm(SENSORS - p, axis=1) / 1500.0
    expect = rates * (r[first] - r.mean())
    np.testing.assert_allclose(emission_shift(rates, first, [False] * 3, p, SENSORS, 1500.0),
                               expect, rtol=1e-12)
    refl = emission_shift(rates, first, [False, True, False], p, SENSORS, 1500.0, 0.0)
    image = _reflected_length(p, SENSORS[3]) / 1500.0
    assert refl[1] == pytest.approx(rates[1] * (image - r.mean()), rel=1e-9)
    with pytest.raises(ValueError, match="surface"):
        emission_shift(rates, first, [True] * 3, p, SENSORS, 1500.0)


def test_a_linear_profile_and_its_fixes_recovered_on_one_graph():
    """Delays of c(d) = 1475 + 0.0165 d along straight rays: the profile's graph recovers the
    gradient, the speed at its reference depth (halfway between sensors and fixes) and every
    fix; one speed's graph leaves the fixes off and its residuals show the misfit."""
    from factors.tdoa.gradient import travel_times
    from fusion.localization.sound_speed import LinearProfile, fix_residuals

    out = []
    for p in SOURCES:
        t, _, _ = travel_times(p, SENSORS, 1475.0, 0.0165, 0.0)
        taus = t[ALL_PAIRS[:, 0]] - t[ALL_PAIRS[:, 1]]
        start = least_squares(lambda q, t=taus: (predicted_tdoas(q, SENSORS, ALL_PAIRS, c=1500.0)
                                                 - t) * 1e6, p).x
        out.append(FixTdoas(SENSORS, ALL_PAIRS, taus, np.full(15, 1e-7), np.ones(15), start))
    est = estimate_sound_speed(out, nominal_mps=1500.0, gradient=True, n_real_sensors=6)
    assert est.gradient_per_s == pytest.approx(0.0165, abs=1e-5)
    assert est.speed_mps == pytest.approx(1475.0 + 0.0165 * est.reference_depth_m, abs=0.01)
    d_half = 0.5 * np.mean(-SENSORS[:, 2]) + 0.5 * np.mean([-f.position[2] for f in out])
    assert est.reference_depth_m == pytest.approx(d_half)
    np.testing.assert_allclose(est.positions, SOURCES, atol=0.01)
    assert est.chi2 < 1e-3 and np.isfinite(est.gradient_sigma_per_s)
    prof = est.profile
    assert isinstance(prof, LinearProfile) and prof.speed_at(prof.reference_depth_m) == est.speed_mps
    assert np.max(np.abs(fix_residuals(out[0], SOURCES[0], prof))) < 1e-9
    one = estimate_sound_speed(out, nominal_mps=1500.0)
    assert np.isnan(one.gradient_sigma_per_s) and one.chi2 > 1e3 * max(est.chi2, 1.0)
    assert np.max(np.linalg.norm(one.positions - SOURCES, axis=1)) > 0.3
