"""Tests of the second link assignment (``relink_gate``), the end extension's eligible
detections (``end_detections``) and the causes of crossings not kept (issue 18)."""

import json
from types import SimpleNamespace

import numpy as np
import pytest

from factors.motion import transition_matrix, wna_covariance
from fusion.cli import main
from fusion.metrics.crossings import crossing_failure_causes, crossing_outcomes
from fusion.passive.smoothing import MultiTrackSmoother
from fusion.passive.smoothing.linking import link_segments

Q = 1e-10


def _end(s0, x0, s1, x1, p):
    return (s0, np.array(x0, float), p, s1, np.array(x1, float), p)


def _ends_with_d2(d2_target, scan_times):
    """Two segments: the first ends at scan 10, the second starts at scan 20 with a bearing
    offset giving the link the squared Mahalanobis distance `d2_target`."""
    p = np.diag([1e-6, 1e-10])
    dt = scan_times[20] - scan_times[10]
    f = transition_matrix(dt, 1)
    cov = f @ p @ f.T + wna_covariance(dt, Q, 1) + p
    delta = np.sqrt(d2_target / np.linalg.inv(cov)[0, 0])
    x_e = np.array([0.3, 1e-4])
    x_s = f @ x_e + np.array([delta, 0.0])
    a = _end(0, x_e - [10 * 10 * 1e-4, 0], 10, x_e, p)
    b = _end(20, x_s, 40, x_s + [20 * 10 * 1e-4, 0], p)
    return [a, b]


@pytest.mark.parametrize("d2", [50.0, 90.0])
def test_relink_gate_links_a_fragment_the_first_gate_rejects(d2):
    """A link of squared distance d2 in (link_gate, relink_gate] is made by the second
    assignment only; not above link_gate there is no second assignment."""
    scan_times = 10.0 * np.arange(60)
    ends = _ends_with_d2(d2, scan_times)
    kw = {"q": Q, "link_gate": 30.0, "max_gap_scans": 40}
    assert link_segments(ends, scan_times, **kw) == [[0], [1]]
    assert link_segments(ends, scan_times, relink_gate=30.0, **kw) == [[0], [1]]
    assert link_segments(ends, scan_times, relink_gate=100.0, **kw) == [[0, 1]]
    assert link_segments(_ends_with_d2(110.0, scan_times), scan_times, relink_gate=100.0,
                         **kw) == [[0], [1]]


def test_second_assignment_keeps_the_first_links():
    """Ends A, B and starts C, D: A->C passes the first gate (d2 25), B->D only the second
    (d2 60): both links made, A->C by the first assignment."""
    scan_times = 10.0 * np.arange(80)
    p = np.diag([1e-6, 1e-10])

    def start_at(x_e, s1, s0, d2):
        dt = scan_times[s0] - scan_times[s1]
        f = transition_matrix(dt, 1)
        cov = f @ p @ f.T + wna_covariance(dt, Q, 1) + p
        return f @ x_e + np.array([np.sqrt(d2 / np.linalg.inv(cov)[0, 0]), 0.0])

    xa, xb = np.array([0.30, 1e-4]), np.array([0.10, 1e-4])
    ends = [_end(0, xa, 10, xa, p), _end(0, xb, 10, xb, p)]
    xc = start_at(xa, 10, 20, 25.0)
    xd = start_at(xb, 10, 20, 60.0)
    ends += [_end(20, xc, 40, xc, p), _end(20, xd, 40, xd, p)]
    chains = link_segments(ends, scan_times, q=Q, link_gate=30.0, max_gap_scans=40,
                           relink_gate=100.0)
    assert sorted(chains) == [[0, 2], [1, 3]]


def _crossing_maneuver(seed=0):
    """Targets 0 and 1 cross at 600 s; target 0's bearing rate changes there from 1e-4 to
    1.2e-3 rad/s (too much for link_gate, within relink_gate)."""
    rng = np.random.default_rng(seed)
    ts = 10.0 * np.arange(120)
    a = np.where(ts < 600, 0.3 + 1e-4 * ts, 0.36 + 12e-4 * (ts - 600))
    t = np.repeat(ts, 2)
    lab = np.tile([0, 1], ts.size)
    z = np.where(lab == 0, np.repeat(a, 2), 0.42 - 1e-4 * t) + rng.normal(0, 0.004, t.size)
    return t, z, lab


