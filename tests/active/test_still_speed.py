"""Speed floor of the motion test from the position error (``--still-wander-s``, issue 20)."""

from __future__ import annotations

import numpy as np
import pytest

from fusion.active.clutter import ClutterMap
from fusion.active.motion import STILL_WANDER_S, motion_statistic, still_speed_mps
from fusion.active.tracker import Tracker
from fusion.active.types import Ping
from fusion.cli import build_parser
from fusion.commands.track import track_options

SCAN_S = 1.68   # the Autoferry radar's scan period
SIGMA_M = 3.0   # radar position error per axis


def _radar_tracker(**kw) -> Tracker:
    """M-of-N with the stationary hold, fixed 3-m errors, a map that flags nothing."""
    opts = dict(confirm_llr=None, clutter_map=ClutterMap(min_pings=50), noise="fixed",
                position_sigma_m=SIGMA_M, init_exclusion_m=SIGMA_M, speed_sigma_mps=1.5,
                accel_psd=1.0)
    opts.update(kw)
    return Tracker(**opts)


def _boat(speed_mps: float, n: int = 14) -> list[Ping]:
    return [Ping(k, SCAN_S * k, np.array([[speed_mps * SCAN_S * k, 50.0]])) for k in range(n)]


def _first_confirmed(res) -> int | None:
    return next((k for k, p in enumerate(res.pings) if (p.status == "confirmed").any()), None)


def test_still_speed_known_answers_and_bad_input():
    assert still_speed_mps(125.0) == pytest.approx(0.5)
    assert still_speed_mps(3.3, 110.0) == pytest.approx(0.03)
    assert STILL_WANDER_S == 250.0
    for bad in ((0.0, 250.0), (3.0, 0.0), (float("nan"), 250.0)):
        with pytest.raises(ValueError):
            still_speed_mps(*bad)


def test_tracker_floor_follows_the_position_error_unless_given():
    assert _radar_tracker().min_speed_mps == pytest.approx(SIGMA_M / 250.0)
    assert _radar_tracker(still_wander_s=100.0).min_speed_mps == pytest.approx(0.03)
    assert _radar_tracker(min_speed_mps=0.5).min_speed_mps == 0.5
    assert _radar_tracker().motion_test.min_speed_mps == pytest.approx(0.012)


def test_slow_boat_on_radar_is_confirmed_scans_earlier_than_with_the_fixed_floor():
    """1 m/s, 1.68-s scans, exact positions, 3-m errors: k detections give
    S_tt = 1.68^2 k (k^2 - 1) / 12 and the statistic (1 - floor)^2 S_tt / 9, which first
    exceeds chi2.ppf(0.999, 2) = 13.82 at k = 9 with the derived floor (0.012 m/s) and at k = 13
    with the former fixed 0.5 m/s."""
    pings = _boat(1.0)
    t = SCAN_S * np.arange(14)
    xy = np.column_stack([t, np.full(14, 50.0)])
    for floor, k_first in ((SIGMA_M / 250.0, 9), (0.5, 13)):
        qs = [motion_statistic(t[:k], xy[:k], SIGMA_M, min_speed_mps=floor) for k in range(3, 15)]
        assert [q > 13.8155 for q in qs].index(True) + 3 == k_first
    assert _first_confirmed(_radar_tracker().run(pings)) == 8
    assert _first_confirmed(_radar_tracker(min_speed_mps=0.5).run(pings)) == 12


def test_moored_boat_stays_held_with_the_derived_floor():
    rng = np.random.default_rng(3)
    pings = [Ping(k, SCAN_S * k, np.array([[0.0, 50.0]]) + rng.normal(0, SIGMA_M, (1, 2)))
             for k in range(30)]
    assert _radar_tracker().run(pings).confirmed_ids().size == 0
    assert _radar_tracker(hold_stationary=False).run(pings).confirmed_ids().size == 1


def test_track_command_options_reach_the_library():
    parse = build_parser("track").parse_args
    base = ["track", "--detections", "d.csv", "--out", "t.csv"]
    opts = track_options(parse(base))
    assert opts.min_speed_mps is None and opts.still_wander_s == 250.0
    opts = track_options(parse([*base, "--still-wander-s", "100", "--min-speed-mps", "0.2"]))
    assert opts.still_wander_s == 100.0 and opts.min_speed_mps == 0.2
