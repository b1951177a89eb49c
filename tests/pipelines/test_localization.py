"""Whale localization end to end: sources near the truth, tracks with the whale's speed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fusion.pipelines.localization import (
    ClickLocalization,
    LocalizerSettings,
    result_document,
    settings_from_args,
    track_windows,
    whale_localizer,
)
from fusion.simulate.clicks import simulate_clicks


@pytest.fixture(scope="module")
def localized():
    """Two whales, a bottom-mounted 5-sensor array, 30 s at 30 dB, every window localized by the
    library's default chain (``ClickLocalization()``: replica, band, echoes and sea floor decided
    from the recording, paths per window)."""
    sc = simulate_clicks(seed=0, n_sensors=5, n_sources=2, duration_s=30.0, snr_db=30.0)
    pipe = ClickLocalization()
    lws = pipe.run_array(sc.audio, sc.fs, sc.sensors)
    return sc, lws


def test_observable_sources_lie_on_a_whale(localized):
    """Every source flagged observable is within 5 m of one of the whales' tracks, and the
    recording's decisions find the whales in most windows (20 fixes in 15 windows of two
    whales; 12 with ``ClickLocalization(decide=False)``). Every window read along surface paths
    too (``LocalizerSettings(surface_paths=True)``, or ``whale_localizer()`` as this chain ran
    before) adds fixes ~1 km from both whales (docs/localization.md section 14)."""
    sc, lws = localized
    fixes = [(lw, f) for lw in lws if lw.output is not None for f in lw.output.sources
             if f.observable]
    for lw, f in fixes:
        mid = 0.5 * (lw.window.t_start + lw.window.t_end)
        times = np.linspace(mid - 4.0, mid, 81)  # emission times around the window
        d = min(np.min(np.linalg.norm(s.position_at(times) - f.position, axis=1))
                for s in sc.sources)
        assert d < 5.0
    assert len(fixes) >= 16


def test_track_follows_the_whale(localized):
    """The fixes of consecutive windows form one track whose smoothed speed is the whale's."""
    sc, lws = localized
    tracks = track_windows(lws)
    longest = max(tracks, key=lambda t: t.times.size)
    assert longest.times.size >= 6
    start = longest.positions[0]
    whale = min(sc.sources, key=lambda s: np.linalg.norm(s.position_at([longest.times[0] - 1.0])[0]
                                                          - start))
    speed = np.linalg.norm(longest.velocities[longest.times.size // 2][:2])
    assert speed == pytest.approx(whale.speed_mps, rel=0.1)
    doc = result_document(lws, tracks=tracks)
    assert doc["tracks"][longest.track_id]["points"][0]["t"] == longest.times[0]
    assert len(doc["windows"]) == len(lws)


def test_whale_localizer_settings():
    """whale_localizer: water column from the floor to the surface, paths read; None: direct."""
    loc = whale_localizer(bottom_z=-1700.0)
    assert loc.region.water_column == (-1700.0, 0.0) and loc.surface_z == 0.0
    assert loc.finder.max_candidates == 16 and loc.min_tdoas == 5.5
    direct = whale_localizer(surface_z=None)
    assert direct.surface_z is None and direct.region.water_column is None


_BELOW = np.array([[0.0, 0, -1600], [1500, 0, -1650], [0, 1500, -1700], [1500, 1500, -1620]])
_TANK = np.array([[-0.9, -0.9, -0.7], [-0.9, -0.9, 0.5], [0.9, -0.9, -0.7], [0.0, 0.0, 0.0]])


def _same(a, b) -> bool:
    """Two localizers configured alike (the settings that differ between the readings)."""
    return (a.method == b.method and a.surface_z == b.surface_z and a.region == b.region
            and a.finder.max_candidates == b.finder.max_candidates and a.min_tdoas == b.min_tdoas
            and a.competition == b.competition)


def test_settings_default_decides_the_paths_below_the_surface(caplog):
    """Default settings, sensors below z = 0: direct paths first, whale_localizer as the
    surface-path fallback; no log line."""
    first, fallback = LocalizerSettings().localizers(_BELOW)
    assert _same(first, whale_localizer(surface_z=None)) and first.surface_z is None
    assert _same(fallback, whale_localizer()) and fallback.surface_z == 0.0
    assert fallback.finder.max_candidates == 16 and fallback.min_tdoas == 5.5
    first, fallback = LocalizerSettings(sea_floor_z=-1700.0).localizers(_BELOW)
    assert _same(first, whale_localizer(surface_z=None, bottom_z=-1700.0))
    assert _same(fallback, whale_localizer(bottom_z=-1700.0))
    for forced in (True, False):  # --surface-paths / --direct-only: no fallback
        assert LocalizerSettings(surface_paths=forced).localizers(_BELOW)[1] is None
    assert not [r for r in caplog.records if r.levelname == "WARNING"]


_FIVE = np.vstack([_BELOW, [[700.0, 800.0, -1680.0]]])


def _synthetic_window(source, with_echoes: bool):
    """A front-end window of exact valid TDOAs of one source on `_FIVE`: the direct-path delays
    of every pair, plus (with echoes) those between its surface echoes (image at -z)."""
    from fusion.pipelines.clicks import ClickWindow, WindowTdoa

    c = 1500.0
    pairs = [(i, j) for i in range(5) for j in range(i + 1, 5)]
    points = [source] + ([source * [1.0, 1.0, -1.0]] if with_echoes else [])
    tdoas = []
    for p in points:
        r = np.linalg.norm(_FIVE - p, axis=1) / c
        for i, j in pairs:
            tdoas.append(WindowTdoa(
                pair=(i, j), tau_s=r[i] - r[j], tau_coarse_s=r[i] - r[j], sigma_s=2e-6,
                crb_s=2e-6, snr_db=20.0, rate=0.0, scm_peak=20.0, n_clicks=20,
                features=np.zeros(4), llr=10.0, passes=True, confirmed=True))
    # cross-pair association of TDOAs sharing one sensor, at the size of 20 matched clicks
    shares = 20.0 * np.array([[len({*a.pair} & {*b.pair}) == 1 for b in tdoas] for a in tdoas])
    return ClickWindow(0.0, 12.0, (), tuple(tdoas), shares)


def test_surface_paths_are_read_only_where_direct_sources_leave_tdoas_unexplained():
    """Direct delays alone: the default solves along direct paths only (same as --direct-only).
    Echo delays too: direct sources explain half, the surface reading all of them -> kept."""
    from fusion.geometry import SensorArray
    from fusion.pipelines.localization import explained_fraction

    sensors = SensorArray(_FIVE, 1500.0)
    source = np.array([300.0, 500.0, -900.0])
    auto = ClickLocalization(localizer=LocalizerSettings(sea_floor_z=-1700.0))
    direct = ClickLocalization(localizer=LocalizerSettings(surface_paths=False,
                                                           sea_floor_z=-1700.0))
    clean = _synthetic_window(source, with_echoes=False)
    a, d = auto.localize(clean, sensors), direct.localize(clean, sensors)
    assert explained_fraction(d.output) == 1.0
    assert [f.position.tolist() for f in a.output.sources] == [
        f.position.tolist() for f in d.output.sources]
    assert np.linalg.norm(a.output.sources[0].position - source) < 1.0

    echoes = _synthetic_window(source, with_echoes=True)
    a, d = auto.localize(echoes, sensors), direct.localize(echoes, sensors)
    assert explained_fraction(d.output) <= 0.6
    assert explained_fraction(a.output) > 0.9
    assert min(np.linalg.norm(f.position - source) for f in a.output.sources) < 1.0


def test_settings_fall_back_to_direct_paths_with_one_line(caplog):
    """A sensor not below z = 0 (a tank array): direct paths, the localizer's own defaults,
    one logged line; surface paths or a sea floor asked for there are refused."""
    loc, fallback = LocalizerSettings().localizers(_TANK)
    assert loc.surface_z is None and loc.finder.max_candidates == 8 and loc.min_tdoas == 3.5
    assert fallback is None
    assert len([r for r in caplog.records if "direct paths only" in r.message]) == 1
    with pytest.raises(ValueError, match="below the sea surface"):
        LocalizerSettings(surface_paths=True).localizer(_TANK)
    with pytest.raises(ValueError, match="below the sea surface"):
        LocalizerSettings(surface_paths=False, sea_floor_z=-2.0).localizer(_TANK)


def test_settings_direct_only_and_explicit_values():
    """--direct-only equals the earlier direct reading; explicit candidates and weights apply
    to either reading; a floor above the deepest sensor is refused."""
    direct = LocalizerSettings(surface_paths=False, sea_floor_z=-1700.0).localizer(_BELOW)
    assert _same(direct, whale_localizer(surface_z=None, bottom_z=-1700.0))
    loc = LocalizerSettings(method="eq18", max_candidates=5, min_source_tdoas=7.0
                            ).localizer(_BELOW)
    assert _same(loc, whale_localizer("eq18", max_candidates=5, min_tdoas=7.0))
    d = LocalizerSettings(surface_paths=False, max_candidates=5, min_source_tdoas=7.0
                          ).localizer(_BELOW)
    assert (d.surface_z, d.finder.max_candidates, d.min_tdoas, d.competition.min_weight) == (
        None, 5, 7.0, 7.0)
    with pytest.raises(ValueError, match="above the deepest sensor"):
        LocalizerSettings(sea_floor_z=-1650.0).localizer(_BELOW)
    with pytest.raises(ValueError, match="method must be"):
        LocalizerSettings(method="best")


def test_cli_options_give_the_settings():
    """fusion localize's options map one to one onto LocalizerSettings (defaults: all auto)."""
    from fusion.cli import build_parser

    base = ["localize", "--audio", "a.flac", "--array", "j.json", "--out", "r.json"]
    parser = build_parser("localize")
    assert settings_from_args(parser.parse_args(base)) == LocalizerSettings()
    args = parser.parse_args(base + ["--direct-only", "--sea-floor-z-m", "-1700", "--candidates",
                                     "12", "--min-source-tdoas", "6", "--method", "eq17"])
    assert settings_from_args(args) == LocalizerSettings(
        method="eq17", surface_paths=False, sea_floor_z=-1700.0, max_candidates=12,
        min_source_tdoas=6.0)
    assert settings_from_args(parser.parse_args(base + ["--surface-paths"])).surface_paths
    with pytest.raises(SystemExit):
        parser.parse_args(base + ["--surface-paths", "--direct-only"])


def test_cli_localize_writes_sources_and_tracks(tmp_path):
    """`fusion localize` on a written scenario: windows every 2 s, sources near the whale,
    and one track through them."""
    from fusion.cli import main
    from fusion.io import read_localization
    from fusion.simulate.clicks import write_click_scenario

    sc = simulate_clicks(seed=7001, n_sensors=5, n_sources=1, duration_s=20.0, snr_db=36.0)
    write_click_scenario(tmp_path / "sc", sc)
    out = tmp_path / "r.json"
    assert main(["localize", "--audio", str(tmp_path / "sc" / "audio.flac"), "--array",
                 str(tmp_path / "sc" / "array.json"), "--out", str(out), "--quiet"]) == 0
    res = read_localization(out)
    assert [w.t_start for w in res.windows] == [0.0, 2.0, 4.0, 6.0, 8.0]
    fixes = [s for w in res.windows for s in w.sources]
    assert fixes
    assert len(res.tracks) >= 1 and len(res.tracks[0][1]) >= 2


def _true_tau(sc, pair, t_i):
    """Direct-path delay and drift, at arrival time ``t_i`` on sensor i, of the nearest whale.

    Exact for the simulated motion: the emission arriving at ``t_i`` solves
    ``t_e + |p(t_e) - s_i| / c = t_i`` (fixed point; the whale moves at ~1e-3 c).
    """
    i, j = pair
    pos, c = sc.sensors.positions, sc.sensors.sound_speed

    def tau(s, t):
        te = t - np.linalg.norm(s.position_at([t])[0] - pos[i]) / c
        for _ in range(4):
            te = t - np.linalg.norm(s.position_at([te])[0] - pos[i]) / c
        p = s.position_at([te])[0]
        return (np.linalg.norm(p - pos[i]) - np.linalg.norm(p - pos[j])) / c

    near = min(sc.sources, key=lambda s: np.min(np.abs(s.arrival_times[:, i] - t_i)))
    h = 0.05
    return tau(near, t_i), (tau(near, t_i + h) - tau(near, t_i - h)) / (2 * h)


def test_tdoas_hold_at_their_own_time_with_their_rate(localized):
    """Each valid TDOA's ``tau`` is the true delay at its ``t`` (µs) and ``rate`` its drift."""
    sc, lws = localized
    doc = result_document(lws)
    errs, rate_errs = [], []
    for w in doc["windows"]:
        assert all(d["t"] == 0.5 * (w["t_start"] + w["t_end"]) for d in w["tdoas"])
        for d in w["tdoas"]:
            if not d["valid"]:
                continue
            tau, rate = _true_tau(sc, tuple(d["pair"]), d["t"])
            if abs(d["tau"] - tau) < 1e-3:  # a delay of a direct path (not an echo's)
                errs.append(abs(d["tau"] - tau))
                rate_errs.append(abs(d["rate"] - rate))
    assert len(errs) >= 50
    assert np.median(errs) < 0.5e-6  # ~1.5e-7 measured (sigma ~1.5e-7); 4e-4 with t off by 3 s
    assert np.median(rate_errs) < 1e-6  # s/s (~1.2e-7 measured); drifts here ~7e-4 s/s


def test_a_window_the_localizer_cannot_solve_says_why():
    """A window the localizer refuses (here a TDOA whose sigma is not finite) carries the reason,
    written as ``not_localized``, instead of a silent empty result."""
    import dataclasses

    from fusion.geometry import SensorArray
    from fusion.pipelines.clicks import ClickWindow

    sensors = SensorArray(_FIVE, 1500.0)
    full = _synthetic_window(np.array([300.0, 500.0, -900.0]), with_echoes=False)
    bad = (dataclasses.replace(full.tdoas[0], sigma_s=float("nan")),) + full.tdoas[1:]
    window = ClickWindow(0.0, 12.0, (), bad, full.alpha)
    lw = ClickLocalization(localizer=LocalizerSettings(sea_floor_z=-1700.0)).localize(window,
                                                                                      sensors)
    assert lw.output is None and "sigma" in lw.note
    assert result_document([lw])["windows"][0]["not_localized"] == lw.note
    good = ClickLocalization(localizer=LocalizerSettings(sea_floor_z=-1700.0)).localize(
        full, sensors)
    assert good.note == "" and "not_localized" not in result_document([good])["windows"][0]


def _simulated(tmp_path, seed, *extra):
    """`fusion simulate clicks` of one whale, 5 sensors, 30 s, floor and surface echoes (and
    options `extra`) into ``tmp_path/s``; its truth."""
    from fusion.cli import main

    assert main(["simulate", "clicks", "--seed", str(seed), "--whales", "1", "--sensors", "5",
                 "--duration-s", "30", "--echo", "both", *extra,
                 "--out", str(tmp_path / "s")]) == 0
    return json.loads((tmp_path / "s" / "truth.json").read_text())


def _localized_within_10_m(tmp_path, name, extra, truth):
    """`fusion localize` on the recording in ``tmp_path/s`` with options `extra`: fixes within
    10 m of a whale, false fixes (observable, not mirror-ambiguous) and windows."""
    from fusion.cli import main
    from fusion.metrics.localization import match_fixes, true_positions

    out = tmp_path / f"{name}.json"
    assert main(["localize", "--audio", str(tmp_path / "s" / "audio.flac"), "--array",
                 str(tmp_path / "s" / "array.json"), "--out", str(out), "--quiet", *extra]) == 0
    doc = json.loads(out.read_text())
    n = false = 0
    for w in doc["windows"]:
        fixes = [[s["x"], s["y"], s["z"]] for s in w["sources"]
                 if s["observable"] and not s["mirror_ambiguous"]]
        m = match_fixes(true_positions(truth, 0.5 * (w["t_start"] + w["t_end"])), fixes)
        n, false = n + m.found, false + m.false
    return n, false, len(doc["windows"])


def test_even_odds_validation_keeps_the_pairs_a_fix_needs(tmp_path):
    """`fusion localize` validates near even odds (LLR 0.5, section 13) with the shipped validator: on a range
    where two hydrophones hear the whale 2 km away (tuning seed 2), the model's own threshold
    drops their short click trains and the first windows keep too few pairs for a fix; at even
    odds every window is localized within 10 m and no fix is false. The model's own threshold
    is that of ``validator_v1.npz`` (3.24), the model section 8 of docs/localization.md was
    decided with; the shipped ``validator_v2.npz`` at its own threshold (4.21) keeps the pairs
    on this seed too (10 of 10). Measured at the fixed detection threshold the section was
    decided with (``--detect-threshold 6``): at the default of section 18 the far sensors'
    trains are longer and v1 at its own threshold localizes all 10 windows too."""
    from fusion.clicks.validate import V1_MODEL_PATH, TdoaValidator
    from fusion.pipelines.clicks import LLR_THRESHOLD

    v1 = TdoaValidator.load(V1_MODEL_PATH)
    assert LLR_THRESHOLD == 0.5 and v1.threshold > 3.0
    truth = _simulated(tmp_path, 2)
    found = {}
    # the model's threshold alone: closure support (section 15) admits the far pairs' partial
    # trains that this threshold drops where the others span three sensors
    # and train integration (section 19) sums the far sensors' statistic along the near ones'
    # trains: both off for the model arm (with it, all 10 windows are localized there too)
    for name, extra in (("even", []), ("model", ["--validator", str(V1_MODEL_PATH),
                                                 "--no-closure-support",
                                                 "--no-train-integration"])):
        extra = ["--detect-threshold", "6", *extra]
        found[name] = _localized_within_10_m(tmp_path, name, extra, truth)
    assert found["even"] == (10, 0, 10)
    assert found["model"][0] <= 8


def test_llr_bar_above_even_odds_drops_surface_echo_trains(tmp_path):
    """With ``validator_v2.npz`` the surface-echo trains of tuning seed 4 (one whale, floor and
    surface echoes, no variation) score LLR 0.03-0.4: at even odds (``--llr-threshold 0``) they
    pass and make false fixes; at the default bar (0.5, docs/localization.md section 13) every
    window is localized within 10 m and no fix is false. Measured, as the bar was chosen, at the
    fixed detection threshold (``--detect-threshold 6``)."""
    from fusion.pipelines.clicks import LLR_THRESHOLD

    assert LLR_THRESHOLD == 0.5
    truth = _simulated(tmp_path, 4, "--snr-db", "30")
    found = {}
    for name, extra in (("default", []), ("even", ["--llr-threshold", "0"])):
        extra = ["--detect-threshold", "6", *extra]
        found[name] = _localized_within_10_m(tmp_path, name, extra, truth)[:2]
    assert found["default"] == (10, 0)
    assert found["even"][1] >= 1


def test_localize_sets_the_detection_threshold_from_a_noise_false_alarm_rate(tmp_path):
    """`fusion localize` sets the detection threshold where the detector passes 0.5 noise
    detections a channel-second (docs/localization.md section 18), about 4.9 on the estimated
    26-kHz band, below the fixed 6.0, and writes it to the settings file;
    ``--detect-threshold 6`` (the ablation) keeps the fixed one. On tuning seed 1 at 24 dB (one
    whale, floor and surface echoes) the lower threshold makes no false fix. The gain in
    windows localized is measured on seeds 0-9 in benchmarks/RESULTS.md ("Issue 17: low
    SNR"), not here: on seed 1 neither threshold localizes a window."""
    from fusion.commands.localize import DETECT_FALSE_ALARMS_PER_S

    assert DETECT_FALSE_ALARMS_PER_S == 0.5
    truth = _simulated(tmp_path, 1, "--snr-db", "24")
    found = {}
    for name, extra in (("default", []), ("fixed", ["--detect-threshold", "6"])):
        found[name] = _localized_within_10_m(tmp_path, name, extra, truth)
    side = json.loads((tmp_path / "default.settings.json").read_text())
    assert side["detection"]["false_alarms_per_s"] == 0.5
    assert 4.5 < side["detection"]["threshold"] < 5.3
    fixed = json.loads((tmp_path / "fixed.settings.json").read_text())["detection"]
    assert fixed == {"threshold": 6.0, "false_alarms_per_s": None}
    assert found["default"][1] == 0
