"""The faster forms of the ping update give what the forms they replaced gave (issue 20, ping
speed): connected components of the clutter map's links, the clutter-intensity histogram, the
per-track measurements of a ping's result and the shadow test on candidate tracks."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter, map_coordinates
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from fusion.active.clutter.density import _components
from fusion.active.clutter.intensity import ClutterIntensity
from fusion.active.kalman import fuse_positions
from fusion.active.ping_scan import PingScan, ping_result
from fusion.active.shadow import ShadowTest
from fusion.active.types import Ping


def test_components_label_as_scipy_connected_components():
    rng = np.random.default_rng(3)
    for n, k in [(1, 0), (5, 0), (30, 12), (200, 150), (200, 400), (60, 59)]:
        if (n, k) == (60, 59):     # one long chain, listed from its far end
            edges = np.column_stack([np.arange(59, 0, -1), np.arange(58, -1, -1)])
        else:
            edges = rng.integers(0, n, (k, 2))
            edges = edges[edges[:, 0] != edges[:, 1]]
        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])) if len(edges)
                           else (np.zeros(0), (np.zeros(0, int), np.zeros(0, int))),
                           shape=(n, n))
        n_ref, ref = connected_components(graph, directed=False)
        n_got, got = _components(n, edges.astype(np.int32))
        assert n_got == n_ref
        np.testing.assert_array_equal(got, ref)


def test_intensity_equals_the_whole_grid_filter_read_bilinearly():
    rng = np.random.default_rng(1)
    ci = ClutterIntensity(bandwidth_m=500.0)
    for _ in range(4):
        ci.update(np.vstack([rng.uniform(-4000, 4000, (150, 2)), rng.normal(800, 300, (40, 2))]))
    hist, lo, cell = ci._smoothed()
    # The form replaced: four np.add.at passes, the whole grid filtered, read by
    # map_coordinates.
    pts = np.concatenate(ci._pings)
    u = (pts - lo) / cell - 0.5
    i0 = np.floor(u).astype(int)
    f = u - i0
    ref_hist = np.zeros(hist.shape)
    for di, wi in ((0, 1.0 - f[:, 0]), (1, f[:, 0])):
        for dj, wj in ((0, 1.0 - f[:, 1]), (1, f[:, 1])):
            np.add.at(ref_hist, (i0[:, 0] + di, i0[:, 1] + dj), wi * wj)
    np.testing.assert_array_equal(hist, ref_hist)
    dens = gaussian_filter(ref_hist, 500.0 / cell, mode="constant", truncate=4.0) / (cell * cell * 4)
    q = np.vstack([rng.uniform(-6000, 6000, (300, 2)), pts[:50], [[800.0, 800.0]]])
    ref = np.maximum(map_coordinates(dens, ((q - lo) / cell - 0.5).T, order=1, mode="constant"),
                     ci.min_intensity)
    got = ci.intensity(q)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * ref.max())
    assert got.max() > 5 * np.median(got)       # the cluster at (800, 800) stands out


def test_ping_result_measurements_single_and_fused():
    xy = np.array([[0.0, 0.0], [100.0, 50.0], [110.0, 40.0], [900.0, 900.0]])
    R = np.stack([np.diag([100.0, 400.0]), np.diag([200.0, 50.0]), np.diag([90.0, 90.0]),
                  np.eye(2)])
    ping = Ping(3, 30.0, xy, {})
    scan = PingScan(ping=ping, Rz=R, hot_d=np.full(4, np.inf), confirmed=np.zeros(3, bool),
                    dets=[[0], [], [1, 2]], rank=[0.5, np.nan, 0.7], rows=[])
    full_index = np.array([2, 4, 5, 7])
    res = ping_result(scan, full_index=full_index, track_id=np.array([10, 11, 12]),
                      state=np.zeros((3, 4)), covariance=np.zeros((3, 4, 4)),
                      status=np.array(["confirmed"] * 3), hotspots=np.zeros((0, 2)))
    np.testing.assert_array_equal(res.measurement[0], xy[0])
    np.testing.assert_array_equal(res.measurement_cov[0], R[0])
    assert np.isnan(res.measurement[1]).all() and np.isnan(res.measurement_cov[1]).all()
    z, C = fuse_positions(xy[1:3], R[1:3])
    np.testing.assert_array_equal(res.measurement[2], z)
    np.testing.assert_array_equal(res.measurement_cov[2], C)
    np.testing.assert_array_equal(res.detection, [2, -1, 4])
    assert [d.tolist() for d in res.detections] == [[2], [], [4, 5]]


def test_shadowed_tracks_equals_shadowed_at_each_latest_detection():
    st = ShadowTest(position_sigma_m=5.0)
    sensor = np.zeros(2)
    rng = np.random.default_rng(0)
    for _ in range(10):     # a confirmed track 200 m north, 20 m across
        st.learn(np.array([7]), np.array([[0.0, 200.0]]),
                 np.array([[rng.normal(0, 10), 200.0]]), [sensor])
    seen = [[[0, 0.0, 400.0, 0, 0, 0, 0.0, 0.0]], [],
            [[0, 300.0, 50.0, 0, 0, 0, 0.0, 0.0]], [[0, 1.0, 300.0, 0, 0, 0, 0.0, 0.0]]]
    cand = np.array([True, True, True, False])
    got = st.shadowed_tracks(cand, seen, [7], [[0.0, 200.0]])
    ref = st.shadowed([[0.0, 400.0], [np.nan, np.nan], [300.0, 50.0], [1.0, 300.0]],
                      [[0.0, 0.0]] * 4, [7], [[0.0, 200.0]])
    assert got.tolist() == [True, False, False, False]
    assert ref.tolist() == [True, False, False, True]     # the last is no candidate


def test_receiver_groups_as_the_dict_of_rounded_rows():
    from fusion.active.types import receiver_groups

    rng = np.random.default_rng(2)
    geos = np.array([[0.0, 0.0, 5000.0, 0.0], [0.0, -0.3, 5000.2, 0.0], [0.0, 0.0, 0.0, 4000.0],
                     [100.0, 0.0, 5000.0, 0.0]])
    pick = rng.integers(0, 4, 60)
    cols = {k: geos[pick, c] for c, k in enumerate(("src_x", "src_y", "rcv_x", "rcv_y"))}
    ping = Ping(0, 0.0, rng.uniform(0, 1000, (60, 2)), cols)
    ref: dict = {}
    for i, row in enumerate(map(tuple, np.round(geos[pick]).tolist())):
        ref.setdefault(row, []).append(i)          # -0.0 and 0.0: one key
    got = receiver_groups(ping)
    assert [k for k, _ in got] == list(ref)
    assert [idx.tolist() for _, idx in got] == list(ref.values())
