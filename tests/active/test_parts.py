"""Tests of the tracker's parts on their own: types, association, lifecycle, bistatic model."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.active.association import PairRanker, assign_by_priority, derived_min_rank
from fusion.active.bistatic import MeasurementModel, bistatic_covariance
from fusion.active.lifecycle import Lifecycle, next_lifecycle
from fusion.active.motion import MotionTest, motion_statistic
from fusion.active.rulebase import default_association_system
from fusion.active.types import Ping, pings_from_columns
from fusion.io import Table


def test_pings_from_a_dict_equal_pings_from_a_table():
    """Any named columns will do: a dict and a fusion.io.Table give the same pings."""
    cols = {"event": np.array([3, 1, 1]), "time": np.array([30.0, 10.0, 10.0]),
            "x": np.array([1.0, 2.0, 3.0]), "y": np.array([4.0, 5.0, 6.0]),
            "snr_db": np.array([7.0, 8.0, 9.0]), "other": np.array([0.0, 0.0, 0.0])}
    a, b = pings_from_columns(cols), pings_from_columns(Table(cols))
    assert [(p.event, p.time, p.n) for p in a] == [(1, 10.0, 2), (2, 20.0, 0), (3, 30.0, 1)]
    for p, q in zip(a, b, strict=True):
        assert_allclose(p.xy, q.xy)
        assert set(p.clues) == {"snr_db"}
        assert_allclose(p.clues["snr_db"], q.clues["snr_db"])
    assert_allclose(a[0].xy, [[2.0, 5.0], [3.0, 6.0]])


def test_assign_by_priority_serves_the_first_group_first():
    """A detection both groups want goes to the first group even at a lower score; each
    detection is used once; -1 where nothing valid is left."""
    score = np.array([[0.5, 0.0], [0.9, 0.8], [0.7, 0.0]])
    valid = np.array([[True, False], [True, True], [True, False]])
    det = assign_by_priority(score, valid, np.array([True, False, False]))
    assert det.tolist() == [0, 1, -1]
    # one group: the largest summed score (0.8 + 0.7), not each row's best
    assert assign_by_priority(score, valid, np.zeros(3, dtype=bool)).tolist() == [-1, 1, 0]


def test_pair_ranker_threshold_and_options():
    """The threshold is the derived rank of the clue set (cached), or min_rank when given."""
    system = default_association_system()
    ranker = PairRanker(system)
    assert ranker.threshold(["snr_db"]) == pytest.approx(derived_min_rank(system, ["snr_db"]))
    assert set(ranker.thresholds) == {frozenset({"snr_db"})}
    assert PairRanker(system, min_rank=0.3).threshold(["snr_db"]) == 0.3
    with pytest.raises(ValueError, match="unknown clue"):
        PairRanker(system, clues=["colour"])
    with pytest.raises(ValueError, match="min_rank"):
        PairRanker(system, min_rank=1.5)


def test_motion_test_decides_from_three_detections():
    """None below three detections; True for a target moving 2 m/s under 100-m errors; False
    for a stationary one; the same statistic as motion_statistic."""
    test = MotionTest(probability=0.999)
    row = [0.0, 0.0, 0.0, 1e4, 0.0, 1e4]
    assert test.moves([row, row]) is None
    moving = [[t, 2.0 * t, 0.0, 1e4, 0.0, 1e4] for t in (0.0, 90.0, 180.0, 270.0)]
    still = [[t, 10.0 * (-1) ** i, 0.0, 1e4, 0.0, 1e4] for i, t in enumerate((0.0, 90.0, 180.0))]
    assert test.moves(moving) is True and test.moves(still) is False
    stat = motion_statistic([0, 90, 180, 270], [[0, 0], [180, 0], [360, 0], [540, 0]], 100.0)
    assert (stat > test.gate) is test.moves(moving)
    with pytest.raises(ValueError, match="motion_probability"):
        MotionTest(probability=1.0)


@pytest.mark.parametrize(("state", "hit", "dropped", "held", "expected"), [
    (Lifecycle("tentative", 2, 2, 0), True, True, False, Lifecycle("deleted", 3, 3, 0)),
    (Lifecycle("tentative", 2, 2, 0), True, False, True, Lifecycle("tentative", 3, 3, 0)),
    (Lifecycle("tentative", 4, 3, 4), False, False, False, Lifecycle("deleted", 5, 3, 5)),
    (Lifecycle("tentative", 4, 3, 1), False, False, False, Lifecycle("tentative", 5, 3, 2)),
    (Lifecycle("tentative", 2, 2, 0), True, False, False, Lifecycle("confirmed", 3, 3, 0)),
])
def test_next_lifecycle_table(state, hit, dropped, held, expected):
    """Hotspot drop, stationary hold, misses of a held track, and plain M-of-N (3 of 4, 5 misses)."""
    assert next_lifecycle(state, hit, dropped=dropped, held=held, m=3, n=4,
                          max_misses=5) == expected


def test_measurement_model_per_detection():
    """Geometric detections get the bistatic ellipse, the others position_sigma_m^2 I."""
    xy = np.array([[3000.0, 6000.0], [1000.0, 1000.0]])
    geo = {"src_x": np.zeros(2), "src_y": np.zeros(2), "rcv_x": np.array([5000.0, np.nan]),
           "rcv_y": np.zeros(2)}
    R, geometric = MeasurementModel(position_sigma_m=50.0, range_sum_sigma_m=30.0,
                                    bearing_sigma_deg=1.0).covariances(Ping(0, 0.0, xy, geo))
    assert geometric
    assert_allclose(R[0], bistatic_covariance(xy[:1], [0, 0], [5000, 0], 30.0, 1.0)[0])
    assert_allclose(R[1], np.eye(2) * 2500.0)
    with pytest.raises(ValueError, match="position_errors"):
        MeasurementModel(position_errors="round")
