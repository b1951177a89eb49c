"""A recording's sound speed from its written windows, and `fusion localize --sound-speed`."""

import json

import numpy as np
import pytest
from scipy.optimize import least_squares

from factors.tdoa.model import predicted_tdoas
from fusion.pipelines.sound_speed import calibrate_speed, fix_tdoas
from tests.pipelines.written_windows import written_window

SENSORS = np.array([[0.0, 0, -1500], [3200, 150, -1610], [1500, 2900, -1550],
                    [-1800, 1400, -1480], [400, -2500, -1590]])
PAIRS = [(i, j) for i in range(5) for j in range(i + 1, 5)]


def _window(p_true, c_true, c_file, t0, pairs=PAIRS):
    """A written window whose one source owns the delays of `pairs`, solved at the file's
    speed."""
    return written_window(p_true, t0, pairs, true_sensors=SENSORS, sensors=SENSORS,
                          c_true=c_true, c_file=c_file)


TRUE = np.array([[800.0, 600, -900], [820, 630, -905], [850, 650, -910], [870, 690, -915]])


def test_windows_re_solved_at_the_speed_their_fixes_share():
    windows = [_window(p, 1484.0, 1500.0, 2.0 * k) for k, p in enumerate(TRUE)]
    before = np.array([[w["sources"][0][a] for a in "xyz"] for w in windows])
    assert np.min(np.linalg.norm(before - TRUE, axis=1)) > 5.0
    cal = calibrate_speed(windows, SENSORS, 1500.0, gradient=False)  # one speed: exact
    assert cal.estimate is not None
    assert cal.speed_mps == pytest.approx(1484.0, abs=0.01)
    after = [cal.apply(w) for w in windows]
    pos = np.array([[w["sources"][0][a] for a in "xyz"] for w in after])
    np.testing.assert_allclose(pos, TRUE, atol=0.01)
    assert all(w["sources"][0]["residual_rms_s"] < 1e-9 for w in after)
    assert windows[0]["sources"][0]["x"] == before[0, 0]  # the input left as it was
    rec = cal.record()
    assert rec["source"] == "estimated" and rec["nominal_mps"] == 1500.0
    assert rec["fixes"] == 4 and rec["tdoas"] == 40
    assert "1484.0" in cal.note and "--sound-speed array" in cal.note


def test_the_right_speed_leaves_the_fixes_where_they_are():
    windows = [_window(p, 1500.0, 1500.0, 2.0 * k) for k, p in enumerate(TRUE)]
    cal = calibrate_speed(windows, SENSORS, 1500.0, gradient=False)
    assert cal.speed_mps == pytest.approx(1500.0, abs=0.01)
    for w in windows:
        s = cal.apply(w)["sources"][0]
        assert np.linalg.norm([s["x"] - w["sources"][0]["x"], s["y"] - w["sources"][0]["y"],
                               s["z"] - w["sources"][0]["z"]]) < 0.01


def test_too_few_fixes_keep_the_file_speed_and_say_so():
    windows = [_window(p, 1484.0, 1500.0, 2.0 * k) for k, p in enumerate(TRUE[:2])]
    cal = calibrate_speed(windows, SENSORS, 1500.0)
    assert cal.estimate is None and cal.speed_mps == 1500.0
    assert "array file's 1500 m/s" in cal.note and "3 are needed" in cal.note
    assert "5 or more sensors" in cal.note
    assert cal.apply(windows[0]) is windows[0]
    # fixes flagged mirror-ambiguous or unobservable teach nothing
    flagged = [_window(p, 1484.0, 1500.0, 2.0 * k) for k, p in enumerate(TRUE)]
    for w in flagged[:2]:
        w["sources"][0]["mirror_ambiguous"] = True
    assert calibrate_speed(flagged, SENSORS, 1500.0).estimate is None


def test_fix_tdoas_moves_each_delay_along_its_drift():
    w = _window(TRUE[0], 1500.0, 1500.0, 0.0)
    for d in w["tdoas"]:
        d["rate"] = 1e-3
    fix = fix_tdoas(w, w["sources"][0], SENSORS, 1500.0)
    r = np.linalg.norm(SENSORS - [w["sources"][0][a] for a in "xyz"], axis=1) / 1500.0
    expect = [d["tau"] + 1e-3 * (r[d["pair"][0]] - r.mean()) for d in w["tdoas"]]
    np.testing.assert_allclose(fix.taus, expect, rtol=1e-12)
    assert fix_tdoas(w, {**w["sources"][0], "owned_tdoas": []}, SENSORS, 1500.0) is None


