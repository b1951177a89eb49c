"""Tests of the streamed crossing path: StreamingGrid, BearingStats, detect_crossings_streamed.

The reference for each is the whole-table path it replaces: ``resample_bearings``,
``estimate_period`` with the median track span, ``detect_crossings``. Equality is bitwise.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusion.passive.bearing_grid import estimate_period, resample_bearings
from fusion.passive.crossing import detect_crossings
from fusion.passive.crossing.stream import (
    GridAssumptionBroken,
    StreamingGrid,
    detect_crossings_streamed,
    scan_long_gaps,
)
from fusion.passive.crossing.summary import BearingStats
from fusion.simulate.bearings import simulate_bearings


def _chunks(tid, tt, bb, n):
    return [(tid[s:s + n], tt[s:s + n], bb[s:s + n]) for s in range(0, tid.size, n)]


def _streamed_grid(tid, tt, bb, *, K, gap, rows_per_chunk, scan=False):
    known = tid >= 0
    t0 = float(tt[known].min())
    gaps = (scan_long_gaps(_chunks(tid, tt, bb, rows_per_chunk), period_s=K, origin_s=t0,
                           max_gap_s=gap) if scan else None)
    grid = StreamingGrid(period_s=K, origin_s=t0, max_gap_s=gap, next_knots=gaps)
    parts = [grid.push(tid[s:s + rows_per_chunk], tt[s:s + rows_per_chunk],
                       bb[s:s + rows_per_chunk]) for s in range(0, tid.size, rows_per_chunk)]
    parts.append(grid.finish())
    return tuple(np.concatenate([p[i] for p in parts]) for i in range(3))


@st.composite
def bearing_tables(draw):
    """Small bearing tables in time order: 1-4 tracks, track -1 rows, gaps, jitter, dense runs."""
    n_tracks = draw(st.integers(1, 4))
    rows = []
    for k in range(n_tracks):
        start = draw(st.integers(0, 20))
        n = draw(st.integers(1, 40))
        step = draw(st.sampled_from([1.0, 0.5, 2.0, 0.3]))
        jitter = draw(st.sampled_from([0.0, 0.1, 1e-10]))
        rate = draw(st.floats(-40.0, 40.0))
        t = start + step * np.arange(n)
        t = t + jitter * np.sin(7.0 * np.arange(n) + k)
        if draw(st.booleans()):  # a gap
            cut = draw(st.integers(0, n))
            t[cut:] += draw(st.floats(0.5, 30.0))
        b = 350.0 + rate * t + k * 40.0  # through north, any wrap
        rows += [(k, ti, bi) for ti, bi in zip(t.tolist(), b.tolist(), strict=True)]
    for _ in range(draw(st.integers(0, 5))):
        rows.append((-1, draw(st.floats(0.0, 60.0)), 10.0))
    rows.sort(key=lambda r: r[1])
    tid = np.array([r[0] for r in rows], dtype=np.int64)
    tt = np.round(np.array([r[1] for r in rows]), 9)
    # distinct times within a labelled track, as the reader guarantees
    keep = np.ones(tid.size, bool)
    for k in range(n_tracks):
        idx = np.flatnonzero(tid == k)
        keep[idx[1:][np.diff(tt[idx]) <= 0]] = False
    return tid[keep], tt[keep], np.array([r[2] for r in rows])[keep]


@settings(max_examples=150, deadline=None)
@given(table=bearing_tables(), K=st.sampled_from([1.0, 0.7, 2.5, 0.1 * 3]),
       gap=st.sampled_from([None, 0.5, 4.0]), rows_per_chunk=st.integers(1, 9))
def test_streaming_grid_equals_resample_bearings(table, K, gap, rows_per_chunk):
    """Streamed grid rows equal resample_bearings' bit for bit (or a fallback is signalled)."""
    tid, tt, bb = table
    if not np.any(tid >= 0):
        return
    ref = resample_bearings(tid, tt, bb, period_s=K, max_gap_s=gap)
    try:
        got = _streamed_grid(tid, tt, bb, K=K, gap=gap, rows_per_chunk=rows_per_chunk)
    except GridAssumptionBroken:
        got = None
    if got is not None:
        for a, b in zip(got, (ref.track_id, ref.time, ref.bearing_deg), strict=True):
            np.testing.assert_array_equal(a, b)
    # read at once, or after a pass for the long gaps, nothing is assumed: always equal
    for got in (_streamed_grid(tid, tt, bb, K=K, gap=gap, rows_per_chunk=tid.size),
                _streamed_grid(tid, tt, bb, K=K, gap=gap, rows_per_chunk=rows_per_chunk,
                               scan=True)):
        for a, b in zip(got, (ref.track_id, ref.time, ref.bearing_deg), strict=True):
            np.testing.assert_array_equal(a, b)


