"""Tests of the association weights of shared bearings (issue 18), the well-posed linear solves,
the crossing-window metrics and the grid output of fusion smooth."""

import itertools

import numpy as np
import pytest
from numpy.testing import assert_allclose

from factors.motion import transition_matrix, wna_covariance
from fusion.cli import main
from fusion.metrics.crossings import crossing_bearing_errors, crossing_window_identity
from fusion.passive.smoothing import MultiTrackSmoother, TrackPrior
from fusion.passive.smoothing.association import (
    clutter_and_detection,
    joint_weights,
    nearest_weights,
)
from fusion.passive.smoothing.graph import _Measurements, _Model, _solve
from fusion.passive.smoothing.grid import on_grid
from fusion.passive.smoothing.settings import fit_smooth_settings
from fusion.passive.smoothing.types import SmoothedTrack

SIG = 0.01


def _brute_joint(dets, tracks, g, p_d, lam):
    """Marginal association probabilities by enumerating every assignment vector."""
    acc = {k: 0.0 for k in g}
    total = 0.0
    for choice in itertools.product([None, *tracks], repeat=len(dets)):
        used = [m for m in choice if m is not None]
        if len(used) != len(set(used)) or any(
                m is not None and (j, m) not in g for j, m in zip(dets, choice, strict=True)):
            continue
        p = (1 - p_d) ** (len(tracks) - len(used))
        for j, m in zip(dets, choice, strict=True):
            p *= lam if m is None else p_d * g[(j, m)]
        total += p
        for j, m in zip(dets, choice, strict=True):
            if m is not None:
                acc[(j, m)] += p
    return {k: v / total for k, v in acc.items()}


@pytest.mark.parametrize("seed", range(6))
def test_joint_weights_equal_brute_force_enumeration(seed):
    rng = np.random.default_rng(seed)
    scan, det, track, dens = [], [], [], []
    for s in range(3):
        dets = list(range(10 * s, 10 * s + int(rng.integers(1, 5))))
        tracks = list(range(int(rng.integers(1, 4))))
        for j in dets:
            for m in tracks:
                if rng.random() < 0.8:
                    scan.append(s)
                    det.append(j)
                    track.append(m)
                    dens.append(rng.uniform(0.1, 40.0))
    scan, det, track, dens = map(np.array, (scan, det, track, dens))
    w, n_approx = joint_weights(scan, det, track, dens, p_detect=0.8, clutter_density=0.7)
    assert n_approx == 0
    for s in np.unique(scan):
        rows = np.flatnonzero(scan == s)
        g = {(int(det[r]), int(track[r])): float(dens[r]) for r in rows}
        ref = _brute_joint(sorted(set(det[rows].tolist())), sorted(set(track[rows].tolist())),
                           g, 0.8, 0.7)
        for r in rows:
            assert w[r] == pytest.approx(ref[(int(det[r]), int(track[r]))], rel=1e-12)
    # per detection the probabilities sum to at most one (the rest is clutter)
    assert np.all(np.bincount(det, weights=w) <= 1 + 1e-12)


def test_joint_weights_one_track_is_the_pda_formula():
    """One track: beta_j = P_D g_j / ((1 - P_D) lambda + sum_k P_D g_k) (known answer)."""
    g = np.array([3.0, 10.0, 0.5])
    w, _ = joint_weights(np.zeros(3, int), np.arange(3), np.zeros(3, int), g, p_detect=0.7,
                         clutter_density=2.0)
    assert_allclose(w, 0.7 * g / (0.3 * 2.0 + 0.7 * g.sum()), rtol=1e-12)


def test_busy_scans_get_per_detection_responsibilities_and_are_counted():
    n = 9
    w, n_approx = joint_weights(np.zeros(n, int), np.arange(n), np.zeros(n, int),
                                np.full(n, 5.0), p_detect=0.9, clutter_density=1.0,
                                max_joint=7)
    assert n_approx == 1
    assert_allclose(w, 0.9 * 5.0 / (1.0 + 0.9 * 5.0))