def test_cli_estimates_the_speed_the_array_file_gets_wrong(tmp_path):
    """A recording made at 1,485 m/s with an array file saying 1,500: the default estimates
    the speed and lands on the whale; ``--sound-speed array`` stays metres off (ablation)."""
    from fusion.cli import main
    from fusion.simulate.clicks import simulate_clicks, write_click_scenario

    sc = simulate_clicks(seed=7001, n_sensors=5, n_sources=1, duration_s=20.0, snr_db=36.0,
                         sound_speed_profile={"kind": "constant", "c0": 1485.0},
                         nominal_sound_speed=1500.0, echo="both")
    write_click_scenario(tmp_path / "sc", sc)
    assert json.loads((tmp_path / "sc" / "array.json").read_text())["sound_speed"] == 1500.0
    whale = sc.sources[0]
    errors = {}
    for mode in ("estimate", "array"):
        out = tmp_path / f"{mode}.json"
        assert main(["localize", "--audio", str(tmp_path / "sc" / "audio.flac"), "--array",
                     str(tmp_path / "sc" / "array.json"), "--out", str(out), "--quiet",
                     "--sound-speed", mode]) == 0
        doc = json.loads(out.read_text())
        errs = []
        for w in doc["windows"]:
            truth = whale.position_at([0.5 * (w["t_start"] + w["t_end"])])[0]
            errs += [np.linalg.norm(np.array([s["x"], s["y"], s["z"]]) - truth)
                     for s in w["sources"]]
        errors[mode] = np.median(errs)
        side = json.loads(out.with_name(out.stem + ".settings.json").read_text())
        if mode == "estimate":
            speed = side["sound_speed"][str(out)]
            assert speed["speed_mps"] == pytest.approx(1485.0, abs=1.0)
        else:
            assert "sound_speed" not in side
    assert errors["estimate"] < 2.0 < 5.0 < errors["array"]


def test_a_source_split_by_the_wrong_speed_is_merged_after_the_re_solve():
    windows = [_window(p, 1484.0, 1500.0, 2.0 * k) for k, p in enumerate(TRUE)]
    w = windows[0]
    src = w["sources"][0]
    # the same whale written as two sources owning halves of its delays (apart at 1500 m/s)
    a = {**src, "owned_tdoas": list(range(6)), "paths": ["direct"] * 6, "x": src["x"] + 9.0}
    b = {**src, "owned_tdoas": list(range(4, 10)), "paths": ["direct"] * 6, "y": src["y"] - 8.0}
    split = {**w, "sources": [a, b]}
    cal = calibrate_speed(windows, SENSORS, 1500.0, gradient=False)
    out = cal.apply(split)["sources"]
    assert len(out) == 1
    assert sorted(out[0]["owned_tdoas"]) == list(range(10)) and out[0]["tdoas_used"] == 10
    np.testing.assert_allclose([out[0][k] for k in "xyz"], TRUE[0], atol=0.01)
    # two whales 40 m apart stay two sources
    other = _window(TRUE[0] + [40.0, 0, 0], 1484.0, 1500.0, 0.0)
    two = {**w, "tdoas": w["tdoas"] + other["tdoas"],
           "sources": [src, {**other["sources"][0],
                             "owned_tdoas": list(range(10, 20)),
                             "paths": ["direct"] * 10}]}
    assert len(cal.apply(two)["sources"]) == 2


