"""Tests of fusion.simulate.bearings (seeded bearing-time scenarios)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from fusion.geometry import compass_bearing_deg, wrap_deg
from fusion.io import read_bearings, read_json, read_table
from fusion.simulate import get_writer
from fusion.simulate.bearings import VARIED_RANGES, simulate_bearings, varied_settings


@pytest.fixture(scope="module")
def scenario():
    return simulate_bearings(seed=3, n_tracks=10, n_crossing_pairs=2, n_wrap_crossings=2,
                             n_near_miss_pairs=1, n_parallel_pairs=1, clutter_rate=0.5,
                             p_detect=0.9)


def test_same_seed_same_scenario():
    """The same seed gives identical measurements; another seed does not."""
    a, b = simulate_bearings(seed=8), simulate_bearings(seed=8)
    assert_array_equal(a.bearing_deg, b.bearing_deg)
    assert a.crossings == b.crossings
    assert not np.array_equal(a.bearing_deg, simulate_bearings(seed=9).bearing_deg)


def test_truth_is_the_compass_bearing_of_the_geometry(scenario):
    """True bearings equal compass bearings from own ship to targets; rates their derivative."""
    ref = compass_bearing_deg(scenario.ownship_xy[None], scenario.target_xy)
    assert_allclose(wrap_deg(scenario.truth_bearing_deg - ref), 0.0, atol=1e-9)
    unw = np.degrees(np.unwrap(np.radians(scenario.truth_bearing_deg), axis=1))
    num = np.gradient(unw, scenario.truth_time, axis=1)
    assert_allclose(num[:, 1:-1], scenario.truth_bearing_rate_deg_per_s[:, 1:-1], atol=2e-4)


def test_crossings_are_sign_changes_of_the_true_difference(scenario):
    """Each listed crossing brackets a sign change; never-crossing pairs have none."""
    tb, t = scenario.truth_bearing_deg, scenario.truth_time
    assert len(scenario.crossings) >= 2
    for a, b, tc in scenario.crossings:
        k = np.searchsorted(t, tc)
        d = wrap_deg(tb[b, [k - 1, k]] - tb[a, [k - 1, k]])
        assert d[0] * d[1] <= 0 and np.all(np.abs(d) < 90)
    for a, b in scenario.non_crossing_pairs:
        d = wrap_deg(tb[b] - tb[a])
        close = np.abs(d) < 90
        assert not np.any((np.sign(d[:-1]) != np.sign(d[1:])) & close[:-1] & close[1:])
    planned = {(c.track_a, c.track_b) for c in scenario.crossings}
    assert set(scenario.planned_crossing_pairs) <= planned


def test_wrap_crossings_happen_at_north_and_south(scenario):
    """With two wrap crossings, the planned pairs cross within 1 deg of 0 and of 180 deg."""
    at = []
    for a, b, tc in scenario.planned_crossings:
        listed = [c.t_cross for c in scenario.crossings if (c.track_a, c.track_b) == (a, b)]
        assert np.min(np.abs(np.array(listed) - tc)) < 1e-6
        k = int(np.argmin(np.abs(scenario.truth_time - tc)))
        rate = scenario.truth_bearing_rate_deg_per_s[a, k]
        at.append(scenario.truth_bearing_deg[a, k] + rate * (tc - scenario.truth_time[k]))
    assert abs(wrap_deg(at[0])) < 1.0
    assert abs(wrap_deg(at[1] - 180.0)) < 1.0


def test_near_miss_and_parallel_pairs(scenario):
    """Near misses come within the miss interval without crossing; parallel offsets are constant."""
    tb = scenario.truth_bearing_deg
    for a, b in scenario.near_miss_pairs:
        d = np.abs(wrap_deg(tb[b] - tb[a]))
        assert 3.0 - 1e-6 <= d.min() <= 8.0
        assert (a, b) in scenario.non_crossing_pairs
    for a, b in scenario.parallel_pairs:
        d = wrap_deg(tb[b] - tb[a])
        assert np.ptp(d) < 1e-9 and 3.0 <= abs(d[0]) <= 15.0


def test_measurements_noise_detection_and_clutter(scenario):
    """Noise sd, detection probability and clutter rows follow the options."""
    known = scenario.track_id >= 0
    err = wrap_deg(scenario.bearing_deg[known] - scenario.true_bearing_deg[known])
    assert abs(np.std(err) - scenario.noise_deg) < 0.05
    n_t = scenario.truth_time.size
    assert abs(known.sum() / (scenario.n_tracks * n_t) - 0.9) < 0.03
    assert abs((~known).sum() / n_t - 0.5) < 0.1
    assert np.all(np.isnan(scenario.true_bearing_deg[~known]))
    assert np.all((scenario.bearing_deg >= 0) & (scenario.bearing_deg < 360))
    assert np.all(np.diff(scenario.time) >= 0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_tracks": 3}, "n_tracks"),
        ({"n_wrap_crossings": 3}, "n_wrap_crossings"),
        ({"p_detect": 0.0}, "p_detect"),
        ({"noise_deg": -1.0}, "noise_deg"),
        ({"range_m": (5.0, 1.0)}, "range_m"),
        ({"sample_period_s": 0.0}, "sample_period_s"),
    ],
)
def test_bad_options_raise(kwargs, match):
    """Bad options raise ValueError naming the option."""
    with pytest.raises(ValueError, match=match):
        simulate_bearings(seed=0, **kwargs)


def test_write_scenario_files(tmp_path):
    """`fusion simulate bearings` writes readable bearings, truth table and truth.json."""
    paths = get_writer("bearings")(tmp_path, seed=1)
    assert {p.name for p in paths} == {"bearings.csv", "truth.json", "truth_bearings.csv"}
    b = read_bearings(tmp_path / "bearings.csv")
    assert np.any(b["track_id"] == -1)
    truth = read_json(tmp_path / "truth.json")
    assert truth["kind"] == "bearings" and truth["sample_period_s"] == 10.0
    assert all(set(c) == {"track_a", "track_b", "t_cross"} for c in truth["crossings"])
    tt = read_table(tmp_path / "truth_bearings.csv",
                    required=("track_id", "time", "bearing_deg", "bearing_rate_deg_per_min"))
    assert len(tt) == 8 * 181


@pytest.mark.parametrize("seed", range(4))
def test_varied_settings_lie_in_documented_ranges(seed):
    """Every drawn assumption of a varied scenario lies in VARIED_RANGES."""
    st = varied_settings(seed)
    r = VARIED_RANGES
    assert r["sample_period_s"][0] <= st["sample_period_s"] <= r["sample_period_s"][1]
    assert r["duration_s"][0] <= st["duration_s"] <= r["duration_s"][1]
    assert np.all((np.array(st["noise_deg"]) >= 0.2) & (np.array(st["noise_deg"]) <= 2.0))
    assert len(st["noise_deg"]) == st["n_tracks"]
    assert r["n_crossing_pairs"][0] <= st["n_crossing_pairs"] <= r["n_crossing_pairs"][1]
    assert st == varied_settings(seed)
    assert st != varied_settings(seed + 1)


def test_varied_scenario_rates_noise_and_gaps():
    """Planned crossings have the drawn rate differences; per-track noise and gaps are applied."""
    sc = simulate_bearings(seed=5, n_tracks=8, n_crossing_pairs=3, n_wrap_crossings=0,
                           n_near_miss_pairs=1, noise_deg=[0.2, 2.0] * 4,
                           crossing_rate_deg_per_min=(0.3, 20.0), gaps_per_hour=4.0,
                           gap_s=(60.0, 60.0), range_m=(1000.0, 15000.0),
                           target_speed_mps=(1.0, 10.0), min_range_m=500.0)
    rate = dict(zip(sc.crossings, sc.crossing_rate_diff_deg_per_min, strict=True))
    for c in sc.planned_crossings:
        listed = [x for x in sc.crossings if (x.track_a, x.track_b) == (c.track_a, c.track_b)
                  and abs(x.t_cross - c.t_cross) < 1e-6]
        assert 0.3 - 1e-6 <= abs(rate[listed[0]]) <= 20.0 + 1e-6
        # independent check: the truth table's rate difference at the nearest sample
        k = int(np.argmin(np.abs(sc.truth_time - c.t_cross)))
        ref = 60 * (sc.truth_bearing_rate_deg_per_s[c.track_b, k]
                    - sc.truth_bearing_rate_deg_per_s[c.track_a, k])
        assert abs(ref - rate[listed[0]]) < 0.05 * abs(rate[listed[0]]) + 0.05
    known = sc.track_id >= 0
    err = wrap_deg(sc.bearing_deg[known] - sc.true_bearing_deg[known])
    for k, sd in ((0, 0.2), (1, 2.0)):
        assert abs(np.std(err[sc.track_id[known] == k]) / sd - 1.0) < 0.15
    assert_allclose(sc.track_noise_deg, [0.2, 2.0] * 4)
    assert len(sc.gaps) > 0
    for k, g0, g1 in sc.gaps:
        inside = (sc.track_id == k) & (sc.time >= g0) & (sc.time <= g1)
        assert not np.any(inside) and g1 - g0 == 60.0


def test_write_varied_scenario_records_settings(tmp_path):
    """`fusion simulate bearings --vary` writes the drawn settings; the files follow them."""
    paths = get_writer("bearings")(tmp_path, seed=2, vary=True)
    truth = read_json(tmp_path / "truth.json")
    st = varied_settings(2)
    assert truth["settings"]["sample_period_s"] == pytest.approx(st["sample_period_s"])
    assert truth["sample_period_s"] == pytest.approx(st["sample_period_s"])
    b = read_bearings(paths[0])
    assert np.unique(b["track_id"][b["track_id"] >= 0]).size == st["n_tracks"]
    assert len(truth["crossing_rate_diff_deg_per_min"]) == len(truth["crossings"])


def test_cli_vary_switch(tmp_path, capsys):
    """`fusion simulate bearings --vary` writes the varied scenario of the seed."""
    from fusion.cli import main

    assert main(["simulate", "bearings", "--vary", "--seed", "4", "--out", str(tmp_path)]) == 0
    truth = read_json(tmp_path / "truth.json")
    assert truth["settings"]["n_tracks"] == varied_settings(4)["n_tracks"]
    assert "bearings.csv" in capsys.readouterr().out
