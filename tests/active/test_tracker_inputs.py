"""The tracker's inputs: no truth taken from the data, one detection per receiver and ping, the
classifier-score gate, a varied scenario end to end, and the ``fusion track`` options."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.active.kalman import fuse_positions
from fusion.active.pilot import fitted_tracker_options
from fusion.active.tracker import Ping, Tracker
from fusion.active.types import pings_from_columns
from fusion.io import Table, read_detections, read_table, write_table
from fusion.metrics.multistatic import score_tracks
from fusion.simulate.multistatic import simulate_multistatic


def _with(table: Table, **cols) -> Table:
    return Table({**table.columns, **cols}, table.source)


def test_aspect_column_is_ignored_unless_declared_a_measurement():
    """By default the output does not change when the aspect_deg column is replaced by the
    target's exact aspect or by noise; with aspect='measured' it does."""
    sc = simulate_multistatic(seed=5, vary=True, n_pings=12)
    det = sc.detections
    noise = np.random.default_rng(0).uniform(0, 180, len(det))
    a = Tracker().run(det).columns()
    b = Tracker().run(_with(det, aspect_deg=noise)).columns()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    c = Tracker(aspect="measured").run(_with(det, aspect_deg=noise)).columns()
    assert len(c["x"]) != len(a["x"]) or not np.array_equal(c["x"], a["x"])


def _three_receiver_pings(n=6, seed=1):
    """A target at 4 m/s seen on every ping by three receivers (30-m errors), no clutter."""
    rng = np.random.default_rng(seed)
    rcv = np.array([[6000.0, 0.0], [-3000.0, 5000.0], [-3000.0, -5000.0]])
    pings = []
    for k in range(n):
        p = np.array([-2000.0 + 4.0 * 90.0 * k, 2500.0])
        xy = p + rng.normal(0, 30.0, (3, 2))
        geo = {"src_x": np.zeros(3), "src_y": np.zeros(3), "rcv_x": rcv[:, 0], "rcv_y": rcv[:, 1]}
        pings.append(Ping(k, 90.0 * k, xy, geo))
    return pings


def test_one_detection_per_receiver_and_ping_fused():
    """A track takes the echo of every receiver (three per ping after the first); its reported
    measurement is the information-weighted fusion of the three, with their covariances."""
    tr = Tracker(noise="fixed", range_sum_sigma_m=60.0, bearing_sigma_deg=0.5)
    res = tr.run(_three_receiver_pings())
    assert res.confirmed_ids().tolist() == [0]
    last = res.pings[-1]
    i = int(np.flatnonzero(last.track_id == 0)[0])
    assert sorted(last.detections[i].tolist()) == [0, 1, 2]
    ping = _three_receiver_pings()[-1]
    R, _ = tr.measurement_covariances(ping)
    z, C = fuse_positions(ping.xy, R)
    assert_allclose(last.measurement[i], z, rtol=1e-9)
    assert_allclose(last.measurement_cov[i], C, rtol=1e-9)


def test_score_gate_keeps_low_scores_out():
    """With score_threshold 0.5 no track takes a detection scoring below 0.5; the default
    (no gate) does, on the same data."""
    sc = simulate_multistatic(seed=7, vary=True, n_pings=10)
    det = sc.detections
    ev = np.asarray(det["event"])
    order = np.argsort(ev, kind="stable")
    score, evs = np.asarray(det["score"])[order], ev[order]

    def taken_scores(result):
        out = []
        for p in result.pings:
            start = int(np.searchsorted(evs, p.event))
            for d in p.detections:
                out.extend(score[start + d].tolist())
        return np.array(out)

    gated = taken_scores(Tracker(score_threshold=0.5).run(det))
    plain = taken_scores(Tracker().run(det))
    assert gated.size and gated.min() >= 0.5
    assert plain.min() < 0.5
    with pytest.raises(ValueError, match="score_threshold"):
        Tracker(score_threshold=1.5)


def test_varied_scenario_end_to_end():
    """A varied run (4 receivers, about 30 detections per ping): the target is covered on most
    pings after the third with at most one false track, and no knowledge of the simulator's
    accuracies, clutter or detection probabilities."""
    sc = simulate_multistatic(seed=1001, vary=True)
    s = score_tracks(Tracker().run(sc.detections).columns(), sc.truth)
    assert s.coverage >= 0.8 and s.false_tracks <= 1 and s.identity_switches <= 1
    kalman = score_tracks(Tracker(mode="kalman").run(sc.detections).columns(), sc.truth)
    assert kalman.false_tracks > 5


def test_cli_options(tmp_path, run_cli):
    """fusion track: --aspect-column measured, --no-track-score, --clutter-map grid and the
    user's settings reach the tracker (outputs as from the library with the same options)."""
    sc = simulate_multistatic(seed=5, vary=True, n_pings=8)
    cols = {k: sc.detections[k] for k in ("event", "time", "x", "y", "snr_db", "score",
                                          "aspect_deg", "src_x", "src_y", "rcv_x", "rcv_y")}
    src = tmp_path / "d.csv"
    write_table(src, cols)
    table = read_detections(src)
    # The command's scales, read from the detections (fusion.active.settings, the speed prior
    # from a pilot run: fusion.active.pilot).
    runs = {
        "default": ((), {}),
        "measured": (("--aspect-column", "measured"), {"aspect": "measured"}),
        "mofn": (("--no-track-score", "--min-speed-mps", "0"), {"confirm_llr": None,
                                                            "min_speed_mps": 0.0}),
        "fixed": (("--noise", "fixed", "--detection-probability", "0.8",
                   "--clutter-density", "1e-7"),
                  {"noise": "fixed", "detection_probability": 0.8, "clutter_intensity": 1e-7}),
    }
    for name, (flags, kw) in runs.items():
        out = tmp_path / f"{name}.csv"
        code, _, err = run_cli("track", "--detections", src, "--out", out, *flags)
        assert code == 0, err
        got = read_table(out, required=("track_id", "x"), text=("status",))
        fitted = fitted_tracker_options(pings_from_columns(table), **kw)
        want = Tracker(**{**fitted, **kw}).run(table).columns()
        assert_allclose(got["x"], want["x"], rtol=1e-6, atol=1e-3)
    code, _, err = run_cli("track", "--detections", src, "--out", tmp_path / "g.csv",
                           "--clutter-map", "grid", "--hotspot-cell-m", "120")
    assert code == 0, err
