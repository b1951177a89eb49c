"""Tests of the multi-source localization: candidate competition (eq. 19-22) and alternatives."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.tdoa import predicted_tdoas, solve_source
from fusion.localization.competition import (
    CompetitionSettings,
    association_weights,
    compete,
    holds_a_source,
    independent_pairs,
    supported_weights,
)
from fusion.localization.localize import MultiSourceLocalizer
from fusion.localization.surfaces import SearchRegion, WindowTdoas
from fusion.simulate.tdoa_sets import all_pairs, simulate_tdoa_window

C = 1500.0
RING = np.array([[0.0, 0.0, -1600.0], [1433.0, 443.3, -1517.1], [-443.3, 1433.0, -1547.4],
                 [-1433.0, -443.3, -1660.3], [443.3, -1433.0, -1616.4]])
SEA = SearchRegion(water_column=(-1750.0, 0.0))
#: 3-sigma ellipsoid of a 3-D Gaussian (chi-square, 3 degrees of freedom, 0.9973).
CHI2_3SIGMA = 14.16
SIGMA = 20e-6


def mahalanobis2(fix, truth) -> float:
    d = fix.position - truth
    return float(d @ np.linalg.solve(fix.covariance, d))


def localize(truths, *, seed, localizer=None, sigma_reported=SIGMA, **kw):
    w = simulate_tdoa_window(RING, truths, c=C, seed=seed, noise_range_s=(SIGMA, SIGMA), **kw)
    loc = localizer or MultiSourceLocalizer(region=SEA)
    return w, loc.localize(RING, w.pairs, w.taus, sigma_reported, w.alpha, c=C)


def match(out, truths):
    """For each truth, the index of the nearest fix."""
    pos = np.array([f.position for f in out.sources]).reshape(-1, 3)
    return [int(np.argmin(np.linalg.norm(pos - t, axis=1))) for t in np.asarray(truths)]


def test_association_weights_match_the_sums():
    """beta and gamma equal eq. (20)-(21) written as explicit sums."""
    rng = np.random.default_rng(0)
    r = rng.normal(0, 1e-4, (3, 7))
    a = rng.poisson(3.0, (7, 7)).astype(float)
    a = np.triu(a, 1) + np.triu(a, 1).T
    sig = 1.5e-4
    beta, gamma = association_weights(r, sig, a)
    for k in range(3):
        for m in range(7):
            b = np.exp(-r[k, m] ** 2 / (sig**2 / 4))
            assert_allclose(beta[k, m], b, rtol=1e-12)
            g = sum((1 - np.exp(-a[m, ll] / 4)) * np.exp(-r[k, ll] ** 2 / (sig**2 / 4)) * b
                    for ll in range(7))
            assert_allclose(gamma[k, m], g, rtol=1e-12)


def test_independent_pairs_is_the_incidence_rank():
    """The union-find count equals the rank of the selected pairs' incidence matrix."""
    rng = np.random.default_rng(1)
    pairs = all_pairs(6)
    inc = np.zeros((len(pairs), 6))
    inc[np.arange(len(pairs)), pairs[:, 0]] = 1
    inc[np.arange(len(pairs)), pairs[:, 1]] = -1
    for _ in range(50):
        rows = rng.random(len(pairs)) < 0.3
        rank = np.linalg.matrix_rank(inc[rows]) if rows.any() else 0
        assert independent_pairs(pairs, rows) == rank


def test_single_source_equals_least_squares():
    """One source: the competition ends at the least-squares fit with solve_source's covariance."""
    truth = np.array([250.0, -300.0, -850.0])
    w, out = localize([truth], seed=5)
    assert len(out.sources) == 1
    fix = out.sources[0]
    p, cov, info = solve_source(RING, w.pairs, w.taus, SIGMA, c=C, initial=truth + 50.0)
    assert_allclose(fix.position, p, atol=1e-4)
    assert_allclose(fix.covariance, cov, rtol=1e-3)
    assert fix.tdoas_used == 10 and fix.observable and not fix.mirror_ambiguous
    assert mahalanobis2(fix, truth) < CHI2_3SIGMA
    assert_allclose(fix.residual_rms_s, info.residual_rms_s, rtol=1e-3)


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_two_sources_separated(seed):
    """Union of two whales' unlabeled TDOAs: each whale localized within 3 sigma."""
    rng = np.random.default_rng(seed)
    truths = np.column_stack([rng.uniform(-900, 900, (2, 2)), rng.uniform(-1200, -500, 2)])
    w, out = localize(truths, seed=seed)
    assert len(out.sources) == 2
    for k, i in enumerate(match(out, truths)):
        fix = out.sources[i]
        assert mahalanobis2(fix, truths[k]) < CHI2_3SIGMA
        # it holds exactly that whale's TDOAs
        assert_allclose(fix.weights > 0.5, w.labels == k)