def _maneuver():
    """One target, no crossing: its bearing rate changes from 1e-4 to 1.2e-3 rad/s in a
    15-scan gap without detections."""
    rng = np.random.default_rng(1)
    ts = 10.0 * np.arange(120)
    th = np.where(ts < 575, 0.3 + 1e-4 * ts, 0.3 + 1e-4 * 575 + 12e-4 * (ts - 575))
    keep = ~((ts >= 500) & (ts < 650))
    return ts[keep], th[keep] + rng.normal(0, 0.004, keep.sum())


KW_MTS = {"sigma_bearing": 0.004, "q": Q, "clutter_density": 0.1, "p_detect": 0.9}


@pytest.mark.parametrize("seed", [0, 1])
def test_smoother_relinks_a_fragment_across_a_crossing(seed):
    """Target 0 turns at the crossing: with relink_gate its segments after the crossing join
    its track before (two tracks, each target followed by one); without (relink_gate equal to
    link_gate) a third track starts after the crossing."""
    t, z, lab = _crossing_maneuver(seed)
    for gate, n_tracks in ((100.0, 2), (30.0, 3)):
        res = MultiTrackSmoother(relink_gate=gate, **KW_MTS).run(t, z)
        assert len(res.tracks) == n_tracks
        for k in (0, 1):
            before = res.labels[(lab == k) & (t < 500)]
            after = res.labels[(lab == k) & (t > 700)]
            same = np.bincount(before[before >= 0]).argmax() == np.bincount(
                after[after >= 0]).argmax()
            assert same == (gate == 100.0 or k == 1)


def test_second_assignment_only_across_a_crossing():
    """The same turn in a gap without any other track: the tracker ends the track and starts
    a new one; no ambiguous scan in the gap, so the wide gate does not link them (a track
    that ended and another that began, as on camera bearings of moored boats)."""
    t, z = _maneuver()
    mts = MultiTrackSmoother(max_misses=3, **KW_MTS)
    assert mts.tracker.run(t, z).n_tracks == 2
    assert len(mts.run(t, z).tracks) == 2


def test_cli_relink_gate_reaches_the_smoother(tmp_path):
    t, z, _ = _crossing_maneuver()
    src = tmp_path / "b.csv"
    src.write_text("track_id,time,bearing_deg\n" + "".join(
        f"-1,{a},{b}\n" for a, b in zip(t, np.degrees(z), strict=True)))
    n = {}
    for gate in ("30", "100"):
        out = tmp_path / f"s{gate}.csv"
        assert main(["smooth", "--bearings", str(src), "--out", str(out), "--quiet",
                     "--bearing-sigma-deg", "0.2292", "--accel-psd-deg2-per-s3", "3.283e-7",
                     "--clutter-density", "0.1", "--detection-probability", "0.9",
                     "--init-rate-sigma-deg-per-s", "0.573", "--max-misses", "5",
                     "--min-length", "5", "--merge-deg", "0", "--twin-deg", "0",
                     "--relink-gate", gate]) == 0
        _, *rows = out.read_text().splitlines()
        n[gate] = len({r.split(",")[0] for r in rows})
        meta = json.loads((tmp_path / f"s{gate}.settings.json").read_text())
        assert meta["relink_gate"] == float(gate) and meta["link_gate"] == 30.0
    assert n == {"30": 3, "100": 2}


@pytest.mark.parametrize(("option", "value", "message"), [
    ("--relink-gate", "-1", "--relink-gate: must be > 0"),
    ("--crossing-gap-scans", "0", "--crossing-gap-scans: must be >= 1"),
])
def test_cli_rejects_a_bad_link_option(tmp_path, capsys, option, value, message):
    src = tmp_path / "b.csv"
    src.write_text("track_id,time,bearing_deg\n-1,0,1\n-1,10,1.1\n")
    assert main(["smooth", "--bearings", str(src), "--out", str(tmp_path / "o.csv"),
                 option, value]) == 2
    assert message in capsys.readouterr().err