def test_nearest_weights_are_the_least_cost_gated_assignment():
    rng = np.random.default_rng(3)
    det = np.repeat(np.arange(4), 3)
    track = np.tile(np.arange(3), 4)
    d2 = rng.uniform(0, 20, det.size)
    w = nearest_weights(np.zeros(det.size, int), det, track, d2, gate=4.0)
    assert set(np.unique(w)) <= {0.0, 1.0}
    best = None  # brute force: assignments of tracks to distinct detections, gated
    for perm in itertools.permutations(range(4), 3):
        cost = sum(d2[perm[m] * 3 + m] if d2[perm[m] * 3 + m] <= 16 else 1e12 for m in range(3))
        if best is None or cost < best[0]:
            best = (cost, perm)
    chosen = {(best[1][m], m) for m in range(3) if d2[best[1][m] * 3 + m] <= 16}
    assert {(int(j), int(m)) for j, m, x in zip(det, track, w, strict=True) if x} == chosen


def test_clutter_and_detection_counts():
    # 10 scans, one track in scans 0-9 detected in 8 (one gap scan released), 5 clutter rows
    scan_of = np.r_[np.arange(8), 8, np.arange(5)]
    labels = np.r_[np.zeros(8, int), -1, np.full(5, -1)]
    released = np.r_[np.zeros(8, bool), True, np.zeros(5, bool)]
    z = np.r_[np.zeros(9), np.linspace(-np.pi + 0.01, np.pi - 0.01, 5)]
    lam, pd = clutter_and_detection(labels, scan_of, np.array([0]), np.array([9]), released, z)
    assert pd == pytest.approx(8 / 9)  # 10 scans of life, 1 gap scan left out
    arc = 2 * np.pi - 2 * (np.pi - 0.01 - np.linspace(-np.pi + 0.01, np.pi - 0.01, 5)[3])
    assert lam == pytest.approx(5 / (10 * max(arc, 2 * np.pi - (np.pi / 2 - 0.005) - 0.02)),
                                rel=0.2)


def test_ill_conditioned_chain_is_solved_and_equals_dense_least_squares():
    """A rigid chain (q 1e-10 rad^2/s^3, 1 s steps) with one bearing and a weak prior made
    GTSAM's Cholesky throw "Indeterminate linear system" (issue 18, the crossing episodes of the
    hard passive benchmark); the QR solve must give the dense least-squares answer."""
    n, q = 12, 9.4e-11
    times = np.arange(n, dtype=float)
    meas = _Measurements(state=np.array([5]), bearing=np.array([1.40]))
    prior = TrackPrior(bearing=1.441, rate=0.0, sigma_bearing=0.16, sigma_rate=0.01)
    model = _Model(sigma_bearing=0.016, q=q, loss="none", k=1.345, max_iterations=50)
    states, sig = _solve(times, meas, prior, model, marginals=True)
    # dense whitened least squares over the 2n unknowns
    rows, rhs = [], []
    a = np.zeros(2 * n)
    a[0] = 1 / 0.16
    rows.append(a)
    rhs.append(1.441 / 0.16)
    a = np.zeros(2 * n)
    a[1] = 1 / 0.01
    rows.append(a)
    rhs.append(0.0)
    li = np.linalg.cholesky(np.linalg.inv(wna_covariance(1.0, q, 1))).T
    f = transition_matrix(1.0, 1)
    for k in range(n - 1):
        blk = np.zeros((2, 2 * n))
        blk[:, 2 * k: 2 * k + 2] = -li @ f
        blk[:, 2 * k + 2: 2 * k + 4] = li
        rows.extend(blk)
        rhs.extend([0.0, 0.0])
    a = np.zeros(2 * n)
    a[10] = 1 / 0.016
    rows.append(a)
    rhs.append(1.40 / 0.016)
    x = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0].reshape(n, 2)
    assert_allclose(states, x, atol=1e-7)
    assert np.all(np.isfinite(sig))


