"""Links refused when their path crosses scans with no detection (issue 18, link-path test)."""

import numpy as np
import pytest
from scipy.stats import binom

from fusion.passive.smoothing import MultiTrackSmoother
from fusion.passive.smoothing.linking import link_segments
from fusion.passive.smoothing.linkpath import (
    implausible_links,
    miss_tail_probability,
    path_misses,
    short_segment_path_test,
)

PERIOD = 10.0
SCAN_TIMES = PERIOD * np.arange(100)
RATE = 1e-3  # rad/s, the target's bearing rate
SIGMA = 0.005  # rad
Q = 1e-12  # rad^2/s^3
P_TIGHT = np.diag([1e-6, 1e-10])
P_WIDE = np.diag([SIGMA**2, 1e-7])  # a three-detection clutter segment: its rate barely known


def _end(s0, b0, r0, s1, b1, r1, p0=P_TIGHT, p1=P_TIGHT):
    return (s0, np.array([b0, r0]), p0.copy(), s1, np.array([b1, r1]), p1.copy())


def _target(scan):
    return RATE * SCAN_TIMES[scan]


def _scene():
    """A: the target's segment, scans 0-30; B: its segment after a crossing gap, 80-95;
    C, D: clutter segments of 3 detections (rates barely known, 0.3 rad off the target) at
    scans 60-63 and 45-48.
    The target is detected on every scan, the clutter segments' paths hold nothing."""
    ends = [_end(0, _target(0), RATE, 30, _target(30), RATE),
            _end(80, _target(80), RATE, 95, _target(95), RATE),
            _end(60, _target(60) - 0.3, 0.0, 63, _target(63) - 0.3, 0.0, P_WIDE, P_WIDE),
            _end(45, _target(45) + 0.3, 0.0, 48, _target(48) + 0.3, 0.0, P_WIDE, P_WIDE)]
    scans = np.arange(100)
    return ends, scans, _target(scans)


def test_the_tail_probability_is_the_binomial_survival():
    m, n = np.array([0, 1, 5, 9, 20]), np.array([10, 10, 10, 9, 20])
    got = miss_tail_probability(m, n, 0.8)
    want = binom.sf(m - 1, n, 0.2)
    assert got == pytest.approx(want, rel=1e-10)


def test_misses_are_counted_along_the_hermite_path():
    ends, scans, z = _scene()
    order = np.argsort(scans)
    ptr = np.searchsorted(scans[order], np.arange(SCAN_TIMES.size + 1))
    # the target's own link: 49 scans inside the gap, a detection on every one
    assert path_misses(ends[0], ends[1], SCAN_TIMES, ptr, z[order], q=Q, sigma=SIGMA) == (0, 49)
    # with its detections of scans 35-39 gone: 5 misses
    keep = (scans < 35) | (scans > 39)
    s2, z2 = scans[keep], z[keep]
    ptr2 = np.searchsorted(s2, np.arange(SCAN_TIMES.size + 1))
    assert path_misses(ends[0], ends[1], SCAN_TIMES, ptr2, z2, q=Q, sigma=SIGMA) == (5, 49)
    # a clutter link: the path from the target's end to D leaves the target's detections
    m, n = path_misses(ends[0], ends[3], SCAN_TIMES, ptr, z[order], q=Q, sigma=SIGMA)
    assert n == 14 and m >= 12
    # adjacent scans: no gap
    touching = _end(31, _target(31), RATE, 40, _target(40), RATE)
    assert path_misses(ends[0], touching, SCAN_TIMES, ptr, z[order], q=Q, sigma=SIGMA) == (0, 0)