def test_end_detections_own_are_the_tracker_tracks_and_its_shared_ones():
    """``own``: the detections the tracker gave the end segment's tracker track or left
    shared with it as a candidate; ``tracked``: any the tracker took."""
    tr = SimpleNamespace(labels=np.array([0, 1, 0, -1, -1, 2, -1]),
                         candidates=((), (), (), (0, 1), (1, 2), (), ()))
    tracked = (tr.labels >= 0) | np.array([len(c) > 0 for c in tr.candidates])
    own = MultiTrackSmoother(sigma_bearing=0.01, q=Q)
    seg = np.array([2])  # a segment of tracker track 0
    assert own._eligible(tr, seg, tracked).tolist() == [1, 0, 1, 1, 0, 0, 0]
    wide = MultiTrackSmoother(sigma_bearing=0.01, q=Q, end_detections="tracked")
    assert wide._eligible(tr, seg, tracked).tolist() == tracked.tolist()
    with pytest.raises(ValueError, match="end_detections"):
        MultiTrackSmoother(sigma_bearing=0.01, q=Q, end_detections="any")


def _three_targets():
    """Targets 0, 1, 2 seen every 1 s from 0 to 99 s; 0 and 1 cross at 50 s."""
    t = np.repeat(np.arange(100.0), 3)
    true = np.tile([0, 1, 2], 100)
    return t, true


KW = {"guard_s": 5.0, "window_s": 20.0}


@pytest.mark.parametrize("case, rate, cause", [
    ("kept", 3.0, ""), ("swap", 3.0, "slow swap"), ("swap", 9.0, "swap"),
    ("late", 9.0, "late start"), ("merge", 9.0, "merge"), ("third", 9.0, "third-target swap"),
    ("fragment", 9.0, "fragmentation"), ("clutter", 9.0, "clutter capture"),
    ("dropped", 9.0, "dropped"),
])
def test_crossing_failure_causes_known_answers(case, rate, cause):
    t, true = _three_targets()
    est = true.copy()
    after = t > 55
    if case == "swap":
        est[after & (true == 0)], est[after & (true == 1)] = 1, 0
    elif case == "late":
        est[(true == 0) & (t < 45)] = -1
    elif case == "merge":
        est[after & (true == 1)] = 0
    elif case == "third":  # target 0 taken over by target 2's track, 2 by a new one
        est[after & (true == 0)] = 2
        est[after & (true == 2)] = 7
    elif case == "fragment":
        est[after & (true == 0)] = 7
    elif case == "clutter":  # track 0 alive after, on clutter; target 0 unlabelled
        est[after & (true == 0)] = -1
        t = np.r_[t, np.arange(56.0, 100.0)]
        true = np.r_[true, np.full(44, -1)]
        est = np.r_[est, np.zeros(44, int)]
    elif case == "dropped":
        est[after & (true == 0)] = -1
    cr = [(0, 1, 50.0)]
    got = crossing_failure_causes(true, est, t, cr, [rate], slow_deg_per_min=6.0, **KW)
    assert got == [cause]
    assert (cause == "") == (crossing_outcomes(true, est, t, cr, **KW)[0] == "kept")


def test_crossing_gap_scans_links_across_a_long_ambiguous_gap():
    """A gap of 50 scans across a crossing (relink_allowed): linked with crossing_gap_scans
    60, not with it off (None, or not above max_gap_scans), nor where the gap holds no
    ambiguous scan."""
    scan_times = 10.0 * np.arange(120)
    p = np.diag([1e-6, 1e-10])
    x_e = np.array([0.3, 1e-4])
    dt = scan_times[60] - scan_times[10]
    x_s = transition_matrix(dt, 1) @ x_e
    ends = [_end(0, x_e - [1e-2, 0], 10, x_e, p), _end(60, x_s, 80, x_s + [2e-2, 0], p)]
    kw = {"q": Q, "link_gate": 30.0, "max_gap_scans": 40, "relink_gate": 100.0}
    across = np.array([[False, True], [False, False]])
    assert link_segments(ends, scan_times, relink_allowed=across, crossing_gap_scans=60,
                         **kw) == [[0, 1]]
    assert link_segments(ends, scan_times, relink_allowed=across, **kw) == [[0], [1]]
    assert link_segments(ends, scan_times, relink_allowed=across, crossing_gap_scans=40,
                         **kw) == [[0], [1]]
    assert link_segments(ends, scan_times, relink_allowed=np.zeros((2, 2), bool),
                         crossing_gap_scans=60, **kw) == [[0], [1]]