def _crossing(seed, p_detect=0.8, clutter=1.0, n=60):
    rng = np.random.default_rng(seed)
    t_s = 10.0 * np.arange(n)
    truth = np.array([0.30 + 0.0004 * (t_s - 300.0), 0.30 - 0.0004 * (t_s - 300.0)])
    t, z, lab = [], [], []
    for k, tk in enumerate(t_s):
        for a in (0, 1):
            if rng.random() < p_detect:
                t.append(tk)
                z.append(truth[a, k] + rng.normal(0, SIG))
                lab.append(a)
        for _ in range(rng.poisson(clutter)):
            t.append(tk)
            z.append(rng.uniform(-np.pi, np.pi))
            lab.append(-1)
    return np.array(t), np.array(z), np.array(lab), truth, t_s


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_weights_are_posterior_probabilities_not_hard_assignment(seed):
    """The settled weights of the shared detections are the joint-event posteriors at the
    tracks' bearings (EM fixed point), fractional near the crossing; with nearest assignment
    they are 0/1 and the smoothed tracks differ. Fails if the weights are replaced by a hard
    assignment."""
    t, z, lab, _, _ = _crossing(seed)
    kw = {"sigma_bearing": SIG, "q": 1e-9, "clutter_density": None, "p_detect": None}
    wres = MultiTrackSmoother(association="weighted", **kw).run(t, z)
    nres = MultiTrackSmoother(association="nearest", **kw).run(t, z)
    det, trk, w = wres.pairs
    assert det.size > 0
    assert np.any((w > 0.05) & (w < 0.95))  # fractional: not a hard assignment
    assert set(np.unique(nres.pairs[2])) <= {0.0, 1.0}
    assert 0.3 < wres.p_detect < 1.0 and wres.clutter_density > 0  # counted from the data
    # EM fixed point: recomputed at the final tracks' bearings, the weights barely move
    theta = np.array([np.interp(t[j], wres.tracks[m].times, np.unwrap(wres.tracks[m].bearing))
                      for j, m in zip(det, trk, strict=True)])
    nu = np.angle(np.exp(1j * (z[det] - theta)))
    dens = np.exp(-0.5 * (nu / SIG) ** 2) / (np.sqrt(2 * np.pi) * SIG)
    scan = np.searchsorted(np.unique(t), t[det])
    again, _ = joint_weights(scan, det, trk, dens, p_detect=wres.p_detect,
                             clutter_density=wres.clutter_density)
    assert np.max(np.abs(again - w)) < 0.15
    # the weights change the smoothed bearings
    diff = max(np.max(np.abs(a.bearing - b.bearing)) for a, b in
               zip(wres.tracks, nres.tracks, strict=False) if a.times.size == b.times.size)
    assert diff > 1e-6


def test_crossing_bearing_errors_known_answer():
    t = np.repeat(np.arange(10.0), 2)
    true = np.tile([0, 1], 10)
    tracks = {0: (np.arange(10.0), np.full(10, 0.1)), 1: (np.arange(10.0), np.full(10, 0.3))}
    truth = {0: np.full(10, 0.0), 1: np.full(10, 0.5)}
    e = crossing_bearing_errors(true, true, t, [(0, 1, 5.0)], tracks, np.arange(10.0), truth,
                                within_s=2.0, guard_s=1.0, window_s=3.0)
    assert_allclose(e, np.r_[np.full(5, 0.1), np.full(5, -0.2)])
    # a target followed by no track before the crossing is not covered
    est = np.where(true == 1, -1, true)
    e = crossing_bearing_errors(true, est, t, [(0, 1, 5.0)], tracks, np.arange(10.0), truth,
                                within_s=2.0, guard_s=1.0, window_s=3.0)
    assert np.isnan(e[5:]).all() and np.isfinite(e[:5]).all()
    assert crossing_window_identity(true, est, t, [(0, 1, 5.0)], guard_s=1.0,
                                    window_s=3.0).tolist() == [[6, 3]]


