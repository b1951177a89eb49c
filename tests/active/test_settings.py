"""Tests of the tracker scales read from the detections (fusion.active.settings), the streamed
pings (fusion.active.types.iter_pings) and what ``fusion track`` says about them."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.active.rulebase import default_association_system
from fusion.active.settings import fit_scales, track_settings
from fusion.active.tracker import Tracker
from fusion.active.types import Ping, iter_pings, pings_from_columns
from fusion.io import iter_detections, read_table, write_table


def _scene(seed: int, *, sigma: float, period: float, speeds: list[float], n_scans: int = 60,
           n_fixed: int = 3, n_clutter: int = 3, half_width: float = 2000.0) -> list[Ping]:
    """Straight-moving objects at `speeds` (m/s), fixed features and uniform clutter; every
    object detected on every scan with `sigma` (m) per axis."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-half_width / 2, half_width / 2, (len(speeds), 2))
    head = rng.uniform(0, 2 * np.pi, len(speeds))
    vel = np.asarray(speeds)[:, None] * np.column_stack([np.sin(head), np.cos(head)])
    fixed = rng.uniform(-half_width, half_width, (n_fixed, 2))
    pings = []
    for k in range(n_scans):
        t = period * k
        xy = np.vstack([start + vel * t, fixed]) + rng.normal(0, sigma, (len(speeds) + n_fixed, 2))
        xy = np.vstack([xy, rng.uniform(-half_width, half_width, (n_clutter, 2))])
        pings.append(Ping(k, t, xy))
    return pings


@pytest.mark.parametrize(("sigma", "period", "speeds"), [
    (5.0, 2.0, [3.0, 4.0, 5.0, 6.0]),           # radar-like
    (80.0, 90.0, [2.0, 3.0, 3.5, 4.0]),         # sonar-like
])
def test_scatter_and_period_known_answers(sigma, period, speeds):
    """The scatter comes out within 15 % of the simulated per-axis sigma, the period exactly,
    and the speed prior near half the 90th-percentile speed, on both scales."""
    pings = _scene(3, sigma=sigma, period=period, speeds=speeds,
                   half_width=2000.0 if sigma < 10 else 20000.0)
    st = track_settings(pings)
    assert st.period_s == pytest.approx(period)
    assert st.position_sigma_m == pytest.approx(sigma, rel=0.15)
    assert st.source["position_sigma_m"] == "data"
    if st.source["speed_sigma_mps"] == "data":
        assert 0.5 * max(speeds) / 2 < st.speed_sigma_mps < 1.5 * max(speeds) / 2
    # The lengths that follow scale with sigma.
    assert_allclose(st.hotspot_near_m, (st.position_sigma_m, 5 * st.position_sigma_m))
    assert st.intensity_bandwidth_m == pytest.approx(10 * st.position_sigma_m)
    assert st.init_exclusion_m == pytest.approx(st.position_sigma_m)


def test_scatter_is_scale_invariant():
    """Scaling every position by 10 scales the scatter by 10 and the speed prior by 10 (the
    period unchanged): nothing assumes metres of one size."""
    pings = _scene(5, sigma=4.0, period=2.0, speeds=[3.0, 5.0, 6.0, 4.0])
    big = [Ping(p.event, p.time, 10.0 * p.xy) for p in pings]
    a, b = fit_scales(pings), fit_scales(big, max_speed_mps=300.0)
    assert b.sigma_m == pytest.approx(10 * a.sigma_m, rel=1e-6)
    assert b.speed_sigma_mps == pytest.approx(10 * a.speed_sigma_mps, rel=1e-6)
    assert b.period_s == a.period_s


def test_pure_clutter_falls_back():
    """Uniform clutter alone forms no chains chance cannot explain: the scatter and the speed
    prior fall back (100 m, 3 m/s) and say so."""
    rng = np.random.default_rng(0)
    pings = [Ping(k, 60.0 * k, rng.uniform(-10000, 10000, (20, 2))) for k in range(30)]
    st = track_settings(pings)
    assert st.source["position_sigma_m"] == "fallback"
    assert st.position_sigma_m == 100.0 and st.speed_sigma_mps == 3.0
    assert "?" in st.describe()
    # 20 per scan over the (20 km)^2 bounding box, all clutter.
    assert st.clutter_density == pytest.approx(20 / 20000.0**2, rel=0.05)


def test_given_settings_win():
    """Settings the user gives are used as given, marked given, and their followers too."""
    pings = _scene(1, sigma=5.0, period=2.0, speeds=[3.0, 4.0, 5.0])
    st = track_settings(pings, position_sigma_m=7.0, speed_sigma_mps=2.0, accel_psd=0.3,
                        init_exclusion_m=0.0, hotspot_near_m=(10.0, 40.0))
    assert (st.position_sigma_m, st.speed_sigma_mps, st.accel_psd, st.init_exclusion_m) == (
        7.0, 2.0, 0.3, 0.0)
    assert st.hotspot_near_m == (10.0, 40.0)
    assert st.source["position_sigma_m"] == "given" and st.source["feature_sigma_m"] == "given"
    assert "7 m*" in st.describe()
    with pytest.raises(ValueError, match="hotspot_near_m"):
        track_settings(pings, hotspot_near_m=(50.0, 10.0))
    with pytest.raises(ValueError, match="position_sigma_m"):
        track_settings(pings, position_sigma_m=-1.0)


def _near(system: object) -> object:
    """The 'near' term of a system's hotspot-distance variable."""
    return next(v for v in system.variables if v.name == "hotspot_distance_m").terms["near"]


