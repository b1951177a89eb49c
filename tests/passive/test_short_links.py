"""Late starts (issue 18): short chains linked to a later track, tracks extended backward."""

import numpy as np
import pytest

from fusion.passive.smoothing import MultiTrackSmoother
from fusion.passive.smoothing.linking import _link_distances
from fusion.passive.smoothing.rescue import link_short_chains
from fusion.pipelines.bearing_smoothing import SHORT_LINK_Q_DEG2_PER_S3, smooth_bearings

SCAN_TIMES = 10.0 * np.arange(100)
Q = 1e-10  # rad^2/s^3, the fitted white-noise acceleration of the tracker


P_END = np.diag([1e-6, 1e-9])  # end-state covariance, rad^2 and (rad/s)^2


def _end(s0, x0, s1, x1, p=P_END):
    return (s0, np.array(x0, float), p.copy(), s1, np.array(x1, float), p.copy())


def _ends():
    """Segment 0: a short chain (10 detections) ending at scan 20 with rate 5e-3 rad/s;
    segment 1: a long track starting at scan 33 where a rate falling to 1e-3 rad/s put the
    bearing (1.0 + 130 s x 3e-3, not the constant-rate 1.65); segment 2: a long track from
    scan 0 to 90 elsewhere; segment 3: a long chain ending at scan 25 near segment 1's start."""
    return [_end(0, [0.9, 5e-3], 20, [1.0, 5e-3]), _end(33, [1.39, 1e-3], 90, [1.45, 1e-3]),
            _end(0, [-1.0, 0.0], 90, [-1.0, 0.0]), _end(0, [1.2, 1e-3], 25, [1.3, 1e-3])]


def test_a_short_chain_whose_rate_fell_is_linked_with_the_link_acceleration_psd():
    ends = _ends()
    sizes = np.array([10, 50, 80, 30])
    chains = [[0], [1], [2], [3]]
    q_link = SHORT_LINK_Q_DEG2_PER_S3 * np.radians(1.0) ** 2
    # the constant-rate link with the tracker's q is far outside the gate ...
    d2_q, _ = _link_distances(ends, np.array([0]), np.array([1]), np.array([130.0]), Q,
                              np.zeros(4), np.zeros(4))
    assert d2_q[0] > 1e3
    d2_l, _ = _link_distances(ends, np.array([0]), np.array([1]), np.array([130.0]), q_link,
                              np.zeros(4), np.zeros(4))
    assert d2_l[0] < 30.0
    out = link_short_chains(chains, sizes, ends, SCAN_TIMES, q=Q, min_length=15, gate=30.0,
                            q_link=q_link, max_gap_scans=40)
    # ... with q_link the short chain joins the track that starts after it; the long chain
    # 3 (kept anyway) is not offered, the track of segment 2 overlaps in time
    assert sorted(out) == [[0, 1], [2], [3]]
    # off: q_link not above q, or no short chain
    assert link_short_chains(chains, sizes, ends, SCAN_TIMES, q=Q, min_length=15, gate=30.0,
                             q_link=Q, max_gap_scans=40) == chains
    assert link_short_chains(chains, sizes, ends, SCAN_TIMES, q=Q, min_length=5, gate=30.0,
                             q_link=q_link, max_gap_scans=40) == chains
    # beyond the longest gap: not linked
    assert link_short_chains(chains, sizes, ends, SCAN_TIMES, q=Q, min_length=15, gate=30.0,
                             q_link=q_link, max_gap_scans=10) == chains


def test_short_chains_link_through_each_other():
    """Three short pieces of one target and its later track become one chain."""
    ends = [_end(0, [0.0, 5e-4], 8, [0.04, 5e-4]), _end(10, [0.05, 5e-4], 16, [0.08, 5e-4]),
            _end(18, [0.09, 5e-4], 90, [0.45, 5e-4])]
    out = link_short_chains([[0], [1], [2]], np.array([6, 6, 60]), ends, SCAN_TIMES, q=Q,
                            min_length=15, gate=30.0, q_link=1e-7, max_gap_scans=40)
    assert out == [[0, 1, 2]]


def test_smoother_options_reach_the_short_chain_links():
    with pytest.raises(ValueError, match="short_link_q"):
        MultiTrackSmoother(sigma_bearing=0.01, q=1e-9, short_link_q=-1.0)
    assert MultiTrackSmoother(sigma_bearing=0.01, q=1e-9).short_link_q == 0.0


def _side_by_side():
    rng = np.random.default_rng(0)
    ts = 10.0 * np.arange(80)
    t = np.repeat(ts, 2)
    lab = np.tile([0, 1], ts.size)
    z = np.where(lab == 0, 0.30 + 1e-4 * t, 0.29 - 1e-4 * t) + rng.normal(0, 0.004, t.size)
    return t, z, lab