@pytest.mark.parametrize("seed", [21, 22])
def test_three_sources_with_clutter_and_gaps(seed):
    """Three whales, 6 clutter TDOAs, 15 % missing: all three within 3 sigma, no false source."""
    rng = np.random.default_rng(seed)
    truths = np.column_stack([rng.uniform(-900, 900, (3, 2)), rng.uniform(-1200, -500, 3)])
    w, out = localize(truths, seed=seed, n_clutter=6, p_missing=0.15)
    assert len(out.sources) == 3
    assert sorted(match(out, truths)) == [0, 1, 2]
    for k, i in enumerate(match(out, truths)):
        fix = out.sources[i]
        assert mahalanobis2(fix, truths[k]) < CHI2_3SIGMA
        assert fix.tdoas_used == int(np.sum(w.labels == k))
    clutter = w.labels < 0
    assert np.all(out.clutter_weights[clutter] > 0.5)  # clutter TDOAs owned by no source
    assert np.all(np.array([f.weights[clutter] for f in out.sources]) < 0.5)
    total = np.sum([f.weights for f in out.sources], axis=0)
    assert np.all(total <= 1.0 + 1e-9)
    assert_allclose(total + out.clutter_weights, 1.0, atol=1e-9)


def test_two_sources_without_alpha():
    """Without the association measure (gamma = beta), two whales are still separated."""
    truths = np.array([[600.0, 500.0, -700.0], [-700.0, -400.0, -1000.0]])
    w = simulate_tdoa_window(RING, truths, c=C, seed=4, noise_range_s=(SIGMA, SIGMA))
    out = MultiSourceLocalizer(region=SEA).localize(RING, w.pairs, w.taus, SIGMA, None, c=C)
    assert len(out.sources) == 2
    for k, i in enumerate(match(out, truths)):
        assert mahalanobis2(out.sources[i], truths[k]) < CHI2_3SIGMA


def test_competition_drops_a_start_with_no_tdoas():
    """A candidate far from every source loses all weight and is dropped; the true one stays."""
    truth = np.array([100.0, 200.0, -800.0])
    w = simulate_tdoa_window(RING, [truth], c=C, seed=6, noise_range_s=(SIGMA, SIGMA))
    t = WindowTdoas(RING, w.pairs, w.taus, np.full(10, SIGMA), c=C, alpha=w.alpha)
    starts = np.array([truth + 5.0, [-2500.0, 2500.0, -100.0]])
    res = compete(t, starts, start_scale_s=5e-3, settings=CompetitionSettings())
    assert list(res.origin) == [0]
    assert res.converged
    assert np.linalg.norm(res.positions[0] - truth) < 1.0


def test_candidate_below_the_sea_floor_jumps_to_its_mirror():
    """A start mirrored below the sea floor settles there alone; with the water column it jumps."""
    truth = np.array([300.0, -200.0, -900.0])
    w = simulate_tdoa_window(RING, [truth], c=C, seed=2, noise_range_s=(SIGMA, SIGMA))
    t = WindowTdoas(RING, w.pairs, w.taus, np.full(10, SIGMA), c=C, alpha=w.alpha)
    centre = RING.mean(0)
    normal = np.linalg.svd(RING - centre)[2][-1]
    start = truth - 2 * ((truth - centre) @ normal) * normal  # about 2.3 km deep
    free = compete(t, start[None], start_scale_s=5e-3)
    assert free.positions[0, 2] < -1750.0  # a ghost below the sea floor
    sea = compete(t, start[None], start_scale_s=5e-3, z_range=(-1750.0, 0.0))
    assert np.linalg.norm(sea.positions[0] - truth) < 1.0
    assert_allclose(sea.weights[0], 1.0, atol=1e-3)


def test_supported_weights_ignore_unassociated_tdoas():
    """A held TDOA associated with none of the others does not count towards a source."""
    pairs = np.array([[0, 1], [0, 2], [0, 3], [1, 4]])
    alpha = np.zeros((4, 4))
    alpha[0, 1] = alpha[1, 0] = alpha[1, 2] = alpha[2, 1] = 20.0  # TDOA 3 linked to nothing
    w = np.ones(4)
    assert_allclose(supported_weights(w, alpha, 3.0), [1, 1, 1, 0])
    assert_allclose(supported_weights(w, None, 3.0), w)
    cfg = CompetitionSettings()
    assert not holds_a_source(w, pairs, alpha, cfg)  # 3 associated TDOAs < 3.5
    alpha[3, 0] = alpha[0, 3] = 20.0
    assert holds_a_source(w, pairs, alpha, cfg)


def test_second_round_finds_a_whale_merged_on_the_coarse_surface():
    """Two whales 180 m apart share one coarse peak; the next round's surface separates them."""
    truths = np.array([[-500.0, 500.0, -800.0], [-350.0, 500.0, -900.0]])
    w = simulate_tdoa_window(RING, truths, c=C, seed=2, noise_range_s=(SIGMA, SIGMA))
    one = MultiSourceLocalizer(region=SEA, max_rounds=1).localize(RING, w.pairs, w.taus, SIGMA,
                                                                  w.alpha, c=C)
    assert len(one.sources) == 1
    out = MultiSourceLocalizer(region=SEA).localize(RING, w.pairs, w.taus, SIGMA, w.alpha, c=C)
    assert len(out.sources) == 2
    for k, i in enumerate(match(out, truths)):
        assert mahalanobis2(out.sources[i], truths[k]) < CHI2_3SIGMA