def test_fixes_that_disagree_keep_the_file_speed():
    """Sensor positions metres off (a survey error shared by every fix): the speed the fixes
    point to is too uncertain to use; the file's speed is kept and the line says why."""
    windows = [_window(p, 1500.0, 1500.0, 2.0 * k) for k, p in enumerate(TRUE)]
    wrong = SENSORS + np.random.default_rng(1).normal(0.0, 3.0, SENSORS.shape)
    # the positions exact (--sensor-position-sigma-m 0): the fixes point to 1,541 m/s, 2.8 % off
    cal = calibrate_speed(windows, wrong, 1500.0, sensor_sigma_m=0.0)
    assert cal.estimate is None and cal.speed_mps == 1500.0
    assert "more than 1.5 % from it" in cal.note and "sensor positions off" in cal.note
    assert cal.apply(windows[0]) is windows[0]
    # by default the sensors' offsets are estimated beside the speed, which comes back
    refined = calibrate_speed(windows, wrong, 1500.0)
    assert "sensor positions estimated together" in refined.note
    assert abs(refined.speed_mps - 1500.0) < 3.0
    # fixes spread over the array whose delays disagree with any one speed: the sigma tells
    spread = [_window(p, 1500.0, 1500.0, 2.0 * k) for k, p in enumerate(
        [[800.0, 600, -900], [-1200, 1500, -700], [1300, -400, -1100], [-900, -1500, -800]])]
    jitter = SENSORS + np.random.default_rng(5).normal(0.0, 8.0, SENSORS.shape)
    assert calibrate_speed(spread, jitter, 1500.0, sensor_sigma_m=0.0).estimate is None


def _four_sensor_window(p_true, c_true, c_file, t0, rng):
    """A written window whose source owns the six delays of sensors 0-3 (solved at the file's
    speed); sensor 4's pairs are candidates below the validator's bar: the true delay and two
    chance ones each."""
    window = _window(p_true, c_true, c_file, t0,
                     pairs=[(i, j) for i in range(4) for j in range(i + 1, 4)])
    for i in range(4):
        true = float(predicted_tdoas(p_true, SENSORS, np.array([[i, 4]]), c=c_true)[0])
        for tau in (true + rng.normal(0, 20e-6), true + rng.uniform(-0.2, 0.2),
                    rng.uniform(-2.0, 2.0)):
            window["tdoas"].append({"pair": [i, 4], "tau": tau, "t": t0 + 6.0, "rate": 0.0,
                                    "valid": False, "llr": 0.1, "sigma": 0.0027})
    return window


def test_far_sensor_delays_teach_the_speed_of_four_sensor_fixes():
    """Every fix spans four sensors (exactly determined at any speed); the fifth sensor's
    sub-threshold candidates agree on one speed across windows: the speed is estimated from
    them and the fixes re-solved at it. Without them (the ablation) the file's speed is kept
    and the fixes stay metres off (seeds 7703, 7800, 7803 of ``--vary-only sound-speed``)."""
    rng = np.random.default_rng(3)
    windows = [_four_sensor_window(p, 1484.0, 1500.0, 2.0 * k, rng)
               for k, p in enumerate(TRUE)]
    before = np.array([[w["sources"][0][a] for a in "xyz"] for w in windows])
    assert np.min(np.linalg.norm(before - TRUE, axis=1)) > 5.0
    off = calibrate_speed(windows, SENSORS, 1500.0, recruit_far=False)
    assert off.estimate is None and "3 are needed" in off.note
    cal = calibrate_speed(windows, SENSORS, 1500.0)
    assert cal.estimate is not None
    assert cal.speed_mps == pytest.approx(1484.0, abs=0.5)
    assert "far sensor's delays recruited" in cal.note
    pos = np.array([[cal.apply(w)["sources"][0][a] for a in "xyz"] for w in windows])
    assert np.max(np.linalg.norm(pos - TRUE, axis=1)) < 1.0
    # the re-solved fixes stand on their own delays only
    assert all(cal.apply(w)["sources"][0]["tdoas_used"] == 6 for w in windows)


def test_chance_candidates_alone_teach_no_speed():
    rng = np.random.default_rng(4)
    windows = [_four_sensor_window(p, 1484.0, 1500.0, 2.0 * k, rng)
               for k, p in enumerate(TRUE)]
    for w in windows:  # the true candidates of sensor 4 replaced by chance ones
        for d in w["tdoas"][6::3]:
            d["tau"] = float(rng.uniform(-2.0, 2.0))
        for d in w["tdoas"][7::3]:
            d["tau"] = float(rng.uniform(-2.0, 2.0))
    cal = calibrate_speed(windows, SENSORS, 1500.0)
    assert cal.estimate is None and cal.speed_mps == 1500.0


