"""Tests of the platform-fixed test (fusion.active.platform) and its use by the tracker."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import chi2

from fusion.active.lifecycle import Lifecycle, stationary_hold
from fusion.active.motion import MotionTest, motion_statistic
from fusion.active.platform import PlatformTest, sensor_positions
from fusion.active.tracker import Tracker
from fusion.active.types import Ping, pings_from_columns
from fusion.io import read_detections, write_table

SIGMA = 2.0      # detection error per axis, m
PERIOD = 2.0     # scan period, s


def _rows(t, xy, sensor, sigma=SIGMA):
    """Rows (time, x, y, R_xx, R_xy, R_yy, sensor_x, sensor_y) of a track's detections."""
    n = len(t)
    return np.column_stack([t, xy, np.full(n, sigma**2), np.zeros(n), np.full(n, sigma**2),
                            sensor]).tolist()


def _scene(seed: int, *, sensor_speed: float, n_scans: int = 30) -> dict[str, np.ndarray]:
    """Detections of a sensor moving north: a return fixed 200 m east of it, a boat crossing
    the world at 4 m/s, and a little uniform clutter; own_x, own_y on every row."""
    rng = np.random.default_rng(seed)
    rows = []
    for k in range(n_scans):
        t = k * PERIOD
        own = np.array([0.0, sensor_speed * t])
        pts = [own + [200.0, 0.0], np.array([-300.0 + 4.0 * t, 150.0])]
        pts = [p + rng.normal(0.0, SIGMA, 2) for p in pts]
        pts += list(rng.uniform(-600.0, 600.0, (2, 2)))
        for p in pts:
            rows.append((k, t, p[0], p[1], own[0], own[1]))
    a = np.array(rows)
    return {"event": a[:, 0].astype(np.int64), "time": a[:, 1], "x": a[:, 2], "y": a[:, 3],
            "own_x": a[:, 4], "own_y": a[:, 5]}


def _confirmed_near(tracker: Tracker, cols, where) -> list[bool]:
    """For each function ``where(t) -> (x, y)``: was a track within 20 m of it confirmed?"""
    res = tracker.run(cols)
    out = []
    for f in where:
        hit = False
        for p in res.pings:
            c = p.status == "confirmed"
            if c.any():
                d = np.hypot(*(p.state[c, :2] - np.asarray(f(p.time))).T)
                hit |= bool(np.any(d < 20.0))
        out.append(hit)
    return out


def _tracker(**kw) -> Tracker:
    return Tracker(position_sigma_m=SIGMA, speed_sigma_mps=3.0, accel_psd=0.5, **kw)


def test_platform_fixed_return_is_fixed_and_moving_target_is_not():
    """Known answers: steady relative to a sensor moving 3 m/s -> True; a boat crossing the
    world -> False; a world-still object seen from the moving sensor -> False."""
    rng = np.random.default_rng(1)
    t = np.arange(6) * PERIOD
    sensor = np.column_stack([np.zeros(6), 3.0 * t])
    noise = rng.normal(0.0, SIGMA, (6, 2))
    test = PlatformTest()
    assert test.fixed(_rows(t, sensor + [200.0, 0.0] + noise, sensor)) is True
    assert test.fixed(_rows(t, np.column_stack([-300 + 4.0 * t, np.full(6, 150.0)]) + noise,
                            sensor)) is False
    assert test.fixed(_rows(t, np.array([50.0, 80.0]) + noise, sensor)) is False


def test_frames_not_distinguishable_gives_none():
    """A fixed sensor, one that moves less than the noise resolves, too few detections, or an
    unknown sensor position: no decision (None)."""
    t = np.arange(6) * PERIOD
    xy = np.column_stack([np.full(6, 200.0), np.zeros(6)])
    test = PlatformTest()
    assert test.fixed(_rows(t, xy, np.zeros((6, 2)))) is None
    crawl = np.column_stack([np.zeros(6), 0.05 * t])     # 0.5 m in 10 s against 2-m errors
    assert test.fixed(_rows(t, xy + crawl, crawl)) is None
    moving = np.column_stack([np.zeros(6), 3.0 * t])
    assert test.fixed(_rows(t[:2], xy[:2] + moving[:2], moving[:2])) is None
    assert test.fixed(_rows(t, xy + moving, np.full((6, 2), np.nan))) is None


