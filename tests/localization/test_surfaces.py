"""Tests of the intensity surfaces (eq. 16-18) and their array-sized grids."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.tdoa import predicted_tdoas
from fusion.localization.intensity import combine_intensities
from fusion.localization.search_grid import sensor_distances
from fusion.localization.surfaces import (
    SearchGrid,
    SearchRegion,
    WindowTdoas,
    array_aperture,
    associated_intensity,
    fine_step,
    intensity_volume,
    refine_peak,
    smoothing_sigma,
    tdoa_intensities,
)
from fusion.simulate.tdoa_sets import all_pairs, sharing_one_sensor, simulate_tdoa_window

C = 1500.0
#: Bottom-mounted kilometre array: a centre hydrophone and a ring of radius 1.5 km (z up, m).
RING = np.array([[0.0, 0.0, -1600.0], [1433.0, 443.3, -1517.1], [-443.3, 1433.0, -1547.4],
                 [-1433.0, -443.3, -1660.3], [443.3, -1433.0, -1616.4]])
#: XAV large array (realdata/xav_large_array/array.json), m, and its sound speed, m/s.
XAV = np.array([[-0.858, -0.86, -0.671], [-0.858, -0.86, 0.479], [0.858, -0.86, -0.671],
                [0.028, 0.0, -0.002], [-0.858, 0.86, -0.671], [0.858, 0.86, 0.671]])
C_XAV = 1484.0


def window(sensors, sources, *, c=C, sigma=20e-6, seed=0, **kw) -> WindowTdoas:
    """Noise-free (by default) TDOAs of the sources with the simulated association."""
    kw.setdefault("noise_range_s", (0.0, 0.0))
    w = simulate_tdoa_window(sensors, sources, c=c, seed=seed, **kw)
    return WindowTdoas(sensors, w.pairs, w.taus, np.full(w.taus.size, sigma), c=c, alpha=w.alpha)


def test_eq18_with_all_ones_alpha_is_square_of_eq17():
    """sum_{l,m} I_l I_m = (sum_m I_m)^2: eq. (18) with alpha = 1 is eq. (17) squared."""
    rng = np.random.default_rng(1)
    t = window(RING, [[300.0, 200.0, -800.0], [-500.0, 100.0, -900.0]])
    ones = WindowTdoas(t.sensors, t.pairs, t.taus, t.sigmas, c=C, alpha=np.ones((t.m, t.m)))
    grid = SearchGrid(np.linspace(-1000, 1000, 9), np.linspace(-900, 800, 7), [-850.0, -800.0])
    v17 = intensity_volume(ones, grid, equation=17, cells=30.0)
    v18 = intensity_volume(ones, grid, equation=18, cells=30.0)
    assert_allclose(v18.values, v17.values**2, rtol=1e-12)
    i = rng.uniform(0, 1, (50, t.m))
    assert_allclose(associated_intensity(i, np.ones((t.m, t.m))), i.sum(1) ** 2, rtol=1e-12)


def test_eq18_identity_and_block_alpha():
    """alpha = I gives sum I_m^2; a block-diagonal alpha gives the sum of the blocks' eq. (18)."""
    rng = np.random.default_rng(2)
    i = rng.uniform(0, 1, (40, 6))
    assert_allclose(associated_intensity(i, np.eye(6)), (i**2).sum(1), rtol=1e-12)
    sources = [[300.0, 200.0, -800.0], [-500.0, 100.0, -900.0]]
    w = simulate_tdoa_window(RING, sources, c=C, seed=0, noise_range_s=(0.0, 0.0),
                             chance_matches=0.0)  # no association across the two sources
    t = WindowTdoas(RING, w.pairs, w.taus, np.full(w.taus.size, 5e-3), c=C, alpha=w.alpha)
    points = rng.uniform([-1000, -1000, -1500], [1000, 1000, -300], (200, 3))
    both = associated_intensity(tdoa_intensities(points, t, t.sigmas), t.alpha)
    parts = sum(associated_intensity(tdoa_intensities(points, sub, sub.sigmas), sub.alpha)
                for sub in (t.subset(w.labels == k) for k in (0, 1)))
    assert_allclose(both, parts, rtol=1e-10)
    # ... while eq. (17) squared also has the cross-source products eq. (18) leaves out
    square = tdoa_intensities(points, t, t.sigmas).sum(1) ** 2
    assert np.all(square >= both / t.alpha.max() - 1e-12)


def test_eq18_at_source_counts_the_association():
    """At a noise-free source every I_m = 1, so eq. (18) is the sum of that source's alpha."""
    t = window(RING, [[300.0, 200.0, -800.0]])
    at = tdoa_intensities(np.array([[300.0, 200.0, -800.0]]), t, t.sigmas)
    assert_allclose(at, 1.0, atol=1e-9)
    assert_allclose(associated_intensity(at, t.alpha), t.alpha.sum(), rtol=1e-9)
    # the support of alpha is the pairs sharing exactly one sensor
    assert np.all((t.alpha > 0) <= sharing_one_sensor(t.pairs))


