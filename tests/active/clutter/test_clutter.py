"""Tests of the online clutter map (fusion.active.clutter)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import chi2

from fusion.active.clutter import ClutterMap, floor_covariance


def test_fixed_feature_becomes_hotspot_at_its_centroid():
    """A point echoing on every ping is a hotspot from min_pings on, located at the mean echo."""
    rng = np.random.default_rng(1)
    cmap = ClutterMap(cell_m=150.0, fraction=0.5, min_pings=3)
    feature = np.array([1234.0, -567.0])
    echoes = []
    for k in range(5):
        xy = feature + rng.normal(0, 20.0, (2, 2))
        echoes.append(xy)
        cmap.update(xy)
        assert (len(cmap.hotspots()) > 0) == (k >= 2)
    spots = cmap.hotspots()
    assert_allclose(spots.positions, np.broadcast_to(feature, spots.positions.shape), atol=40)
    assert np.all(spots.visits == 5)
    assert cmap.distance([feature])[0] == 0.0


def test_moving_point_is_not_a_hotspot():
    """A target moving 400 m per ping never visits one neighbourhood on min_pings pings."""
    cmap = ClutterMap(cell_m=150.0, fraction=0.5, min_pings=3)
    for k in range(10):
        cmap.update([[400.0 * k, 0.0]])
    assert len(cmap.hotspots()) == 0
    assert np.isinf(cmap.distance([[0.0, 0.0]])).all()


def test_fraction_rule_known_answer():
    """Visits on 3 of 7 pings (not > 1/2) is no hotspot; on 4 of 7 it is."""
    for hits, expected in ((3, False), (4, True)):
        cmap = ClutterMap(cell_m=100.0, fraction=0.5, min_pings=3)
        for k in range(7):
            cmap.update([[50.0, 50.0]] if k < hits else np.zeros((0, 2)))
        assert (len(cmap.hotspots()) > 0) is expected
        assert cmap.n_pings == 7


def test_distance_matches_brute_force():
    """Distances equal a brute-force loop over hotspots of |p - c| (1 - g / m), clipped at 0."""
    rng = np.random.default_rng(7)
    cmap = ClutterMap(cell_m=100.0, fraction=0.5, min_pings=2, position_sigma_m=30.0)
    features = rng.uniform(-5000, 5000, (6, 2))
    for k in range(4):
        cmap.update(np.vstack([features + rng.normal(0, 20.0, features.shape),
                               rng.uniform(-5000, 5000, (10, 2))]), time=60.0 * k)
    spots = cmap.hotspots()
    assert len(spots) >= 6
    g = np.sqrt(chi2.ppf(0.99, 2))
    assert_allclose(spots.gate, g)
    pts = np.vstack([rng.uniform(-6000, 6000, (200, 2)), features])
    brute = np.full(len(pts), np.inf)
    for c, C in zip(spots.positions, spots.covariances, strict=True):
        d = pts - c
        m = np.sqrt(np.einsum("ni,ij,nj->n", d, np.linalg.inv(C), d))
        brute = np.minimum(brute, np.where(m > g, np.linalg.norm(d, axis=1) * (1 - g / m), 0.0))
    assert_allclose(cmap.distance(pts), brute, rtol=1e-9, atol=1e-9)
    assert np.all(cmap.distance(features) == 0.0)


def test_edge_echoes_of_a_spread_feature_are_near():
    """Echoes spread over several cells form ONE hotspot whose region reaches the spread's edge."""
    rng = np.random.default_rng(11)
    cmap = ClutterMap(cell_m=150.0, position_sigma_m=100.0)
    feature = np.array([2000.0, 3000.0])
    # Elongated spread (bistatic cross-range error): 250 m east-west, 60 m north-south.
    for k in range(12):
        cmap.update(feature + rng.normal(0, 1, (3, 2)) * [250.0, 60.0], time=90.0 * k)
    spots = cmap.hotspots()
    assert len(spots) == 1 and spots.cells[0] > 1
    sd = np.sqrt(np.diag(spots.covariances[0]))
    # x spread estimated from the hot cells (the far tail lies in cells that are not hot);
    # y floored at the position error.
    assert 130 < sd[0] < 330 and 95 < sd[1] < 130
    # An echo 600 m east (2.4 sigma) is "near" (< 100 m from the region: default near = 1);
    # 600 m north it is ~300 m beyond the region, about 900 m from a distance-to-centre "near".
    d = cmap.distance([feature + [600.0, 0.0], feature + [0.0, 600.0]])
    assert d[0] < 100.0
    assert 250 < d[1] < 350


