"""Tests of links with the segments' bearing accelerations (``link_curvature``, ``fusion smooth
--link-curvature``; issue 18)."""

import json

import numpy as np
import pytest

from fusion.cli import main
from fusion.passive.smoothing import MultiTrackSmoother
from fusion.passive.smoothing.linking import (
    CURVATURE_MIN_SCANS,
    link_segments,
    segment_accelerations,
)

P = np.diag([1e-6, 1e-10])
SCAN_TIMES = 10.0 * np.arange(120)


def _seg(s0, s1, theta1, rate1, acc):
    """A segment over scans s0..s1 of constant bearing acceleration `acc` (rad/s^2) ending at
    bearing `theta1` and rate `rate1`: its (first, last) states as ``_segment_ends`` gives."""
    span = SCAN_TIMES[s1] - SCAN_TIMES[s0]
    rate0 = rate1 - acc * span
    theta0 = theta1 - rate0 * span - 0.5 * acc * span**2
    return (s0, np.array([theta0, rate0]), P, s1, np.array([theta1, rate1]), P)


def test_segment_accelerations_known_answer():
    """Rate change over the span; the variance of that difference; 0 below the minimum span."""
    ends = [_seg(0, 30, 0.0, 3e-4, 1e-6), _seg(40, 40 + CURVATURE_MIN_SCANS - 1, 0.1, 0.0, 1e-6)]
    acc, var = segment_accelerations(ends, SCAN_TIMES)
    assert acc[0] == pytest.approx(1e-6, rel=1e-9)
    assert var[0] == pytest.approx(2e-10 / 300.0**2, rel=1e-9)
    assert acc[1] == 0.0 and var[1] == 0.0


def _crossing_ends():
    """Ends A (decelerating, 1e-6 rad/s^2) and B (constant rate) at scan 30, their
    continuations C and D from scan 50: propagated at constant rate, A lands nearer D and B
    nearer C (0.003^2 + 0.017^2 < 0.02^2: the bounced pairing is cheaper)."""
    a = _seg(0, 30, 0.0, 0.0, 1e-6)
    b = _seg(0, 30, -0.017, 1e-4, 0.0)
    dt, acc = 200.0, 1e-6
    c_start = np.array([0.5 * acc * dt**2, acc * dt])
    c = _seg(50, 80, c_start[0] + c_start[1] * 300 + 0.5 * acc * 300**2,
             c_start[1] + acc * 300, acc)
    d = _seg(50, 80, 0.003 + 1e-4 * 300, 1e-4, 0.0)
    return [a, b, c, d]


def test_curvature_links_a_curving_track_to_its_continuation():
    """With the accelerations the assignment links A->C and B->D; at constant rate it
    bounces (A->D, B->C)."""
    kw = {"q": 1e-14, "link_gate": 1e6, "max_gap_scans": 40}
    ends = _crossing_ends()
    assert sorted(link_segments(ends, SCAN_TIMES, curvature=True, **kw)) == [[0, 2], [1, 3]]
    assert sorted(link_segments(ends, SCAN_TIMES, **kw)) == [[0, 3], [1, 2]]


def test_curvature_is_off_in_the_library_and_on_in_fusion_smooth(tmp_path, monkeypatch):
    """``MultiTrackSmoother`` default False; ``fusion smooth`` passes True, or False with
    ``--no-link-curvature``, and writes it to the settings."""
    assert MultiTrackSmoother(sigma_bearing=0.01, q=1e-8).link_curvature is False
    seen = []
    import fusion.pipelines.bearing_smoothing as bs

    class Spy(MultiTrackSmoother):
        def __init__(self, **kw):
            seen.append(kw["link_curvature"])
            super().__init__(**kw)

    monkeypatch.setattr(bs, "MultiTrackSmoother", Spy)
    rng = np.random.default_rng(0)
    ts = 10.0 * np.arange(60)
    src = tmp_path / "b.csv"
    src.write_text("track_id,time,bearing_deg\n" + "".join(
        f"-1,{a},{b}\n" for a, b in zip(ts, 30 + 0.01 * ts + rng.normal(0, 0.3, ts.size),
                                         strict=True)))
    for flag in ([], ["--no-link-curvature"]):
        out = tmp_path / f"s{len(flag)}.csv"
        assert main(["smooth", "--bearings", str(src), "--out", str(out), "--quiet", *flag]) == 0
        meta = json.loads((tmp_path / f"s{len(flag)}.settings.json").read_text())
        assert meta["link_curvature"] is (not flag)
    assert seen == [True, False]


def test_an_acceleration_the_white_noise_explains_is_not_used():
    """A rate change of 3e-4 rad/s over 300 s counts with q = 0; with q = 1e-9 rad^2/s^3
    (rate variance 3e-7 over the span, above 9e-8) it is taken as 0."""
    ends = [_seg(0, 30, 0.0, 3e-4, 1e-6)]
    assert segment_accelerations(ends, SCAN_TIMES, q=0.0)[0][0] == pytest.approx(1e-6)
    acc, var = segment_accelerations(ends, SCAN_TIMES, q=1e-9)
    assert acc[0] == 0.0 and var[0] == 0.0


@pytest.mark.parametrize("curvature", [False, True])
def test_link_distances_equal_the_per_pair_matrices(curvature):
    """The closed-form 2 x 2 distances of all links at once equal ``nu' S^-1 nu`` and
    ``ln det S`` built per pair with the motion model's F and Q and a linear solve."""
    from factors.motion import transition_matrix, wna_covariance
    from fusion.geometry import wrap_angle
    from fusion.passive.smoothing.linking import _link_distances

    rng = np.random.default_rng(3)
    ends = []
    for k in range(6):
        a = rng.normal(size=(2, 2))
        p0 = a @ a.T * np.array([[1e-5, 1e-7], [1e-7, 1e-9]]) + np.diag([1e-6, 1e-10])
        s0 = 14 * k
        ends.append((s0, rng.normal([3.0, 0.0], [0.5, 1e-3]), p0, s0 + 11,
                     rng.normal([-3.0, 0.0], [0.5, 1e-3]), p0.T.copy()))
    q = 1e-9
    acc, var = (segment_accelerations(ends, SCAN_TIMES, q=0.0) if curvature
                else (np.zeros(6), np.zeros(6)))
    ei, si = np.array([0, 0, 1, 2, 3, 4]), np.array([1, 3, 5, 4, 5, 5])
    dt = SCAN_TIMES[[ends[s][0] for s in si]] - SCAN_TIMES[[ends[e][3] for e in ei]]
    assert (acc != 0).sum() == (5 if curvature else 0)
    d2, lndet = _link_distances(ends, ei, si, dt, q, acc, var)
    for k, (e, s) in enumerate(zip(ei, si, strict=True)):
        f = transition_matrix(dt[k], 1)
        cov = f @ ends[e][5] @ f.T + wna_covariance(dt[k], q, 1) + ends[s][2]
        jac = np.array([0.5 * dt[k] ** 2, dt[k]])
        nu = ends[s][1] - f @ ends[e][4] - 0.5 * (acc[e] + acc[s]) * jac
        cov = cov + 0.25 * (var[e] + var[s]) * np.outer(jac, jac)
        nu[0] = wrap_angle(nu[0])
        assert d2[k] == pytest.approx(nu @ np.linalg.solve(cov, nu), rel=1e-9)
        assert lndet[k] == pytest.approx(np.log(np.linalg.det(cov)), rel=1e-9)