def test_on_grid_equals_the_smoother_with_states_at_the_grid_times():
    """GP interpolation of the smoothed states = the batch graph solved with extra,
    measurement-free states at the grid times (linear Gaussian: exact)."""
    rng = np.random.default_rng(4)
    td = np.r_[0.0, 3.0, 7.0, 10.0, 31.0, 34.0, 40.0]  # a gap of 21 s
    zd = 0.2 + 0.002 * td + rng.normal(0, SIG, td.size)
    model = _Model(sigma_bearing=SIG, q=1e-7, loss="none", k=1.345, max_iterations=50)
    prior = TrackPrior(bearing=0.2, rate=0.0, sigma_bearing=0.1, sigma_rate=0.01)
    xs, sg = _solve(td, _Measurements(np.arange(td.size), zd), prior, model, marginals=True)
    tr = SmoothedTrack(0, td, xs[:, 0], xs[:, 1], sg[:, 0], sg[:, 1])
    g = on_grid(tr, period=5.0, q=1e-7, max_gap_s=30.0)
    assert_allclose(g.times, 5.0 * np.arange(9))
    allt = np.union1d(td, g.times)
    xa, sa = _solve(allt, _Measurements(np.searchsorted(allt, td), zd), prior, model,
                    marginals=True)
    k = np.searchsorted(allt, g.times)
    assert_allclose(g.bearing, xa[k, 0], atol=1e-9)
    assert_allclose(g.rate, xa[k, 1], atol=1e-11)
    assert_allclose(g.sigma_bearing, sa[k, 0], rtol=0.35)  # neighbours' correlation left out
    # a gap longer than max_gap_s gets no grid points
    assert on_grid(tr, period=5.0, q=1e-7, max_gap_s=15.0).times.tolist() == [
        0.0, 5.0, 10.0, 35.0, 40.0]


def test_period_pools_labelled_rows_with_unknown_ones():
    ids = np.r_[np.full(5, -1), np.zeros(20, int)]
    t = np.r_[0.0, 4.0, 8.0, 12.0, 16.0, np.arange(20.0)]
    z = np.r_[np.zeros(5), 0.001 * np.arange(20.0)]
    assert fit_smooth_settings(ids, t, z).period_s == 1.0
    assert fit_smooth_settings(ids, t, z, period_s=2.0).period_s == 2.0


def test_cli_smooth_writes_tracks_on_the_grid(tmp_path):
    t, z, lab, _, _ = _crossing(5, p_detect=0.9, clutter=0.3)
    src = tmp_path / "b.csv"
    lines = ["track_id,time,bearing_deg"] + [
        f"-1,{a},{b}" for a, b in zip(t, np.degrees(z), strict=True)]
    lines += ["7,3.0,10.0", "7,13.0,10.5", "7,43.0,12.0"]  # a 30 s gap
    src.write_text("\n".join(lines) + "\n")
    out = tmp_path / "s.csv"
    assert main(["smooth", "--bearings", str(src), "--out", str(out), "--period-s", "5",
                 "--association", "nearest", "--output-times", "grid"]) == 0
    head, *rows = out.read_text().splitlines()
    arr = np.array([list(map(float, r.split(","))) for r in rows])
    assert_allclose(np.mod(arr[:, 1], 5.0), 0.0)  # every row on the grid 0, 5, 10, ...
    r7 = arr[arr[:, 0] == 7]
    assert r7[:, 1].tolist() == [5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0]
    assert np.all(r7[:, 4] > 0)


def test_gaussian_weighted_bearings_equal_the_weighted_factor_path():
    """A weight w on a Gaussian bearing factor is the factor with sigma / sqrt(w): the graph
    built that way has the same optimum as the one through factors.weighted.weighted_factor
    (taken with a Huber loss whose threshold no residual reaches)."""
    rng = np.random.default_rng(7)
    times = 10.0 * np.arange(30)
    truth = 0.3 + 1e-3 * times
    state = np.r_[np.arange(30), np.arange(10, 20)]
    z = np.r_[truth, truth[10:20] + 0.02] + rng.normal(0, SIG, 40)
    widx = np.r_[np.full(30, -1), np.arange(10)]
    weights = rng.uniform(0.0, 1.0, 10)
    weights[3] = 0.0
    meas = _Measurements(state=state, bearing=z, weight_index=widx)
    gauss = _Model(sigma_bearing=SIG, q=1e-9, loss="none", k=1.345, max_iterations=100)
    wide = _Model(sigma_bearing=SIG, q=1e-9, loss="huber", k=1e6, max_iterations=100)
    a, sa = _solve(times, meas, None, gauss, weights=weights, marginals=True)
    b, sb = _solve(times, meas, None, wide, weights=weights, marginals=True)
    assert_allclose(a, b, atol=1e-9)
    assert_allclose(sa, sb, rtol=1e-6)
    c, _ = _solve(times, meas, None, gauss, weights=np.ones(10))
    assert np.max(np.abs(c[10:20, 0] - a[10:20, 0])) > 1e-4  # the weights matter