def _profile_window(p_true, t0, c0=1475.0, g=0.0165, c_file=1494.0):
    """A written window whose delays follow the linear profile ``c(d) = c0 + g d`` along
    straight rays (the simulator's model), solved at the file's one speed."""
    from factors.tdoa.gradient import travel_times

    q = np.array(PAIRS)
    t, _, _ = travel_times(p_true, SENSORS, c0, g, 0.0)
    taus = t[q[:, 0]] - t[q[:, 1]]
    start = least_squares(lambda x: (predicted_tdoas(x, SENSORS, q, c=c_file) - taus) * 1e6,
                          p_true).x
    window = _window(p_true, c_file, c_file, t0)
    for d, tau in zip(window["tdoas"], taus, strict=True):
        d["tau"] = float(tau)
    window["sources"][0] |= {"x": start[0], "y": start[1], "z": start[2]}
    return window


def test_a_depth_gradient_is_estimated_where_one_speed_leaves_fixes_off():
    """Delays of a speed linear in depth (0.0165 1/s, whales 600-1,100 m deep over sensors at
    1,480-1,610 m): the profile estimated on the graph puts every fix within centimetres;
    one speed (``--no-speed-gradient``) leaves them about a metre off."""
    whales = np.array([[800.0, 600, -900], [1200, 1500, -700], [-300, 400, -1100],
                       [2000, -500, -800], [500, 2000, -600]])
    windows = [_profile_window(p, 2.0 * k) for k, p in enumerate(whales)]
    cal = calibrate_speed(windows, SENSORS, 1494.0)
    est = cal.estimate
    assert est.gradient_per_s == pytest.approx(0.0165, abs=2e-4)
    d_ref = est.reference_depth_m  # halfway between the sensors and the whales
    assert d_ref == pytest.approx(0.5 * np.mean(-SENSORS[:, 2]) + 0.5 * np.mean(-whales[:, 2]),
                                  abs=5.0)
    assert est.speed_mps == pytest.approx(1475.0 + 0.0165 * d_ref, abs=0.1)
    assert "gradient 0.0165" in cal.note and cal.record()["gradient_per_s"] == est.gradient_per_s
    pos = np.array([[cal.apply(w)["sources"][0][a] for a in "xyz"] for w in windows])
    assert np.max(np.linalg.norm(pos - whales, axis=1)) < 0.05
    one = calibrate_speed(windows, SENSORS, 1494.0, gradient=False)
    assert np.isnan(one.estimate.gradient_sigma_per_s) and "gradient" not in one.note
    pos1 = np.array([[one.apply(w)["sources"][0][a] for a in "xyz"] for w in windows])
    assert np.median(np.linalg.norm(pos1 - whales, axis=1)) > 0.5


def test_a_gradient_the_fixes_do_not_tell_is_not_used():
    """Four-sensor fixes taught by far delays recruited by one speed's consensus: no gradient
    is estimated from them; and delays of one speed (a constant sea) keep one speed: the
    profile fits them no better (F test)."""
    rng = np.random.default_rng(3)
    windows = [_four_sensor_window(p, 1484.0, 1500.0, 2.0 * k, rng)
               for k, p in enumerate(TRUE)]
    cal = calibrate_speed(windows, SENSORS, 1500.0)
    assert cal.estimate is not None and np.isnan(cal.estimate.gradient_sigma_per_s)
    assert "depth gradient not estimated" in cal.note
    whales = np.array([[800.0, 600, -900], [1200, 1500, -700], [-300, 400, -1100],
                       [2000, -500, -800], [500, 2000, -600]])
    flat = [_profile_window(p, 2.0 * k, c0=1490.0, g=0.0, c_file=1500.0)
            for k, p in enumerate(whales)]
    for w in flat:  # TDOA noise at the sigma (1e-7 s)
        for d in w["tdoas"]:
            d["tau"] += float(rng.normal(0.0, 1e-7))
    one = calibrate_speed(flat, SENSORS, 1500.0)
    assert np.isnan(one.estimate.gradient_sigma_per_s)
    assert "fits no better than one speed" in one.note
    assert one.speed_mps == pytest.approx(1490.0, abs=0.1)