def test_refused_links_are_not_made():
    ends, scans, z = _scene()
    bad = implausible_links(ends, np.array([0, 2, 0]), np.array([3, 1, 1]), SCAN_TIMES, scans,
                            z, q=Q, sigma=SIGMA, p_detect=0.8, alpha=1e-6)
    assert bad.tolist() == [True, True, False]
    # the same at a level no miss count reaches: nothing refused
    assert not implausible_links(ends, np.array([0, 2]), np.array([3, 1]), SCAN_TIMES, scans,
                                 z, q=Q, sigma=SIGMA, p_detect=0.8, alpha=1e-30).any()
    kw = dict(q=Q, link_gate=1e6, max_gap_scans=60)
    test = short_segment_path_test(ends, np.array([25, 40, 3, 3]), 10, SCAN_TIMES, scans, z,
                                   q=Q, sigma=SIGMA, p_detect=0.8, alpha=1e-6)
    chains = link_segments(ends, SCAN_TIMES, implausible=test, **kw)
    assert [0, 1] in chains
    # only links from or to a segment shorter than min_length are tested
    off = short_segment_path_test(ends, np.array([25, 40, 30, 30]), 10, SCAN_TIMES, scans, z,
                                  q=Q, sigma=SIGMA, p_detect=0.8, alpha=1e-6)
    assert link_segments(ends, SCAN_TIMES, implausible=off, **kw) == link_segments(
        ends, SCAN_TIMES, **kw)
    # every link refused: every segment alone
    none = link_segments(ends, SCAN_TIMES, implausible=lambda e, s: np.ones(e.size, bool),
                         **kw)
    assert sorted(none) == [[0], [1], [2], [3]]


def _scenario(seed):
    """The association benchmark's scenario of `seed` and the smoother it builds."""
    from fusion.passive.smoothing.settings import fit_smooth_settings
    from fusion.simulate.bearings import simulate_bearings

    rng = np.random.default_rng(seed)
    n_tracks, p_d, clutter = int(rng.integers(2, 7)), rng.uniform(0.7, 0.9), rng.uniform(0.5, 2)
    sc = simulate_bearings(seed=seed, n_tracks=n_tracks, n_crossing_pairs=n_tracks // 2,
                           n_wrap_crossings=1, n_near_miss_pairs=0, clutter_rate=clutter,
                           p_detect=p_d, noise_deg=float(rng.uniform(0.3, 1.0)))
    t, z = sc.time, np.radians(sc.bearing_deg)
    st = fit_smooth_settings(np.full(t.size, -1), t, z)
    deg2 = np.radians(1.0) ** 2

    def smoother(alpha):
        return MultiTrackSmoother(
            sigma_bearing=np.radians(st.sigma_bearing_deg), q=st.q_deg2_per_s3 * deg2,
            p_detect=st.p_detect, min_length=st.min_length,
            init_sigma_rate=np.radians(st.init_sigma_rate_deg_per_s),
            max_misses=st.max_misses, max_gap_scans=st.max_gap_scans, crossing_gap_scans=60,
            link_curvature=True, short_link_q=5e-4 * deg2, link_path_alpha=alpha)
    return sc, t, z, smoother


def test_the_clutter_links_of_seed_9874_are_refused():
    """Spent seed 9874: target 3's track before its crossing with target 2 ran on into
    clutter, and a chain of clutter segments took target 3 after it (a fragmentation)."""
    from fusion.metrics.crossings import crossing_outcomes

    sc, t, z, smoother = _scenario(9874)
    cr = [(c.track_a, c.track_b, c.t_cross) for c in sc.crossings]
    kw = {"guard_s": 15 * sc.sample_period_s, "window_s": 20 * sc.sample_period_s}
    i = next(k for k, c in enumerate(cr) if {c[0], c[1]} == {2, 3})
    off = crossing_outcomes(sc.track_id, smoother(0.0).run(t, z).labels, t, cr, **kw)
    on = crossing_outcomes(sc.track_id, smoother(1e-8).run(t, z).labels, t, cr, **kw)
    assert off[i] == "lost" and on[i] == "kept"
    assert np.sum(on == "kept") > np.sum(off == "kept")


def test_the_option_is_checked():
    with pytest.raises(ValueError, match="link_path_alpha"):
        MultiTrackSmoother(sigma_bearing=0.01, q=1e-10, link_path_alpha=1.0)