def test_tracker_options_configure_a_tracker():
    """tracker_options builds a working tracker whose hotspot rule has the fitted 'near'."""
    pings = _scene(2, sigma=5.0, period=2.0, speeds=[3.0, 4.0, 5.0, 6.0])
    st = track_settings(pings)
    opts = st.tracker_options()
    near = _near(opts["system"])
    assert_allclose(near(np.array([st.hotspot_near_m[0], st.hotspot_near_m[1]])), [1.0, 0.0])
    result = Tracker(**opts).run(pings)
    assert result.confirmed_ids().size >= 4   # the moving objects at least


def test_default_rule_base_unchanged():
    """The default rule base keeps the sonar 'near' of 100-500 m."""
    near = _near(default_association_system())
    assert_allclose(near(np.array([100.0, 300.0, 500.0])), [1.0, 0.5, 0.0])


@pytest.mark.parametrize("size", [1, 5, 64, 10_000])
def test_iter_pings_matches_pings_from_columns(size):
    """Streaming the rows in chunks of any size gives the pings of the whole-table grouping,
    empty pings for missing events included."""
    rng = np.random.default_rng(size)
    ev = np.sort(rng.choice(np.arange(120), 300))
    ev = ev[(ev != 40) & (ev != 41)]
    cols = {"event": ev, "time": 3.0 * ev + 1.0, "x": rng.normal(size=ev.size),
            "y": rng.normal(size=ev.size), "snr_db": rng.uniform(0, 30, ev.size)}
    want = pings_from_columns(cols)
    got = list(iter_pings({k: v[i:i + size] for k, v in cols.items()}
                          for i in range(0, ev.size, size)))
    assert [(p.event, p.time, p.n) for p in got] == [(p.event, p.time, p.n) for p in want]
    for p, q in zip(got, want, strict=True):
        assert_allclose(p.xy, q.xy)
        assert_allclose(p.clues["snr_db"], q.clues["snr_db"])
    with pytest.raises(ValueError, match="event order"):
        list(iter_pings([{"event": [2, 1], "time": [0.0, 1.0], "x": [0.0, 0.0],
                          "y": [0.0, 0.0]}]))


def test_cli_settings_line_json_and_chunks(tmp_path, run_cli, monkeypatch):
    """fusion track prints one settings line, writes T.settings.json, and the same tracks
    whether the file is read in small chunks or whole (--confirmed-only reads it whole)."""
    pings = _scene(4, sigma=5.0, period=2.0, speeds=[3.0, 4.0, 5.0, 6.0], n_scans=40)
    rows = {"event": [], "time": [], "x": [], "y": []}
    for p in pings:
        rows["event"] += [p.event] * p.n
        rows["time"] += [p.time] * p.n
        rows["x"] += p.xy[:, 0].tolist()
        rows["y"] += p.xy[:, 1].tolist()
    write_table(tmp_path / "d.csv", rows)
    import fusion.commands.track as track_command

    monkeypatch.setattr(track_command, "iter_detections",
                        functools.partial(iter_detections, rows_per_chunk=17))
    code, _, err = run_cli("track", "--detections", tmp_path / "d.csv", "--out", tmp_path / "t.csv")
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if ln.startswith("fusion track: scan period")]
    assert len(lines) == 1 and "position sigma" in lines[0] and "speed sigma" in lines[0]
    side = json.loads((tmp_path / "t.settings.json").read_text())
    assert side["settings"]["position_sigma_m"] == pytest.approx(5.0, rel=0.2)
    assert side["confirmed_tracks"] >= 4 and side["no_track_reason"] is None
    code, _, err = run_cli("track", "--detections", tmp_path / "d.csv", "--out",
                           tmp_path / "w.csv", "--confirmed-only")
    assert code == 0, err
    cols = ("track_id", "event", "x", "status")
    a = read_table(tmp_path / "t.csv", required=cols, text=("status",))
    b = read_table(tmp_path / "w.csv", required=cols, text=("status",))
    keep = np.isin(a["track_id"], np.unique(a["track_id"][a["status"] == "confirmed"]))
    assert_allclose(a["x"][keep], b["x"])


def test_cli_says_why_nothing_confirmed(tmp_path, run_cli):
    """A run that confirms no track says so in one line, with the reason (too few hits on
    pure clutter; stationary echoes held), also in the settings file."""
    rng = np.random.default_rng(1)
    n = 30
    write_table(tmp_path / "c.csv", {"event": np.repeat(np.arange(n), 3),
                                     "time": np.repeat(60.0 * np.arange(n), 3),
                                     "x": rng.uniform(-2e4, 2e4, 3 * n),
                                     "y": rng.uniform(-2e4, 2e4, 3 * n)})
    code, _, err = run_cli("track", "--detections", tmp_path / "c.csv", "--out", tmp_path / "c_t.csv")
    assert code == 0, err
    why = [ln for ln in err.splitlines() if "no track confirmed" in ln]
    assert len(why) == 1 and "hits within" in why[0]
    assert "no track confirmed" in json.loads(
        (tmp_path / "c_t.settings.json").read_text())["no_track_reason"]
    # One still object echoing on every ping: its track is held (it does not move).
    write_table(tmp_path / "s.csv", {"event": np.arange(n), "time": 2.0 * np.arange(n),
                                     "x": rng.normal(0, 3, n), "y": rng.normal(0, 3, n)})
    code, _, err = run_cli("track", "--detections", tmp_path / "s.csv", "--out",
                           tmp_path / "s_t.csv", "--position-sigma-m", "3")
    assert code == 0, err
    why = [ln for ln in err.splitlines() if "no track confirmed" in ln]
    assert len(why) == 1 and "held tentative" in why[0] and "--min-speed-mps" in why[0]