#: A planar array (all hydrophones at one depth, 1 km square plus centre).
PLANAR = np.array([[0, 0, -1000.0], [1000, 0, -1000], [0, 1000, -1000], [1000, 1000, -1000],
                   [500, 500, -1000]])


def planar_fix(truth, region):
    w = simulate_tdoa_window(PLANAR, [truth], c=C, seed=1, noise_range_s=(SIGMA, SIGMA))
    out = MultiSourceLocalizer(region=region).localize(PLANAR, w.pairs, w.taus, SIGMA, w.alpha,
                                                       c=C)
    assert len(out.sources) == 1
    return out.sources[0]


def test_planar_array_in_plane_source_outside_aperture_is_flagged():
    """A source in the plane of a planar array, 3 km out: depth unobservable, flagged."""
    fix = planar_fix([3500.0, 400.0, -1000.0], SearchRegion())
    assert not fix.observable
    assert fix.condition_number > 1e6
    assert np.linalg.norm(fix.position[:2] - [3500.0, 400.0]) < 5.0


def test_planar_array_mirror_is_flagged_and_resolved_by_the_water_column():
    """Planar array: z and its mirror fit equally; flagged, unless the water column decides."""
    truth = np.array([500.0, 400.0, -500.0])
    fix = planar_fix(truth, SearchRegion())
    assert fix.mirror_ambiguous and not fix.observable
    found = {round(fix.position[2]), round(fix.mirror_position[2])}
    assert found == {-500, -1500}
    fix = planar_fix(truth, SearchRegion(water_column=(-1000.0, 0.0)))
    assert not fix.mirror_ambiguous and fix.observable
    assert mahalanobis2(fix, truth) < CHI2_3SIGMA


def test_lsq_method_is_the_unweighted_fit():
    """method='lsq' is solve_source over all TDOAs (one source)."""
    truth = np.array([-300.0, 700.0, -600.0])
    loc = MultiSourceLocalizer(method="lsq", region=SEA)
    w, out = localize([truth], seed=8, localizer=loc)
    p, cov, _ = solve_source(RING, w.pairs, w.taus, SIGMA, c=C, initial=truth + 30.0)
    assert len(out.sources) == 1
    assert_allclose(out.sources[0].position, p, atol=1e-6)
    assert_allclose(out.sources[0].covariance, cov, rtol=1e-6)


@pytest.mark.parametrize("method", ["eq17", "eq18"])
def test_surface_methods_find_a_noise_free_source(method):
    """The plain surface peaks land within a few fine cells of a noise-free source."""
    truth = np.array([-300.0, 700.0, -600.0])
    w = simulate_tdoa_window(RING, [truth], c=C, seed=8, noise_range_s=(0.0, 0.0))
    out = MultiSourceLocalizer(method=method, region=SEA).localize(RING, w.pairs, w.taus, SIGMA,
                                                                   w.alpha, c=C)
    assert len(out.sources) >= 1
    assert np.linalg.norm(out.sources[0].position - truth) < 3 * SIGMA * C / 2
    assert out.sources[0].tdoas_used == 10


def test_window_without_tdoas_has_no_source():
    """No TDOAs (or too few to fix anything) give an empty output, not an error."""
    loc = MultiSourceLocalizer(region=SEA)
    out = loc.localize(RING, np.zeros((0, 2), int), np.zeros(0), SIGMA, np.zeros((0, 0)), c=C)
    assert out.sources == () and out.clutter_weights.shape == (0,)
    pairs = np.array([[0, 1], [0, 2]])
    taus = predicted_tdoas([0.0, 0, -800], RING, pairs, c=C)
    out = loc.localize(RING, pairs, taus, SIGMA, np.array([[0, 20.0], [20.0, 0]]), c=C)
    assert out.sources == ()
    assert_allclose(out.clutter_weights, 1.0)


def test_localizer_checks_inputs():
    """Unknown methods, eq18 without alpha, and bad options are ValueErrors."""
    with pytest.raises(ValueError, match="method"):
        MultiSourceLocalizer(method="music")
    with pytest.raises(ValueError, match="gate_sigmas"):
        MultiSourceLocalizer(gate_sigmas=0.0)
    pairs = all_pairs(5)
    taus = predicted_tdoas([0.0, 0, -800], RING, pairs, c=C)
    with pytest.raises(ValueError, match="alpha"):
        MultiSourceLocalizer(method="eq18").localize(RING, pairs, taus, SIGMA, c=C)
    with pytest.raises(ValueError, match="clutter_fraction"):
        CompetitionSettings(clutter_fraction=1.0)
