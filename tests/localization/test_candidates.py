"""Tests of the candidate positions picked from the 3-D maxima of an intensity volume."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.localization.candidates import CandidateFinder
from fusion.localization.surfaces import (
    IntensityVolume,
    SearchGrid,
    SearchRegion,
    WindowTdoas,
    intensity_volume,
)
from fusion.simulate.tdoa_sets import simulate_tdoa_window

C = 1500.0
RING = np.array([[0.0, 0.0, -1600.0], [1433.0, 443.3, -1517.1], [-443.3, 1433.0, -1547.4],
                 [-1433.0, -443.3, -1660.3], [443.3, -1433.0, -1616.4]])


def blobs(centres, heights, grid: SearchGrid, width: float = 1.5) -> IntensityVolume:
    """A volume of Gaussian blobs (grid units) at the given centres."""
    p = grid.points().reshape(grid.shape + (3,))
    v = np.zeros(grid.shape)
    for c, h in zip(centres, heights, strict=True):
        v += h * np.exp(-0.5 * np.sum((p - np.asarray(c)) ** 2, axis=-1) / width**2)
    return IntensityVolume(grid, v, 17, np.ones(1))


GRID = SearchGrid(np.arange(20.0), np.arange(20.0), np.arange(10.0))


def test_maxima_ranked_strongest_first():
    """Three separated blobs give three candidates at their centres, strongest first."""
    vol = blobs([(4, 4, 3), (15, 12, 6), (8, 16, 2)], [1.0, 3.0, 2.0], GRID)
    c = CandidateFinder(refine_levels=0).find(vol)
    assert_allclose(c.positions, [(15, 12, 6), (8, 16, 2), (4, 4, 3)])
    assert_allclose(c.relative, [1.0, 2 / 3, 1 / 3], rtol=1e-3)
    assert np.all(np.diff(c.intensities) < 0)


def test_floor_and_cap():
    """min_relative drops weak maxima; max_candidates caps the count."""
    vol = blobs([(4, 4, 3), (15, 12, 6), (8, 16, 2)], [1.0, 3.0, 2.0], GRID)
    assert CandidateFinder(refine_levels=0, min_relative=0.5).find(vol).k == 2
    c = CandidateFinder(refine_levels=0, max_candidates=1).find(vol)
    assert c.k == 1 and tuple(c.positions[0]) == (15, 12, 6)


def test_plateau_is_one_candidate():
    """Equal neighbouring values (a plateau) yield one candidate, not one per point."""
    v = np.zeros(GRID.shape)
    v[5:7, 5:7, 4] = 1.0
    c = CandidateFinder(refine_levels=0).find(IntensityVolume(GRID, v, 17, np.ones(1)))
    assert c.k == 1


def test_flat_volume_has_no_candidates():
    """An all-zero volume has no candidate."""
    c = CandidateFinder().find(IntensityVolume(GRID, np.zeros(GRID.shape), 17, np.ones(1)))
    assert c.k == 0 and c.positions.shape == (0, 3)


def test_two_sources_each_get_a_candidate():
    """On eq. (18) of two whales' unlabeled TDOAs, each whale has a candidate within 20 m."""
    truth = np.array([[400.0, 300.0, -700.0], [-600.0, -200.0, -1000.0]])
    w = simulate_tdoa_window(RING, truth, c=C, seed=3)
    t = WindowTdoas(RING, w.pairs, w.taus, np.full(w.taus.size, 20e-6), c=C, alpha=w.alpha)
    region = SearchRegion(water_column=(-1750.0, 0.0))
    vol = intensity_volume(t, region.volume(RING), equation=18)
    lo, hi = region.bounds(RING)
    c = CandidateFinder().find(vol, t, lo=lo, hi=hi)
    assert c.k <= 8
    for p in truth:
        assert np.min(np.linalg.norm(c.positions - p, axis=1)) < 20.0
    assert c.step < vol.grid.step / 8  # two refinement levels, 3 times finer each


@pytest.mark.parametrize(("kw", "match"), [
    ({"max_candidates": 0}, "max_candidates"),
    ({"min_relative": 1.0}, "min_relative"),
    ({"footprint": 4}, "footprint"),
    ({"refine_levels": -1}, "refine_levels"),
])
def test_finder_checks_options(kw, match):
    """Bad options are ValueErrors naming the option."""
    with pytest.raises(ValueError, match=match):
        CandidateFinder(**kw)


def test_suppression_equals_the_pairwise_greedy_rule():
    """Non-maximum suppression keeps exactly the points no earlier kept point is within radius
    of (the pairwise greedy rule), on grids with ties at many distances; a limit truncates."""
    rng = np.random.default_rng(5)
    finder = CandidateFinder()
    for _ in range(50):
        p = rng.integers(0, 5, (int(rng.integers(0, 60)), 3)) * 7.3 - 900.0
        radius = 7.3 * float(rng.choice([1.0, 1.5, 2.0]))
        kept: list[int] = []
        for k in range(p.shape[0]):
            if all(np.linalg.norm(p[k] - p[j]) > radius for j in kept):
                kept.append(k)
        assert finder._suppress(p, radius).tolist() == kept
        assert finder._suppress(p, radius, 3).tolist() == kept[:3]