def _slow_crossing(seed=0):
    """Targets 0 and 1 cross at 700 s at 5e-5 rad/s relative rate (0.17 deg/min): within the
    smoother's separation for more than 40 scans."""
    rng = np.random.default_rng(seed)
    ts = 10.0 * np.arange(140)
    t = np.repeat(ts, 2)
    lab = np.tile([0, 1], ts.size)
    z = np.where(lab == 0, 0.3 + 2.5e-5 * (t - 700), 0.3 - 2.5e-5 * (t - 700))
    return t, z + rng.normal(0, 0.004, t.size), lab


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_smoother_links_across_a_slow_crossing(seed):
    """With crossing_gap_scans 60 each target of a slow crossing is followed by one track
    before and after it (two tracks); with the gap limited to max_gap_scans (40) the
    tracks end at the ambiguous stretch and the targets after it get new ones (four
    tracks). Straight bearing lines: q small enough that the rates tell the pairs apart."""
    t, z, lab = _slow_crossing(seed)
    for gap, kept in ((60, True), (None, False)):
        res = MultiTrackSmoother(crossing_gap_scans=gap, **{**KW_MTS, "q": 1e-13}).run(t, z)
        follow = []
        for k in (0, 1):
            for sel in ((lab == k) & (t < 250), (lab == k) & (t > 1150)):
                lk = res.labels[sel]
                follow.append(np.bincount(lk[lk >= 0]).argmax() if (lk >= 0).any() else -1)
        same = follow[0] == follow[1] and follow[2] == follow[3] and follow[0] != follow[2]
        assert same == kept, (gap, follow, len(res.tracks))
        assert len(res.tracks) == (2 if kept else 4)


def test_cli_crossing_gap_scans_reaches_the_smoother(tmp_path):
    """``fusion smooth --crossing-gap-scans``: 60 (default) links the slow crossing's
    fragments (2 tracks), 40 (= --max-gap-scans: off) leaves 4; written to the settings."""
    t, z, _ = _slow_crossing(0)
    src = tmp_path / "b.csv"
    src.write_text("track_id,time,bearing_deg\n" + "".join(
        f"-1,{a},{b}\n" for a, b in zip(t, np.degrees(z), strict=True)))
    n = {}
    for gap in ("60", "40", None):
        out = tmp_path / f"s{gap}.csv"
        assert main(["smooth", "--bearings", str(src), "--out", str(out), "--quiet",
                     "--bearing-sigma-deg", "0.2292", "--accel-psd-deg2-per-s3", "3.283e-10",
                     "--clutter-density", "0.1", "--detection-probability", "0.9",
                     "--init-rate-sigma-deg-per-s", "0.573", "--max-misses", "5",
                     "--max-gap-scans", "40", "--min-length", "5", "--merge-deg", "0",
                     "--twin-deg", "0"] + ([] if gap is None else ["--crossing-gap-scans", gap])
                    ) == 0
        _, *rows = out.read_text().splitlines()
        n[gap] = len({r.split(",")[0] for r in rows})
        meta = json.loads((tmp_path / f"s{gap}.settings.json").read_text())
        assert meta["crossing_gap_scans"] == int(gap or 60)
    assert n == {"60": 2, "40": 4, None: 2}


def test_across_crossings_known_answer():
    """Pairs (end, start) whose gap (one scan of margin) holds an ambiguous scan of the end's
    or the start's tracker track: tracker track 0 is ambiguous at scan 5 only."""
    from fusion.passive.smoothing.segments import across_crossings

    ambiguous = np.zeros((2, 30), bool)
    ambiguous[0, 5] = True
    tr = SimpleNamespace(labels=np.array([0, 1, 1, 0]))
    segments = [np.array([0]), np.array([1]), np.array([2]), np.array([3])]
    # (first scan, ., ., last scan) of segments A (track 0), B (1), C (1), D (0)
    ends = [(0, None, None, 3), (8, None, None, 10), (12, None, None, 16),
            (20, None, None, 25)]
    out = across_crossings(ambiguous, tr, segments, ends)
    want = np.zeros((4, 4), bool)
    want[0, 1] = want[0, 2] = want[0, 3] = True  # gaps from scan 3 hold scan 5
    assert (out == want).all()
    ambiguous[1, 17] = True  # now the gaps of B -> D and C -> D hold track 1's scan 17
    want[1, 3] = want[2, 3] = True
    assert (across_crossings(ambiguous, tr, segments, ends) == want).all()
