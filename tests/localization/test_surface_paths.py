"""Tests of TDOAs read along direct and surface-reflected paths (image sensors)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.localization.competition import compete
from fusion.localization.intensity import combine_intensities, tdoa_intensities
from fusion.localization.localize import MultiSourceLocalizer
from fusion.localization.search_grid import SearchRegion
from fusion.localization.surface_paths import PATHS, surface_paths
from fusion.localization.window_tdoas import WindowTdoas
from fusion.simulate.tdoa_sets import all_pairs

C = 1500.0
RING = np.array([[0.0, 0.0, -1600.0], [1433.0, 443.3, -1517.1], [-443.3, 1433.0, -1547.4],
                 [-1433.0, -443.3, -1660.3], [443.3, -1433.0, -1616.4]])
WHALE = np.array([-300.0, 250.0, -800.0])


def path_delay(p, si, sj, kind: int, surface_z: float = 0.0) -> float:
    """Delay of one click along path pair `kind`, from the image source (independent of the code)."""
    image = p * np.array([1.0, 1.0, -1.0]) + np.array([0.0, 0.0, 2.0 * surface_z])
    src_i = image if PATHS[kind] in ("surface", "surface-direct") else p
    src_j = image if PATHS[kind] in ("surface", "direct-surface") else p
    return float(np.linalg.norm(src_i - si) - np.linalg.norm(src_j - sj)) / C


def echo_window(sigma: float = 1e-6) -> tuple[WindowTdoas, np.ndarray]:
    """The whale's direct TDOAs on every pair plus echo delays on some pairs (kinds returned)."""
    pairs = all_pairs(5)
    rows = [(i, j, 0) for i, j in pairs]
    rows += [(i, j, 1) for i, j in pairs[:4]] + [(i, j, 2) for i, j in pairs[4:7]]
    rows += [(i, j, 3) for i, j in pairs[7:9]]
    taus = [path_delay(WHALE, RING[i], RING[j], k) for i, j, k in rows]
    m = len(rows)
    alpha = 24.0 * (1.0 - np.eye(m))  # every TDOA shares clicks with every other
    w = WindowTdoas(RING, np.array([(i, j) for i, j, _ in rows]), taus, np.full(m, sigma), c=C,
                    alpha=alpha)
    return w, np.array([k for _, _, k in rows])


def test_columns_predict_the_image_source_delays():
    """Column (m, path) predicts the delay computed from the image source, at random positions."""
    w, _ = echo_window()
    p = surface_paths(w, 0.0)
    rng = np.random.default_rng(3)
    for x in rng.uniform([-2000, -2000, -1500], [2000, 2000, -10], (20, 3)):
        pred = p.tdoas.predicted(x)
        for col in range(p.tdoas.m):
            i, j = w.pairs[p.measured[col]]
            assert_allclose(pred[col], path_delay(x, RING[i], RING[j], p.path[col]), atol=1e-12)


def test_surface_reading_of_a_source_at_the_surface_counts_each_delay_once():
    """At the surface every path pair predicts the same delay: grouped eq. (17) equals M, not 4 M."""
    w, _ = echo_window()
    p = surface_paths(w, 0.0)
    x = np.array([[100.0, -50.0, 0.0]])
    i = tdoa_intensities(x, p.tdoas, np.full(p.tdoas.m, 1e-3))
    per_path = i.reshape(len(PATHS), w.m)
    assert_allclose(per_path, per_path[:1].repeat(len(PATHS), 0), atol=1e-12)
    grouped = combine_intensities(i, p.tdoas, 17, p.measured)
    assert_allclose(grouped, per_path.max(axis=0).sum(keepdims=True), rtol=1e-12)
    assert_allclose(combine_intensities(i, p.tdoas, 17), 4 * grouped, rtol=1e-12)