def test_one_detection_scans_equal_the_joint_event_enumeration_exactly():
    """Scans with one shared detection take a short path; it must give the enumeration's
    numbers to the last bit (same products, same order)."""
    from fusion.passive.smoothing.association import _events

    rng = np.random.default_rng(11)
    scan = np.repeat(np.arange(40), 3)
    det = np.repeat(np.arange(40), 3)
    track = np.tile([2, 0, 1], 40)
    dens = rng.uniform(0.01, 50.0, scan.size)
    w, _ = joint_weights(scan, det, track, dens, p_detect=0.8, clutter_density=0.3)
    for s in range(40):
        rows = np.flatnonzero(scan == s)
        pairs = {(int(det[r]), int(track[r])): float(dens[r]) for r in rows}
        acc, total = _events([s], [0, 1, 2], pairs, 0.8, 0.3)
        for r in rows:
            assert w[r] == acc[(s, int(track[r]))] / total


def test_tracks_that_start_side_by_side_are_extended_over_their_ambiguous_start():
    """Two tracks that start 0.01 rad apart and part slowly: their first scans are ambiguous
    (closer than the separation, a crossing within J scans), so both are cut there. With the
    end extension the released detections before the first segments enter both tracks
    through association weights and each track starts at the first scan, its own detections
    labelled; without it (extend_ends=False) both tracks start later and lose some of them."""
    rng = np.random.default_rng(0)
    ts = 10.0 * np.arange(80)
    t = np.repeat(ts, 2)
    lab = np.tile([0, 1], ts.size)
    z = np.where(lab == 0, 0.30 + 1e-4 * t, 0.29 - 1e-4 * t) + rng.normal(0, 0.004, t.size)
    early = t < 100.0
    out = {}
    for ext in (True, False):
        res = MultiTrackSmoother(sigma_bearing=0.004, q=1e-10, clutter_density=0.1,
                                 p_detect=0.9, extend_ends=ext).run(t, z)
        assert len(res.tracks) == 2
        right = 0
        for k in (0, 1):  # the track that owns this target later on
            later = res.labels[(lab == k) & ~early]
            mine = np.bincount(later[later >= 0]).argmax()
            right += int(np.sum(res.labels[(lab == k) & early] == mine))
        out[ext] = (min(tr.times[0] for tr in res.tracks), right)
    assert out[True] == (0.0, int(early.sum()))  # from the first scan, every label right
    assert out[False][0] >= 20.0 and out[False][1] < early.sum()


def test_cli_end_extension_reaches_the_smoother(tmp_path):
    """fusion smooth extends tracks over their ambiguous start with --end-extension and not by
    default (the two tracks of the side-by-side start above)."""
    rng = np.random.default_rng(0)
    t = np.repeat(10.0 * np.arange(80), 2)
    lab = np.tile([0, 1], 80)
    z = np.where(lab == 0, 0.30 + 1e-4 * t, 0.29 - 1e-4 * t) + rng.normal(0, 0.004, t.size)
    src = tmp_path / "b.csv"
    src.write_text("track_id,time,bearing_deg\n" + "".join(
        f"-1,{a},{b}\n" for a, b in zip(t, np.degrees(z), strict=True)))
    starts = {}
    for extra in ([], ["--end-extension"]):
        out = tmp_path / f"s{len(extra)}.csv"
        assert main(["smooth", "--bearings", str(src), "--out", str(out), "--quiet",
                     "--bearing-sigma-deg", "0.2292", "--accel-psd-deg2-per-s3", "3.283e-7",
                     "--clutter-density", "0.1", "--detection-probability", "0.9",
                     "--init-rate-sigma-deg-per-s", "0.573", "--max-misses", "5",
                     "--min-length", "5", "--merge-deg", "0", "--twin-deg", "0",
                     *extra]) == 0
        _, *rows = out.read_text().splitlines()
        arr = np.array([list(map(float, r.split(","))) for r in rows])
        starts[len(extra)] = sorted(arr[arr[:, 0] == k, 1].min() for k in np.unique(arr[:, 0]))
    assert starts[1][0] < starts[0][0]