def test_track_resuming_after_an_assumed_end_is_signalled():
    """A track silent a hair before a grid point, resuming late: signalled; exact after a scan."""
    K = 1.0
    t0 = np.arange(0.0, 60.0)  # track 0 keeps the grid going
    t1 = np.array([0.0, 1.0, 2.0, 3.0 - 1e-10, 55.0, 56.0])  # grid point 3 just after 3 - 1e-10
    tid = np.concatenate([np.zeros(t0.size, np.int64), np.ones(t1.size, np.int64)])
    tt = np.concatenate([t0, t1])
    bb = np.concatenate([10.0 + 0.1 * t0, 20.0 - 0.2 * t1])
    order = np.argsort(tt, kind="stable")
    tid, tt, bb = tid[order], tt[order], bb[order]
    with pytest.raises(GridAssumptionBroken, match="track 1 resumed"):
        _streamed_grid(tid, tt, bb, K=K, gap=None, rows_per_chunk=5)
    ref = resample_bearings(tid, tt, bb, period_s=K)
    for got in (_streamed_grid(tid, tt, bb, K=K, gap=None, rows_per_chunk=tid.size),
                _streamed_grid(tid, tt, bb, K=K, gap=None, rows_per_chunk=5, scan=True)):
        np.testing.assert_array_equal(got[2], ref.bearing_deg)
    # the value at the grid point after the pause is interpolated towards t = 55, not held
    at3 = (ref.track_id == 1) & (ref.time == 3.0)
    assert ref.bearing_deg[at3][0] != 20.0 - 0.2 * (3.0 - 1e-10)


def test_grid_refuses_rows_out_of_time_order():
    """Rows must come in non-decreasing time across pushes."""
    grid = StreamingGrid(period_s=1.0, origin_s=0.0)
    grid.push(np.array([0, 1]), np.array([0.0, 2.0]), np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match="non-decreasing time"):
        grid.push(np.array([0]), np.array([1.0]), np.array([1.0]))


@settings(max_examples=100, deadline=None)
@given(ids=st.lists(st.integers(-1, 5), min_size=2, max_size=60),
       rows_per_chunk=st.integers(1, 12), decimals=st.integers(0, 2))
def test_bearing_stats_equal_the_whole_table(ids, rows_per_chunk, decimals):
    """BearingStats gives estimate_period, the spans and the origin of the whole table exactly."""
    rng = np.random.default_rng(len(ids) * 13 + decimals)
    tid = np.array(ids, dtype=np.int64)
    tt = np.sort(np.round(rng.uniform(0.0, 50.0, tid.size), decimals))
    keep = np.ones(tid.size, bool)  # distinct times within a track
    for k in np.unique(tid[tid >= 0]):
        idx = np.flatnonzero(tid == k)
        keep[idx[1:][np.diff(tt[idx]) == 0]] = False
    tid, tt = tid[keep], tt[keep]
    stats = BearingStats()
    for s in range(0, tid.size, rows_per_chunk):
        stats.add(tid[s:s + rows_per_chunk], tt[s:s + rows_per_chunk])
    sm = stats.summary()
    known = tid >= 0
    try:
        step = estimate_period(tid[known], tt[known])
    except ValueError:
        step = None
    assert sm.step_s == step
    ids_known = np.unique(tid[known])
    np.testing.assert_array_equal(sm.track_ids, ids_known)
    np.testing.assert_array_equal(sm.spans_s, [np.ptp(tt[tid == k]) for k in ids_known])
    assert sm.n_unknown == int(np.sum(~known))
    assert sm.time_ordered
    if known.any():
        assert sm.t_min_s == tt[known].min()


def test_bearing_stats_notice_rows_not_in_time_order():
    """Tracks one after the other (each in order) are not in time order overall."""
    stats = BearingStats()
    stats.add(np.array([0, 0, 1]), np.array([0.0, 10.0, 0.0]))
    assert not stats.summary().time_ordered


@pytest.mark.parametrize("rows_per_chunk", [17, 400])
def test_detect_crossings_streamed_equals_the_batch_entry_point(rows_per_chunk):
    """The streamed alerts equal detect_crossings' on a simulated scenario, alert for alert."""
    sc = simulate_bearings(seed=4, n_tracks=6, duration_s=1200.0, sample_period_s=10.0,
                           p_detect=0.9, clutter_rate=0.5)
    order = np.lexsort((sc.track_id, sc.time))
    tid, tt, bb = sc.track_id[order], sc.time[order], sc.bearing_deg[order]
    opts = {"J": 10, "K": 10.0, "n_windows": 3, "level": 0.999, "confirm": 2}
    ref = detect_crossings({"track_id": tid, "time": tt, "bearing_deg": bb}, **opts)
    chunks = ((tid[s:s + rows_per_chunk], tt[s:s + rows_per_chunk], bb[s:s + rows_per_chunk])
              for s in range(0, tid.size, rows_per_chunk))
    got = detect_crossings_streamed(chunks, origin_s=float(tt[tid >= 0].min()), **opts)
    assert len(ref) >= 2
    assert got == ref