def test_drifting_cluster_is_no_hotspot():
    """Three echoes per ping from a point moving 100 m per ping pass the count test on ping 3
    (indistinguishable from a fixed feature), then are a hotspot on few pings only, once the
    drift shows; the same echoes from a fixed point are a hotspot on every ping from ping 3."""
    rng = np.random.default_rng(1)
    moving, fixed = ClutterMap(), ClutterMap()
    flagged_moving, flagged_fixed = [], []
    for k in range(10):
        noise = rng.normal(0, 50.0, (3, 2))
        moving.update(np.array([100.0 * k, 0.0]) + noise, time=90.0 * k)
        fixed.update(noise, time=90.0 * k)
        flagged_moving.append(len(moving.hotspots()) > 0)
        flagged_fixed.append(len(fixed.hotspots()) > 0)
    assert flagged_fixed == [False, False] + [True] * 8
    assert flagged_moving[2] and not any(flagged_moving[4:])


@pytest.mark.parametrize("kwargs, match", [
    ({"cell_m": 0.0}, "cell_m"), ({"fraction": 1.0}, "fraction"), ({"min_pings": 0}, "min_pings"),
    ({"position_sigma_m": -1.0}, "position_sigma_m"), ({"extent_probability": 1.0}, "extent"),
    ({"drift_probability": 0.0}, "drift_probability"),
])
def test_bad_options(kwargs, match):
    """Invalid options raise ValueError naming the option."""
    with pytest.raises(ValueError, match=match):
        ClutterMap(**kwargs)


def test_non_finite_positions_rejected():
    """NaN positions raise ValueError."""
    with pytest.raises(ValueError, match="finite"):
        ClutterMap().update([[np.nan, 0.0]])


def test_hotspot_extent_floor_follows_the_detection_covariances():
    """Echoes of a feature with a tiny scatter but elongated error covariances: the hotspot
    extent is raised to the mean given covariance (rotated ellipse), not to a circle; without
    covariances the floor is position_sigma_m^2 I."""
    rng = np.random.default_rng(4)
    ang = np.radians(30.0)
    rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    err = rot @ np.diag([200.0**2, 40.0**2]) @ rot.T
    given, plain = ClutterMap(position_sigma_m=100.0), ClutterMap(position_sigma_m=100.0)
    for k in range(4):
        xy = np.array([500.0, 500.0]) + rng.normal(0, 5.0, (3, 2))
        given.update(xy, time=90.0 * k, cov=np.broadcast_to(err, (3, 2, 2)))
        plain.update(xy, time=90.0 * k)
    assert_allclose(given.hotspots().covariances[0], err, rtol=1e-6)
    assert_allclose(plain.hotspots().covariances[0], np.eye(2) * 100.0**2, rtol=1e-6)


def test_floor_contains_both_ellipses():
    """The floored covariance is >= the sample covariance and >= the error covariance (Loewner
    order), and equals the eigenvalue floor for an isotropic error."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        A, B = rng.normal(0, 100, (2, 2, 2))
        C, E = A @ A.T, B @ B.T + np.eye(2)
        F = floor_covariance(C[None], E[None])[0]
        assert np.linalg.eigvalsh(F - C).min() > -1e-6 * np.abs(F).max()
        assert np.linalg.eigvalsh(F - E).min() > -1e-6 * np.abs(F).max()
    C = np.array([[300.0, 100.0], [100.0, 50.0]]) * 100
    w, v = np.linalg.eigh(C)
    expect = v @ np.diag(np.maximum(w, 100.0**2)) @ v.T
    assert_allclose(floor_covariance(C[None], np.eye(2)[None] * 1e4)[0], expect)


def test_bad_covariances_rejected():
    """A covariance array of the wrong shape or not positive definite raises ValueError."""
    with pytest.raises(ValueError, match="cov"):
        ClutterMap().update([[0.0, 0.0]], cov=np.eye(2))
    with pytest.raises(ValueError, match="positive definite"):
        ClutterMap().update([[0.0, 0.0]], cov=np.zeros((1, 2, 2)))
