"""Tests of the density clutter map and the clutter intensity (fusion.active.clutter)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.active.clutter import ClutterIntensity, DensityClutterMap
from fusion.active.motion import motion_statistic


def _ellipse(sig_long, sig_short, angle):
    c, s = np.cos(angle), np.sin(angle)
    V = np.array([[c, -s], [s, c]])
    return V @ np.diag([sig_long**2, sig_short**2]) @ V.T


def test_feature_seen_by_two_receivers_is_one_hotspot():
    """A feature echoing to two receivers whose error ellipses cross at right angles (300 x 80 m)
    is one hotspot from its min_pings-th ping on, centred on the feature, whatever the grid."""
    rng = np.random.default_rng(0)
    feat = np.array([2345.0, -1234.0])
    covs = np.stack([_ellipse(300, 80, 0.3), _ellipse(300, 80, 0.3 + np.pi / 2)])
    cmap = DensityClutterMap(min_pings=4)
    for k in range(8):
        xy = feat + np.stack([rng.multivariate_normal([0, 0], c) for c in covs])
        cmap.update(xy, 90.0 * k, cov=covs)
        assert (len(cmap.hotspots()) > 0) == (k >= 3), k
    spots = cmap.hotspots()
    assert len(spots) == 1
    assert_allclose(spots.positions[0], feat, atol=150)
    assert cmap.distance([feat])[0] == 0.0


def test_recurrence_counts_pings_not_echoes():
    """Three receivers echoing one place on one ping count once: recurrence 1 after a ping,
    n after n pings."""
    cmap = DensityClutterMap(position_sigma_m=50.0)
    for k in range(3):
        cmap.update(np.zeros((3, 2)) + [[0, 0], [10, 0], [0, 10]])
        assert np.all(cmap.recurrence() == k + 1)


def test_slow_target_is_no_hotspot_but_the_same_echoes_standing_still_are():
    """Echoes of a target at 1.5 m/s with 150-m errors (ping 90 s) recur on every ping for a
    while, but drift: no hotspot after 12 pings; the same scatter without the drift is one."""
    rng = np.random.default_rng(3)
    for speed, expect in ((1.5, 0), (0.0, 1)):
        cmap = DensityClutterMap()
        for k in range(12):
            xy = np.array([[speed * 90.0 * k, 0.0]]) + rng.normal(0, 150.0, (2, 2))
            cmap.update(xy, 90.0 * k, cov=np.broadcast_to(np.eye(2) * 150.0**2, (2, 2, 2)))
        assert len(cmap.hotspots()) == expect, speed
    # the drift the map sees is the one the motion statistic measures
    t = 90.0 * np.arange(12)
    q = motion_statistic(t, np.column_stack([1.5 * t, np.zeros(12)]), 150.0 / np.sqrt(2))
    assert q > 9.21


def test_random_clutter_makes_no_hotspot_and_huge_ellipses_are_not_stored():
    """Sparse uniform clutter does not recur at min_pings; echoes with a 2-km ellipse are left
    out (they would call the whole field one place)."""
    rng = np.random.default_rng(4)
    cmap = DensityClutterMap()
    for k in range(15):
        cmap.update(rng.uniform(-10000, 10000, (10, 2)), 90.0 * k)
    assert len(cmap.hotspots()) == 0
    cmap = DensityClutterMap()
    for k in range(8):
        cmap.update([[0.0, 0.0]], 90.0 * k, cov=[np.eye(2) * 2000.0**2])
    assert cmap.recurrence().size == 0 and len(cmap.hotspots()) == 0


def test_memory_forgets_old_pings():
    """With memory_pings = 4 a feature that stopped echoing six pings ago is forgotten."""
    cmap = DensityClutterMap(min_pings=3, memory_pings=4, position_sigma_m=30.0)
    for _ in range(5):
        cmap.update([[100.0, 100.0]])
    assert len(cmap.hotspots()) == 1
    for _ in range(6):
        cmap.update(np.zeros((0, 2)))
    assert len(cmap.hotspots()) == 0 and cmap.recurrence().size == 0
    assert cmap.empty_copy().memory_pings == 4


@pytest.mark.parametrize("kwargs, match", [
    ({"fraction": 1.0}, "fraction"), ({"min_pings": 0}, "min_pings"),
    ({"feature_sigma_m": -1.0}, "feature_sigma_m"), ({"max_sigma_m": 0.0}, "max_sigma_m"),
    ({"memory_pings": 1}, "memory_pings")])
def test_density_map_bad_options(kwargs, match):
    """Bad options raise ValueError naming the option."""
    with pytest.raises(ValueError, match=match):
        DensityClutterMap(**kwargs)


def test_density_map_bad_input():
    """Non-finite positions and covariances of the wrong shape raise ValueError."""
    cmap = DensityClutterMap()
    with pytest.raises(ValueError, match="finite"):
        cmap.update([[np.nan, 0.0]])
    with pytest.raises(ValueError, match="cov"):
        cmap.update([[0.0, 0.0]], cov=np.eye(2))


def test_intensity_of_uniform_clutter_known_answer():
    """Uniform clutter of 1 per km^2 per ping: the estimate away from the edges is 1e-6 per m^2
    (within 20 %), the floor outside; it counts pings, not detections per ping."""
    rng = np.random.default_rng(5)
    ci = ClutterIntensity(bandwidth_m=800.0)
    for _ in range(15):
        ci.update(rng.uniform(-10000, 10000, (400, 2)))
    lam = ci.intensity(rng.uniform(-5000, 5000, (50, 2)))
    assert np.mean(lam) == pytest.approx(1e-6, rel=0.1)
    assert np.all(np.abs(lam / 1e-6 - 1) < 0.2)
    assert ci.intensity([[1e6, 1e6]])[0] == ci.min_intensity
    assert ClutterIntensity().intensity([[0.0, 0.0]])[0] == ClutterIntensity().min_intensity


def test_intensity_kernel_known_answer():
    """One detection on each of two pings at the origin: lambda at the origin is
    N(0; 0, B) = 1 / (2 pi b^2) per ping, and exp(-1/2) of that one bandwidth away."""
    ci = ClutterIntensity(bandwidth_m=1000.0, min_intensity=1e-15)
    ci.update([[0.0, 0.0]])
    ci.update([[0.0, 0.0]])
    lam = ci.intensity([[0.0, 0.0], [1000.0, 0.0]])
    assert_allclose(lam[0], 1.0 / (2 * np.pi * 1e6), rtol=0.05)
    assert_allclose(lam[1] / lam[0], np.exp(-0.5), rtol=0.05)


def _mixed_pings(seed, n_pings):
    """Pings of three still features, a target at 2 m/s and uniform clutter, each echo with a
    bistatic-like ellipse (60-250 m), 60 s apart: (time, positions, covariances) per ping."""
    rng = np.random.default_rng(seed)
    feats = rng.uniform(-3000, 3000, (3, 2))
    for k in range(n_pings):
        t = 60.0 * k
        truth = np.concatenate([feats, [[-2000.0 + 2.0 * t, 500.0]],
                                rng.uniform(-4000, 4000, (rng.integers(2, 6), 2))])
        covs = np.stack([_ellipse(rng.uniform(80, 250), rng.uniform(60, 90), rng.uniform(0, 3))
                         for _ in truth])
        xy = np.stack([rng.multivariate_normal(p, c) for p, c in zip(truth, covs, strict=True)])
        yield t, xy, covs


def test_running_drift_sums_match_a_brute_force_window():
    """With pings forgotten (memory 6 of 25), after every ping each stored detection's
    neighbourhood, recurrence, drift-fit sums and drift verdict equal a brute-force
    recomputation over the remembered window (all pairs tested, fit by motion_statistic)."""
    cmap = DensityClutterMap(min_pings=3, memory_pings=6)
    g2 = cmap._g2
    F = np.eye(2) * cmap.feature_sigma_m**2
    window, verdicts = [], set()
    for k, (t, xy, covs) in enumerate(_mixed_pings(11, 25)):
        cmap.update(xy, t, cov=covs)
        window = (window + [(k, t, xy, covs)])[-6:]
        ping = np.concatenate([np.full(len(w[2]), w[0]) for w in window])
        tt = np.concatenate([np.full(len(w[2]), w[1]) for w in window])
        p = np.concatenate([w[2] for w in window])
        R = np.concatenate([w[3] for w in window])
        n = p.shape[0]
        assert_allclose(cmap._xy, p)
        linked = np.zeros((n, n), bool)
        for a in range(n):
            for b in range(n):
                if ping[a] != ping[b]:
                    d = p[a] - p[b]
                    linked[a, b] = d @ np.linalg.solve(R[a] + R[b] + 2 * F, d) <= g2
        rec = np.array([np.unique(np.append(ping[linked[a]], ping[a])).size for a in range(n)])
        assert np.array_equal(cmap.recurrence(), rec)
        assert np.array_equal(cmap._deg, linked.sum(axis=1))
        moving = cmap._drifting(np.arange(n))
        for a in range(n):
            member = np.append(a, np.flatnonzero(linked[a]))
            W = np.linalg.inv(R[member] + F)
            dt = tt[member] - tt[a]
            sums = np.concatenate([W.sum(0).ravel(), np.einsum("n,nij->ij", dt, W).ravel(),
                                   np.einsum("n,nij->ij", dt * dt, W).ravel(),
                                   np.einsum("nij,nj->i", W, p[member]),
                                   np.einsum("n,nij,nj->i", dt, W, p[member])])
            assert_allclose(cmap._mom[a], sums, rtol=1e-9, atol=1e-12)
            if member.size >= 3:
                q = motion_statistic(tt[member], p[member], cov=R[member] + F)
                if abs(q - cmap._drift_gate) > 1e-6 * cmap._drift_gate:
                    assert moving[a] == (q > cmap._drift_gate), (k, a, q)
                verdicts.add(bool(moving[a]))
            else:
                assert not moving[a]
    assert verdicts == {False, True}


class _RefitMap(DensityClutterMap):
    """The density map with every drift verdict refitted from scratch (no running sums)."""

    def _drifting(self, cand):
        return self._drifting_refit(cand)


def test_hotspots_equal_those_of_a_full_refit_every_ping():
    """Hotspots from the running drift sums are identical (exact equality) to those of the map
    that refits every neighbourhood from scratch, ping after ping, with and without memory."""
    for memory in (None, 5):
        fast = DensityClutterMap(min_pings=3, memory_pings=memory)
        slow = _RefitMap(min_pings=3, memory_pings=memory)
        n_spots = 0
        for t, xy, covs in _mixed_pings(12, 30):
            fast.update(xy, t, cov=covs)
            slow.update(xy, t, cov=covs)
            a, b = fast.hotspots(), slow.hotspots()
            assert np.array_equal(a.positions, b.positions)
            assert np.array_equal(a.covariances, b.covariances)
            assert np.array_equal(a.visits, b.visits) and np.array_equal(a.cells, b.cells)
            n_spots = max(n_spots, len(a))
        assert n_spots >= 2, memory
