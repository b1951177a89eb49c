"""Sensor positions refined from a recording's fixes (``fusion localize
--sensor-position-sigma-m``, default 2 m): survey errors the fixes of a moving whale tell, a
still whale whose fixes do not, and delays bent window by window (no survey error) that the
held-out check refuses.

(A whale that moves a few metres with survey errors passes both checks; over survey errors
drawn from the prior its fixes' mean error halves but the median grows: docs/localization.md
section 24 says so.)"""

import numpy as np

from fusion.click_defaults import SENSOR_POSITION_SIGMA_M
from fusion.localization.sensor_positions import estimate_sensor_positions
from fusion.pipelines.sound_speed import calibrate_speed, fix_tdoas
from tests.pipelines.written_windows import written_window

SURVEYED = np.array([[0.0, 0, -1500], [3200, 150, -1610], [1500, 2900, -1550],
                     [-1800, 1400, -1480], [400, -2500, -1590]])
#: Survey errors of 1-3 m per axis (zero mean: the gauge the priors hold is the survey's mean).
ERRORS = np.array([[2.0, -1.5, 1.0], [-2.5, 1.0, -2.0], [1.5, 2.5, 1.5], [-1.0, -2.0, 2.5],
                   [0.0, 0.0, -3.0]])
TRUE_SENSORS = SURVEYED + ERRORS
PAIRS = [(i, j) for i in range(5) for j in range(i + 1, 5)]
#: A whale crossing the range (a few hundred metres per fix).
CROSSING = np.array([[-600.0, -300, -900], [0, 200, -1000], [600, 700, -1100], [1200, 1200, -950],
                     [1800, 1600, -800], [2400, 2100, -1000]])


def _window(p_true, t0):
    """A written window: delays of the true sensors, its fix solved on the surveyed ones."""
    return written_window(p_true, t0, PAIRS, true_sensors=TRUE_SENSORS, sensors=SURVEYED,
                          sigma_s=1e-6)


def _errors(windows, cal):
    pos = np.array([[cal.apply(w)["sources"][0][a] for a in "xyz"] for w in windows])
    return np.linalg.norm(pos - CROSSING[:len(windows)], axis=1)


def test_a_crossing_whale_tells_the_survey_errors():
    windows = [_window(p, 2.0 * k) for k, p in enumerate(CROSSING)]
    surveyed = calibrate_speed(windows, SURVEYED, 1500.0, gradient=False, sensor_sigma_m=0.0)
    refined = calibrate_speed(windows, SURVEYED, 1500.0, gradient=False)  # the default: 2 m
    assert SENSOR_POSITION_SIGMA_M == 2.0
    before, after = _errors(windows, surveyed), _errors(windows, refined)
    assert np.median(before) > 3.0  # the survey errors move the fixes by metres
    # what is left is the gauge the priors hold (a rotation or scale of the whole array)
    assert np.median(after) < 0.4 * np.median(before)
    rec = refined.record()["sensor_positions"]
    assert rec["prior_sigma_m"] == 2.0 and len(rec["sensors"]) == 5
    pos = np.array([[s[a] for a in "xyz"] for s in rec["sensors"]])
    np.testing.assert_allclose(pos, refined.sensors)
    # the refined fixes and positions explain the delays the surveyed ones could not
    rms = [[cal.apply(w)["sources"][0]["residual_rms_s"] for w in windows]
           for cal in (surveyed, refined)]
    assert np.max(rms[1]) < 0.1 * np.median(rms[0])
    # each sigma finite and at most the prior's (the gauge the survey holds)
    sig = np.array([s["sigma_m"] for s in rec["sensors"]])
    assert np.all(np.isfinite(sig)) and np.all(sig <= 2.0 + 1e-6)
    assert "sensor positions (prior +- 2 m" in refined.note and "F = " in refined.note
    assert "sensor_positions" not in surveyed.record()


def test_a_still_whale_keeps_the_surveyed_positions_and_says_so():
    windows = [_window(CROSSING[1], 2.0 * k) for k in range(4)]  # one place, four windows
    cal = calibrate_speed(windows, SURVEYED, 1500.0, gradient=False, sensor_sigma_m=2.0)
    np.testing.assert_array_equal(cal.sensors, SURVEYED)
    assert "sensor_positions" not in cal.record()
    assert "sensor positions: the array file's" in cal.note and "do not tell them" in cal.note


def _biased_window(p_true, t0, bias_s):
    """A window of exact sensors whose sensor 4 delays are off by `bias_s` in this window
    alone (a misread path, a whale that moved within the window): no survey error."""
    w = written_window(p_true, t0, PAIRS, true_sensors=SURVEYED, sensors=SURVEYED, sigma_s=1e-6)
    for d in w["tdoas"]:
        d["tau"] += bias_s * ((d["pair"][0] == 4) - (d["pair"][1] == 4))
    return w


def test_delays_bent_window_by_window_are_not_taken_for_a_survey_error():
    biases = np.array([30.0, -20, 25, -35, 20, -30]) * 1e-6
    windows = [_biased_window(p, 2.0 * k, b)
               for k, (p, b) in enumerate(zip(CROSSING, biases, strict=True))]
    cal = calibrate_speed(windows, SURVEYED, 1500.0, gradient=False)
    # the offsets fit the pooled fixes far better (F in the hundreds), but offsets fitted
    # without a fix make its delays worse: the held-out check keeps the survey (without it
    # the fixes went from 0.1-0.5 m to 4-43 m off)
    assert "held-out chi-square" in cal.note and "not a survey error" in cal.note
    np.testing.assert_array_equal(cal.sensors, SURVEYED)
    assert np.max(_errors(windows, cal)) < 1.0


def test_the_offset_parameters_the_fixes_determine_are_counted():
    """One place gives every fix the same geometry: its one redundant delay per fix (five
    sensors, four delays, three coordinates) tells one combination of the 15 offsets and the
    speed; a crossing whale tells more. (The F test divided the chi-square drop by 15 before.)"""
    def determined(points):
        fixes = [fix_tdoas(w, w["sources"][0], SURVEYED, 1500.0)
                 for w in (_window(p, 2.0 * k) for k, p in enumerate(points))]
        return estimate_sensor_positions(fixes, n_real=5, nominal_mps=1500.0,
                                         sigma_m=2.0).n_determined
    still = determined([CROSSING[1]] * 4)
    crossing = determined(CROSSING)
    assert 0.3 < still < 1.2  # one combination, shared with the speed its delays also tell
    assert 1.5 < crossing < 15.0 and crossing > still + 0.5
