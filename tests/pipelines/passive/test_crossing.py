"""Tests of the passive pipeline's crossing episodes."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from fusion.pipelines.passive.crossing import CrossingEpisode, CrossingResolver, EpisodeBook


def test_episode_book_opens_on_merge_and_closes_when_apart():
    """An episode opens when the pair's peaks merge (before its planned start) and closes
    after the crossing once they are apart for `clear_scans` scans."""
    book = EpisodeBook(separation_lobes=1.5, min_half_s=3.0, max_span_s=100.0, clear_scans=3)
    book.schedule((1, 2), now=0.0, t_cross=50.0, rate_diff=1e-3, beamwidth=0.01)  # half 15 s
    lobes = {1: 2.0, 2: 2.0}
    book.observe(10.0, {1: 10.0, 2: 20.0}, lobes)
    assert book.member_of(1) is None
    book.observe(11.0, {1: 10.0, 2: 12.0}, lobes)  # merged: opens early
    assert book.member_of(2) is not None and book.member_of(2).t_open == 11.0
    for t in range(12, 60):
        book.observe(float(t), {1: 15.0, 2: 15.0} if t < 52 else {1: 10.0, 2: 20.0}, lobes)
        due = book.close_due(float(t), ended=set())
        if due:
            break
    assert t == 54 and due[0].members == [1, 2] and due[0].t_close == 54.0
    assert book.episodes == []


def _crossing_episode(rng: np.random.Generator, *, unlabeled_swap: bool = False):
    """Two straight tracks crossing at t = 50 s with one detection per track and scan."""
    t_all = np.arange(0.0, 100.0)
    a = 1.0 + 0.002 * (t_all - 50.0)
    b = 1.0 - 0.002 * (t_all - 50.0)
    s = 0.003
    ep = CrossingEpisode(members=[3, 7], t_open=30.0, t_close=80.0, t_cross=50.0)
    ep.context = {3: [(t, a[int(t)] + s * rng.standard_normal(), s) for t in t_all[10:30]],
                  7: [(t, b[int(t)] + s * rng.standard_normal(), s) for t in t_all[10:30]]}
    for t in t_all[30:80]:
        k = int(t)
        for z in (a[k], b[k]):
            ep.detections.append((t, z + s * rng.standard_normal(), s))
        ep.predictions.setdefault(3, []).append((t, a[k], 2 * s))
        ep.predictions.setdefault(7, []).append((t, b[k], 2 * s))
    return ep, a, b


def test_resolver_assigns_detections_to_their_tracks():
    """Past the crossing, every detection assigned to a track lies on that track's line."""
    ep, a, b = _crossing_episode(np.random.default_rng(1))
    res, assigned = CrossingResolver().resolve(ep, scan_period=1.0, q=1e-9)
    assert set(assigned) == {3, 7} and res.tracks == (3, 7)
    assert res.method in ("multitrack", "nearest")
    for m, line in ((3, a), (7, b)):
        times, z, _ = assigned[m]
        late = times > 60.0
        assert late.sum() >= 15
        assert_allclose(z[late], line[times[late].astype(int)], atol=0.02)


def test_resolver_falls_back_to_predictions():
    """Without context bearings the multi-track match is impossible: nearest assignment."""
    ep, a, _ = _crossing_episode(np.random.default_rng(2))
    ep.context = {}
    res, assigned = CrossingResolver().resolve(ep, scan_period=1.0, q=1e-9)
    assert res.method == "nearest"
    times, z, _ = assigned[3]
    assert_allclose(z, a[times.astype(int)], atol=0.02)