def test_collapse_and_paths_of_known_answers():
    """Column weights sum per measurement; a held measurement takes its heaviest column's path."""
    w, _ = echo_window()
    p = surface_paths(w, 0.0)
    cols = np.zeros(p.tdoas.m)
    cols[0 * w.m + 0] = 0.9  # measurement 0 direct
    cols[1 * w.m + 1], cols[2 * w.m + 1] = 0.2, 0.7  # measurement 1: mostly direct-surface
    cols[3 * w.m + 2] = 0.3  # measurement 2: not held
    assert_allclose(p.collapse(cols)[:3], [0.9, 0.9, 0.3])
    assert p.paths_of(cols)[:4].tolist() == [0, 2, -1, -1]


def test_sensor_above_the_surface_is_rejected():
    """surface_paths refuses a sensor above the surface (its image would be in the water)."""
    w, _ = echo_window()
    with pytest.raises(ValueError, match="below the surface"):
        surface_paths(w, -1550.0)


def test_competition_gives_each_measurement_one_path():
    """With groups, a candidate's weights over the paths of one measurement sum to at most one."""
    w, _ = echo_window(sigma=2e-6)
    p = surface_paths(w, 0.0)
    res = compete(p.tdoas, [WHALE + 30.0], start_scale_s=1e-3, groups=p.measured, surface_z=0.0,
                  z_range=(-1700.0, 0.0))
    assert res.positions.shape == (1, 3)
    total = p.collapse(res.weights[0])
    assert np.all(total <= 1.0 + 1e-9)
    assert_allclose(total + res.clutter[: w.m], 1.0, atol=1e-9)
    assert_allclose(res.positions[0], WHALE, atol=0.05)


def test_localizer_reads_the_echoes_of_one_whale():
    """With the surface, one fix holds every direct and echo delay along its true path pair."""
    w, kinds = echo_window()
    loc = MultiSourceLocalizer(region=SearchRegion(water_column=(-1700.0, 0.0)), surface_z=0.0)
    out = loc.localize(RING, w.pairs, w.taus, w.sigmas, w.alpha, c=C)
    assert len(out.sources) == 1
    fix = out.sources[0]
    assert_allclose(fix.position, WHALE, atol=0.01)
    assert fix.tdoas_used == w.m
    assert fix.paths.tolist() == kinds.tolist()
    assert np.all(fix.weights <= 1.0) and fix.observable


def test_combined_path_intensities_equal_the_reduceat_reference():
    """The per-measurement best path and eq. 17/18 equal maximum.reduceat's, bit for bit."""
    rng = np.random.default_rng(11)
    s = np.array([[0.0, 0, -1000], [1000, 0, -1000], [0, 1000, -1000], [500, 500, -990]])
    for trial in range(20):
        m = int(rng.integers(1, 9))
        pairs = np.array(all_pairs(4))[rng.integers(0, 6, m)]
        alpha = rng.random((m, m))
        alpha = alpha + alpha.T
        np.fill_diagonal(alpha, 0.0)
        w = WindowTdoas(s, pairs, rng.uniform(-0.5, 0.5, m), [1e-3] * m, c=1500.0, alpha=alpha)
        p = surface_paths(w, 0.0)
        keep = np.sort(rng.choice(p.tdoas.m, size=int(rng.integers(1, p.tdoas.m + 1)),
                                  replace=False)) if trial % 2 else np.arange(p.tdoas.m)
        sub, groups = p.tdoas.subset(keep), p.measured[keep]
        i = rng.random((257, keep.size))
        order = np.argsort(groups, kind="stable")
        starts = np.flatnonzero(np.r_[True, np.diff(groups[order]) != 0])
        best = np.maximum.reduceat(i[:, order], starts, axis=1)
        first = order[starts]
        assert np.array_equal(combine_intensities(i, sub, 17, groups), best.sum(axis=1))
        a = np.asarray(sub.alpha)[np.ix_(first, first)]
        assert np.array_equal(combine_intensities(i, sub, 18, groups),
                              np.einsum("pm,pm->p", best @ a, best))