@pytest.mark.parametrize("equation", [17, 18])
def test_km_volume_peaks_at_source(equation):
    """Coarse volume then coarse-to-fine: the peak lands on a noise-free km-array source."""
    truth = np.array([350.0, -420.0, -760.0])
    t = window(RING, [truth])
    region = SearchRegion(water_column=(-1750.0, 0.0))
    grid = region.volume(RING)
    vol = intensity_volume(t, grid, equation=equation)
    p0, _ = vol.peak()
    assert np.linalg.norm(p0 - truth) < 2 * grid.step
    lo, hi = region.bounds(RING)
    p, value, step = refine_peak(t, p0, grid.step, equation=equation, lo=lo, hi=hi)
    assert step <= fine_step(t) * 1.0001
    assert np.linalg.norm(p - truth) < 3 * step
    assert value > (0.8 * t.m if equation == 17 else 0.8 * t.alpha.sum())


@pytest.mark.parametrize("truth", [[0.3, -0.2, 0.1], [-0.9, 0.9, -1.3]])
def test_xav_volume_peaks_at_source(truth):
    """The same defaults work on the 1.7 m XAV frame (a source inside and one 1.6 m out)."""
    truth = np.asarray(truth)
    t = window(XAV, [truth], c=C_XAV, sigma=10e-6)
    region = SearchRegion()
    grid = region.volume(XAV)
    assert 0.05 < grid.step < 0.5  # sized by the aperture, not by kilometres
    vol = intensity_volume(t, grid, equation=18)
    lo, hi = region.bounds(XAV)
    p, _, step = refine_peak(t, vol.peak()[0], grid.step, equation=18, lo=lo, hi=hi)
    assert np.linalg.norm(p - truth) < 3 * step


def test_plane_at_assumed_depth_peaks_at_source():
    """A 2-D plane at the source's depth peaks at its (x, y) (step 56: hyperbolas in a plane)."""
    truth = np.array([-250.0, 600.0, -900.0])
    t = window(RING, [truth])
    region = SearchRegion()
    plane = region.plane(RING, truth[2])
    assert plane.shape[2] == 1
    vol = intensity_volume(t, plane, equation=18)
    p0, _ = vol.peak()
    lo, hi = region.bounds(RING)
    lo[2] = hi[2] = truth[2]
    p, _, step = refine_peak(t, p0, plane.step, equation=18, lo=lo, hi=hi)
    assert p[2] == truth[2]
    assert np.linalg.norm(p - truth) < 3 * step


def test_chunking_does_not_change_the_volume():
    """Evaluating in chunks of 7 points gives the same volume as one pass (to rounding)."""
    t = window(RING, [[300.0, 200.0, -800.0]], sigma=1e-3)
    grid = SearchGrid(np.linspace(-500, 500, 5), np.linspace(-500, 500, 6), np.linspace(-900, -700, 3))
    a = intensity_volume(t, grid, equation=18, chunk_points=7)
    b = intensity_volume(t, grid, equation=18, chunk_points=10_000)
    assert_allclose(a.values, b.values, rtol=1e-12, atol=1e-300)


def test_region_follows_the_array_size():
    """Box: centroid +- 2 apertures (water column when given); coarse grid within the budget."""
    for sensors in (RING, XAV):
        region = SearchRegion(max_points=20_000)
        lo, hi = region.bounds(sensors)
        ap = array_aperture(sensors)
        assert_allclose(hi - lo, 4 * ap)
        assert_allclose((hi + lo) / 2, sensors.mean(0), atol=1e-9 * ap)
        g = region.volume(sensors)
        assert 0.5 * 20_000 < g.size <= 1.2 * 20_000
    lo, hi = SearchRegion(water_column=(-1700.0, 0.0)).bounds(RING)
    assert (lo[2], hi[2]) == (-1700.0, 0.0)


def test_smoothing_sigma_and_fine_step():
    """sigma_t = sqrt(sigma^2 + (cells step / c)^2); the fine step is sigma c / 2."""
    assert_allclose(smoothing_sigma([1.5e-3, 0.0], 6.0, c=1500.0, cells=0.5), [0.0025, 0.002])
    t = window(RING, [[0.0, 0.0, -800.0]], sigma=20e-6)
    assert_allclose(fine_step(t), 20e-6 * C / 2)