def test_statistics_match_motion_statistic_in_each_frame():
    """Cross-check: the two statistics are motion_statistic of p - s and of s with the same
    isotropic errors (closed form), and the gate is the 2-dof chi-square quantile."""
    rng = np.random.default_rng(7)
    t = np.sort(rng.uniform(0.0, 20.0, 8))
    sensor = rng.normal(0.0, 30.0, (8, 2))
    xy = rng.normal(0.0, 100.0, (8, 2))
    test = PlatformTest(probability=0.99, min_speed_mps=0.3)
    q_rel, q_sensor = test.statistics(_rows(t, xy, sensor, sigma=5.0))
    assert_allclose(q_rel, motion_statistic(t, xy - sensor, 5.0, min_speed_mps=0.3), rtol=1e-9)
    assert_allclose(q_sensor, motion_statistic(t, sensor, 5.0, min_speed_mps=0.3), rtol=1e-9)
    assert_allclose(test.gate, chi2.ppf(0.99, 2))


def test_stationary_hold_holds_platform_fixed_track():
    """stationary_hold keeps a platform-fixed track tentative that the world test lets through."""
    t = np.arange(4) * PERIOD
    sensor = np.column_stack([np.zeros(4), 3.0 * t])
    seen = [_rows(t, sensor + [200.0, 0.0], sensor)]
    lives = [Lifecycle(hits=3)]
    cand = np.array([True])
    mt = MotionTest(min_speed_mps=0.5)
    assert not stationary_hold(cand, lives, seen, m=3, motion_test=mt, score_short=None)[0]
    assert stationary_hold(cand, lives, seen, m=3, motion_test=mt, score_short=None,
                           platform_test=PlatformTest(min_speed_mps=0.5))[0]


def test_tracker_rejects_platform_fixed_return_and_confirms_boat():
    """A sensor moving north at 3 m/s: the return fixed to it is never confirmed, the boat is;
    without the test the platform-fixed return is confirmed (the test decides)."""
    cols = _scene(3, sensor_speed=3.0)
    fixed = lambda t: (200.0, 3.0 * t)                    # noqa: E731
    boat = lambda t: (-300.0 + 4.0 * t, 150.0)            # noqa: E731
    assert _confirmed_near(_tracker(), cols, [fixed, boat]) == [False, True]
    assert _confirmed_near(_tracker(reject_platform_fixed=False), cols, [fixed, boat]) == [True, True]


def test_fixed_sensor_changes_nothing():
    """With a sensor that does not move the run is identical with and without sensor columns."""
    cols = _scene(5, sensor_speed=0.0)
    bare = {k: v for k, v in cols.items() if k not in ("own_x", "own_y")}
    a = _tracker().run(cols).columns()
    b = _tracker().run(bare).columns()
    for k in a:
        assert np.array_equal(a[k], b[k]), k


def test_sensor_positions_prefers_receiver_and_reader_keeps_own_columns(tmp_path):
    """rcv_x, rcv_y win over own_x, own_y; the detections reader carries own_x, own_y to pings."""
    p = Ping(0, 0.0, [[1.0, 2.0]], {"rcv_x": [5.0], "rcv_y": [6.0], "own_x": [7.0], "own_y": [8.0]})
    assert sensor_positions(p).tolist() == [[5.0, 6.0]]
    assert np.isnan(sensor_positions(Ping(0, 0.0, [[1.0, 2.0]]))).all()
    path = tmp_path / "d.csv"
    write_table(path, {"event": np.array([0, 1]), "time": np.array([0.0, 1.0]),
                       "x": np.array([1.0, 2.0]), "y": np.array([0.0, 0.0]),
                       "own_x": np.array([3.0, 4.0]), "own_y": np.array([5.0, 6.0])})
    pings = pings_from_columns(read_detections(path))
    assert [sensor_positions(q).tolist() for q in pings] == [[[3.0, 5.0]], [[4.0, 6.0]]]


@pytest.mark.parametrize("kw, match", [({"probability": 1.0}, "probability"),
                                       ({"min_detections": 1}, "min_detections"),
                                       ({"min_speed_mps": -1.0}, "min_speed_mps")])
def test_bad_options_raise(kw, match):
    """Invalid options raise ValueError naming the problem."""
    with pytest.raises(ValueError, match=match):
        PlatformTest(**kw)