def test_start_extension_extends_only_the_start():
    """Two tracks that start side by side (see test_association): with extend_starts both
    begin at the first scan with their own early detections; without, they start later."""
    t, z, lab = _side_by_side()
    early = t < 100.0
    firsts = {}
    for ext in (True, False):
        res = MultiTrackSmoother(sigma_bearing=0.004, q=1e-10, clutter_density=0.1,
                                 p_detect=0.9, extend_starts=ext).run(t, z)
        assert len(res.tracks) == 2
        firsts[ext] = min(tr.times[0] for tr in res.tracks)
        if ext:
            for k in (0, 1):
                later = res.labels[(lab == k) & ~early]
                mine = np.bincount(later[later >= 0]).argmax()
                assert np.all(res.labels[(lab == k) & early] == mine)
    assert firsts[True] == 0.0 and firsts[False] >= 20.0


def test_pipeline_default_uses_the_short_chain_links(monkeypatch):
    """fusion smooth's library call: short-chain links on (SHORT_LINK_Q_DEG2_PER_S3, in
    rad^2/s^3 at the smoother), start extension off unless asked."""
    import fusion.pipelines.bearing_smoothing as pipe

    seen = []

    class Spy(MultiTrackSmoother):
        def __init__(self, **kw):
            seen.append(kw)
            super().__init__(**kw)

    monkeypatch.setattr(pipe, "MultiTrackSmoother", Spy)
    t, z, _ = _side_by_side()
    table = {"track_id": np.full(t.size, -1), "time": t, "bearing_deg": np.degrees(z)}
    res = smooth_bearings(table, extend_starts=True)
    assert min(tr.times[0] for tr in res.tracks) == 0.0
    smooth_bearings(table)
    assert SHORT_LINK_Q_DEG2_PER_S3 > 0
    assert seen[1]["short_link_q"] == pytest.approx(
        SHORT_LINK_Q_DEG2_PER_S3 * np.radians(1.0) ** 2)
    assert seen[0]["extend_starts"] and not seen[1]["extend_starts"]


def test_a_track_wound_over_a_turn_by_its_initial_line_gets_a_wrapped_prior():
    """A track made of clutter (a wrong short-chain link) has bearings spread over the circle;
    its unwrapped initial line wandered 1.8 turns (tuning seed 9208, ``short_link_q`` 3e-3
    deg^2/s^3) and the weak prior of its EM span was refused as "not radians". The prior's
    bearing is wrapped; the graph puts it on the branch of the first state anyway."""
    mts = MultiTrackSmoother(sigma_bearing=0.01, q=1e-10)
    init = np.array([[-11.207468687466752, 0.0], [-11.2, 0.0]])
    prior = mts._span_prior(init)
    assert prior.bearing == pytest.approx(-11.207468687466752 + 4 * np.pi)
    assert abs(prior.bearing) <= np.pi


def test_the_seed_that_raised_at_a_wide_short_link_psd_runs():
    from fusion.passive.smoothing.settings import fit_smooth_settings
    from fusion.simulate.bearings import simulate_bearings

    rng = np.random.default_rng(9208)  # the association benchmark's scenario of seed 9208
    n_tracks, p_d, clutter = int(rng.integers(2, 7)), rng.uniform(0.7, 0.9), rng.uniform(0.5, 2)
    sc = simulate_bearings(seed=9208, n_tracks=n_tracks, n_crossing_pairs=n_tracks // 2,
                           n_wrap_crossings=1, n_near_miss_pairs=0, clutter_rate=clutter,
                           p_detect=p_d, noise_deg=float(rng.uniform(0.3, 1.0)))
    t, z = sc.time, np.radians(sc.bearing_deg)
    st = fit_smooth_settings(np.full(t.size, -1), t, z)
    deg2 = np.radians(1.0) ** 2
    mts = MultiTrackSmoother(
        sigma_bearing=np.radians(st.sigma_bearing_deg), q=st.q_deg2_per_s3 * deg2,
        p_detect=st.p_detect, min_length=st.min_length,
        init_sigma_rate=np.radians(st.init_sigma_rate_deg_per_s), max_misses=st.max_misses,
        max_gap_scans=st.max_gap_scans, crossing_gap_scans=60, link_curvature=True,
        short_link_q=3e-3 * deg2)
    res = mts.run(t, z)
    assert len(res.tracks) >= n_tracks
    assert all(np.all(np.abs(tr.bearing) <= np.pi) for tr in res.tracks)