def test_window_checks_inputs():
    """Bad shapes, signs and asymmetric alpha are ValueErrors naming the problem."""
    pairs = all_pairs(5)
    taus = predicted_tdoas([0.0, 0, -800], RING, pairs, c=C)
    with pytest.raises(ValueError, match="symmetric"):
        WindowTdoas(RING, pairs, taus, 1e-5, c=C, alpha=np.triu(np.ones((10, 10)), 1))
    with pytest.raises(ValueError, match="non-negative"):
        WindowTdoas(RING, pairs, taus, 1e-5, c=C, alpha=-np.ones((10, 10)))
    with pytest.raises(ValueError, match="shape"):
        WindowTdoas(RING, pairs, taus, 1e-5, c=C, alpha=np.ones((3, 3)))
    with pytest.raises(ValueError, match="sigmas"):
        WindowTdoas(RING, pairs, taus, 0.0, c=C)
    t = WindowTdoas(RING, pairs, taus, 1e-5, c=C)
    with pytest.raises(ValueError, match="alpha"):
        intensity_volume(t, SearchGrid([0.0], [0.0], [0.0]), equation=18)
    with pytest.raises(ValueError, match="equation"):
        intensity_volume(t, SearchGrid([0.0], [0.0], [0.0]), equation=16)
    with pytest.raises(ValueError, match="water_column"):
        SearchRegion(water_column=(0.0, -100.0))
    with pytest.raises(ValueError, match="increasing"):
        SearchGrid([1.0, 0.0], [0.0], [0.0])


@pytest.mark.parametrize("grouped", [False, True])
@pytest.mark.parametrize("equation", [17, 18])
def test_cached_ranges_give_the_column_arithmetic_bit_for_bit(grouped, equation):
    """Intensities from a grid's cached ranges (read per sensor in passes of points) equal
    the column form of eq. (16)-(18) (ranges gathered per TDOA column, then summed or
    ``I^T alpha I``) bit for bit, with and without measurement groups."""
    w = window(RING, np.array([[300.0, -200.0, -900.0], [-500.0, 400.0, -1200.0]]),
               noise_range_s=(0.0, 5e-5))
    groups = np.repeat(np.arange((w.m + 1) // 2), 2)[:w.m] if grouped else None
    grid = SearchRegion(max_points=5000).volume(RING)
    d = sensor_distances(grid, RING)
    vol = intensity_volume(w, grid, equation=equation, distances=d, groups=groups,
                           chunk_points=3000)
    sig = smoothing_sigma(w.sigmas, grid.step, c=C)
    want = []
    for a in range(0, grid.size, 3000):
        c = np.ascontiguousarray(d[a:a + 3000])
        r = ((c[:, w.pairs[:, 0]] - c[:, w.pairs[:, 1]]) / C - w.taus) / sig
        want.append(combine_intensities(np.exp(-0.5 * r * r), w, equation, groups))
    assert np.array_equal(vol.values.reshape(-1), np.concatenate(want))
    assert_allclose(d, np.linalg.norm(grid.points()[:, None] - RING[None], axis=-1), atol=1e-6)


def test_centred_grid_in_a_box_is_the_checked_grid():
    """A refinement grid built inside the search box (checks skipped: its axes are finite and
    increasing by construction) equals the grid built through the checks, clipped at the box
    (a plane keeps its one depth), with its spacing; a bad centre still raises."""
    lo, hi = np.array([-100.0, -100.0, -50.0]), np.array([100.0, 100.0, -50.0])
    g = SearchGrid.centred([95.0, 0.0, -50.0], 3.0, 4, lo=lo, hi=hi)
    axes = [np.clip(c + 3.0 * np.arange(-4, 5), lo[a], hi[a]) for a, c in enumerate([95.0, 0.0, -50.0])]
    want = SearchGrid(*[np.unique(a) for a in axes])
    assert all(np.array_equal(getattr(g, a), getattr(want, a)) for a in "xyz")
    assert g.shape == (7, 9, 1) and g.step == 3.0 == want.step
    assert not g.x.flags.writeable and np.array_equal(g.points(), want.points())
    with pytest.raises(ValueError, match="finite"):
        SearchGrid.centred([np.nan, 0.0, -50.0], 3.0, 4, lo=lo, hi=hi)


@pytest.mark.parametrize("grouped", [False, True])
def test_refinement_grids_give_the_column_arithmetic_bit_for_bit(grouped):
    """Without cached ranges (refinement grids) the intensities equal eq. (16) of
    :func:`tdoa_intensities` combined column-wise, bit for bit (ranges computed per sensor)."""
    w = window(RING, np.array([[300.0, -200.0, -900.0], [-500.0, 400.0, -1200.0]]),
               noise_range_s=(0.0, 5e-5))
    groups = np.repeat(np.arange((w.m + 1) // 2), 2)[:w.m] if grouped else None
    lo, hi = RING.min(axis=0) - 2000.0, RING.max(axis=0) + 2000.0
    for half in (4, 7):  # 729 points (one pass) and 3,375 (several)
        grid = SearchGrid.centred([250.0, -150.0, -950.0], 20.0, half, lo=lo, hi=hi)
        vol = intensity_volume(w, grid, equation=18, groups=groups, chunk_points=2000)
        sig = smoothing_sigma(w.sigmas, grid.step, c=C)
        want = [combine_intensities(tdoa_intensities(grid.points(a, a + 2000), w, sig), w, 18,
                                    groups) for a in range(0, grid.size, 2000)]
        assert np.array_equal(vol.values.reshape(-1), np.concatenate(want))
