"""The bottom-mounted-range physics of the click simulator (fusion.simulate.clicks range options,
``fusion simulate clicks --vary``): propagation through a sound-speed profile, floor echoes,
survey errors, echo choices, per-whale clicks, interferers and the command-line options."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.io import read_array, read_audio, read_json
from fusion.simulate.clicks import ClickWaveform, simulate_clicks
from fusion.simulate.whale_range.propagation import (
    FloorPlane,
    SoundSpeedProfile,
    segment_time,
)
from fusion.simulate.whale_range.varied import VARIED_RANGES, varied_settings

RNG = np.random.default_rng(12345)


def _points(n: int, depth=(5.0, 2500.0)) -> np.ndarray:
    xy = RNG.uniform(-6000.0, 6000.0, (n, 2))
    return np.column_stack([xy, -RNG.uniform(*depth, n)])


# --------------------------------------------------------------------------------------------
# straight-ray travel times through a profile
# --------------------------------------------------------------------------------------------
def test_constant_profile_time_is_distance_over_speed():
    """c = 1512 m/s everywhere: every segment (steep, shallow, horizontal) takes L / c."""
    prof = SoundSpeedProfile("constant", {"c0": 1512.0}, max_depth_m=3000.0)
    a, b = _points(400), _points(400)
    b[:50, 2] = a[:50, 2]  # horizontal
    b[50:100, 2] = a[50:100, 2] + RNG.uniform(-1.0, 1.0, 50)  # nearly horizontal
    dist = np.linalg.norm(a - b, axis=1)
    assert_allclose(segment_time(a, b, prof), dist / 1512.0, rtol=1e-12, atol=0)


def test_linear_profile_time_matches_closed_form():
    """c(d) = c0 + g d: T = L / |dd| * (1/g) ln(c(d2) / c(d1)), and L / c(d) when level."""
    c0, g = 1480.0, 0.0175
    prof = SoundSpeedProfile("linear", {"c0": c0, "gradient": g}, max_depth_m=3000.0)
    a, b = _points(500), _points(500)
    b[:40, 2] = a[:40, 2]
    b[40:80, 2] = a[40:80, 2] + RNG.uniform(-1.9, 1.9, 40)  # the quadrature branch
    b[80:120, 2] = a[80:120, 2] + RNG.uniform(-20.0, 20.0, 40)
    length = np.linalg.norm(a - b, axis=1)
    d1, d2 = -a[:, 2], -b[:, 2]
    dd = d2 - d1
    with np.errstate(divide="ignore", invalid="ignore"):
        # ln(c(d2) / c(d1)) as log1p: no cancellation for nearly level segments
        closed = length / dd / g * np.log1p(g * dd / (c0 + g * d1))
    closed = np.where(dd == 0, length / (c0 + g * d1), closed)
    got = segment_time(a, b, prof)
    assert_allclose(got, closed, rtol=1e-11, atol=1e-12)
    # and the profile is not the constant one: times differ from L / c0 by up to ~ g d / c0
    assert np.max(np.abs(got * c0 / length - 1.0)) > 0.01


def test_profile_rejects_unrealistic_speeds_and_bad_kinds():
    with pytest.raises(ValueError, match="profile kind"):
        SoundSpeedProfile("cubic", {"c0": 1500.0})
    with pytest.raises(ValueError, match="needs parameters"):
        SoundSpeedProfile("linear", {"c0": 1500.0})
    with pytest.raises(ValueError, match="leaves 1300-1800"):
        SoundSpeedProfile("linear", {"c0": 1500.0, "gradient": 1.0}, max_depth_m=2000.0)


@pytest.mark.parametrize("seed", [1, 3, 8])
def test_effective_speeds_of_varied_profiles_differ_from_nominal_by_at_most_about_1_percent(seed):
    """Per-path effective speeds (length / time) of a varied world scatter around the nominal
    speed of array.json by up to ~1 %, never exactly equal to it, never all the same."""
    settings = varied_settings(seed) | {"duration_s": 4.0, "snr_db": np.inf, "n_transients": 0}
    sc = simulate_clicks(**settings)
    nominal = sc.sensors.sound_speed
    assert nominal == sc.world.nominal_sound_speed
    assert nominal == round(sc.world.profile.mean_speed(sc.world.floor.depth_m), 1)
    speeds = np.concatenate([v.ravel() for s in sc.sources for v in s.effective_speeds.values()])
    dev = speeds / nominal - 1.0
    assert np.max(np.abs(dev)) <= 0.0125
    assert np.max(np.abs(dev)) > 5e-4
    assert np.ptp(speeds) > 0.5  # m/s: not one speed
    direct = np.concatenate([s.effective_speeds["direct"].ravel() for s in sc.sources])
    assert not np.allclose(direct, nominal, rtol=1e-4)


def test_varied_profiles_stay_realistic():
    """Across many seeds the drawn profiles keep 1470-1560 m/s over the water column."""
    for seed in range(40):
        s = varied_settings(seed)
        spec = dict(s["sound_speed_profile"])
        prof = SoundSpeedProfile(spec.pop("kind"), spec, max_depth_m=2500.0)
        c = prof.speed(np.linspace(0.0, s["floor_depth_m"], 200))
        assert 1470.0 < c.min() and c.max() < 1560.0, (seed, c.min(), c.max())


# --------------------------------------------------------------------------------------------
# floor geometry and the bottom echo
# --------------------------------------------------------------------------------------------
def _mirror_brute_force(floor: FloorPlane, p: np.ndarray) -> np.ndarray:
    """Mirror points across the floor found from three points on it (independent of
    FloorPlane.normal/mirror): foot of the perpendicular by least squares, then reflect."""
    xy = np.array([[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]])
    q = np.column_stack([xy, -floor.depth_at(xy[:, 0], xy[:, 1])])
    u, v = q[1] - q[0], q[2] - q[0]
    basis = np.column_stack([u, v])
    coef, *_ = np.linalg.lstsq(basis, (p - q[0]).T, rcond=None)
    foot = q[0] + (basis @ coef).T
    return 2.0 * foot - p


@pytest.fixture(scope="module")
def bottom_world():
    """Constant speed, sloping floor, bottom echo only, 8 sensors, random echo signs."""
    return simulate_clicks(
        seed=11, n_sensors=8, n_sources=2, duration_s=6.0, snr_db=np.inf, n_transients=0,
        echo="bottom", floor_depth_m=1400.0, floor_slope_deg=4.0, floor_azimuth_deg=30.0,
        sensor_spacing_m=2500.0, bottom_reflection_sign="random",
    )


def test_sensors_stand_1_to_20_m_above_the_sloping_floor(bottom_world):
    w = bottom_world.world
    heights = w.sensor_heights_m()
    assert np.all((heights >= 1.0) & (heights <= 20.0))
    depth_below = w.floor.depth_at(w.sensors_true[:, 0], w.sensors_true[:, 1])
    # vertical distance above the floor = height / cos(slope)
    assert_allclose(depth_below + w.sensors_true[:, 2], heights / np.cos(np.radians(4.0)),
                    rtol=1e-9)
    d = np.linalg.norm(w.sensors_true[:, None, :2] - w.sensors_true[None, :, :2], axis=2)
    np.fill_diagonal(d, np.inf)
    assert np.median(d.min(axis=1)) == pytest.approx(2500.0, rel=0.01)  # drawn spacing


def test_bottom_echo_delay_is_the_image_geometry_delay(bottom_world):
    """Delays equal (|p' - s| - |p - s|) / c with p' mirrored independently across the floor,
    lie in (0, 2 h / c] and mostly in 0.2-10 ms."""
    sc, w = bottom_world, bottom_world.world
    for src in sc.sources:
        image = _mirror_brute_force(w.floor, src.positions)
        r_img = np.linalg.norm(image[:, None, :] - w.sensors_true[None], axis=2)
        r_dir = np.linalg.norm(src.positions[:, None, :] - w.sensors_true[None], axis=2)
        delay = src.bottom_echo_arrival_times - src.arrival_times
        assert_allclose(delay, (r_img - r_dir) / 1500.0, rtol=0, atol=1e-9)
        assert np.all(delay > 0)
        assert np.all(delay <= 2.0 * w.sensor_heights_m()[None, :] / 1500.0 + 1e-12)
        assert 0.2e-3 < np.median(delay) < 10e-3


def test_bottom_echo_amplitude_and_sign_as_drawn(bottom_world):
    """Echo / direct amplitude = coefficient x spreading-and-absorption ratio; coefficients
    -15 to -3 dB with both signs (sign random)."""
    sc, w = bottom_world, bottom_world.world
    coef = w.bottom_coefficients
    db = 20 * np.log10(np.abs(coef))
    assert np.all((db >= -15.0) & (db <= -3.0))
    assert np.any(coef > 0) and np.any(coef < 0)
    def loss(r):  # spherical spreading and 8 dB/km, unit at 1 km
        return (1000.0 / r) * 10.0 ** (-8.0 * (r - 1000.0) / 20_000.0)

    for src in sc.sources:
        r_dir = np.linalg.norm(src.positions[:, None, :] - w.sensors_true[None], axis=2)
        r_img = np.linalg.norm(_mirror_brute_force(w.floor, src.positions)[:, None, :]
                               - w.sensors_true[None], axis=2)
        ratio = src.bottom_echo_amplitudes / src.arrival_amplitudes
        assert_allclose(ratio, coef[None, :] * loss(r_img) / loss(r_dir), rtol=1e-9)
        assert np.all(np.abs(ratio) <= np.abs(coef)[None, :])
        assert np.all(np.sign(src.bottom_echo_amplitudes) == np.sign(coef)[None, :])
        assert np.all(src.echo_amplitudes == 0.0)  # no surface echo rendered
    truth_coef = np.asarray(w.to_dict()["bottom_reflection_coefficients"])
    assert_allclose(truth_coef, coef)


def test_surface_coefficients_drawn_per_sensor_and_inverted():
    sc = simulate_clicks(seed=2, n_sensors=6, n_sources=1, duration_s=2.0, snr_db=np.inf,
                         n_transients=0, echo="surface", surface_reflection_range=(0.5, 0.95))
    c = sc.world.surface_coefficients
    assert np.all((c <= -0.5) & (c >= -0.95)) and np.ptp(c) > 0
    ratio = sc.sources[0].echo_amplitudes / sc.sources[0].arrival_amplitudes
    assert np.all(ratio < 0)
    assert np.all(sc.sources[0].bottom_echo_amplitudes == 0.0)


# --------------------------------------------------------------------------------------------
# echo choices in the audio
# --------------------------------------------------------------------------------------------
def _window_energy(audio: np.ndarray, fs: float, ch: int, t: float, half_s: float) -> float:
    a, b = int(np.floor((t - half_s) * fs)), int(np.ceil((t + half_s) * fs)) + 1
    return float(np.sum(audio[a:b, ch].astype(float) ** 2))


@pytest.fixture(scope="module")
def echo_worlds():
    kw = dict(seed=9, n_sensors=4, n_sources=1, duration_s=5.0, snr_db=np.inf, n_transients=0,
              floor_depth_m=1500.0, sensor_spacing_m=1500.0, height_above_floor_m=(12.0, 20.0))
    return {e: simulate_clicks(echo=e, **kw) for e in ("none", "surface", "bottom", "both")}


def test_echo_choice_changes_only_the_echoes(echo_worlds):
    base = echo_worlds["none"]
    for sc in echo_worlds.values():
        assert_allclose(sc.sensors.positions, base.sensors.positions, rtol=0, atol=0)
        assert_allclose(sc.sources[0].arrival_times, base.sources[0].arrival_times, rtol=0, atol=0)
        assert_allclose(sc.sources[0].bottom_echo_arrival_times,
                        base.sources[0].bottom_echo_arrival_times, rtol=0, atol=0)
    assert [sc.world.echo for sc in echo_worlds.values()] == ["none", "surface", "bottom", "both"]


def _isolated_arrivals(sc, path: str, half_s: float):
    """(click, sensor, time) of `path` arrivals with no other arrival within 4 half-widths."""
    src = sc.sources[0]
    times = {"direct": src.arrival_times, "surface": src.echo_arrival_times,
             "bottom": src.bottom_echo_arrival_times}
    every = np.concatenate([t for t in times.values()], axis=0)
    out = []
    for k in range(src.n_clicks):
        for ch in range(sc.n_sensors):
            t = times[path][k, ch]
            if not 0.01 < t < sc.duration_s - 0.01:
                continue
            if np.sum(np.abs(every[:, ch] - t) < 4 * half_s) == 1:
                out.append((k, ch, t))
    return out


@pytest.mark.parametrize("echo,surface,bottom", [("none", False, False), ("surface", True, False),
                                                 ("bottom", False, True), ("both", True, True)])
def test_echo_energy_in_the_audio(echo_worlds, echo, surface, bottom):
    """Energy around each isolated echo arrival relative to the direct arrival of the same click
    is (echo amplitude / direct amplitude)^2 when that echo is rendered, 0 when it is not."""
    sc = echo_worlds[echo]
    src, half = sc.sources[0], 0.5 * sc.click.duration_s + 20e-6
    checked = 0
    for path, on, amps in (("surface", surface, echo_worlds["both"].sources[0].echo_amplitudes),
                           ("bottom", bottom,
                            echo_worlds["both"].sources[0].bottom_echo_amplitudes)):
        for k, ch, t in _isolated_arrivals(sc, path, half):
            t_dir = src.arrival_times[k, ch]
            if not 0.01 < t_dir < sc.duration_s - 0.01:
                continue
            if np.sum(np.abs(src.arrival_times[:, ch] - t_dir) < 4 * half) != 1 or \
                    abs(t - t_dir) < 4 * half:
                continue
            e_dir = _window_energy(sc.audio, sc.fs, ch, t_dir, half)
            e_echo = _window_energy(sc.audio, sc.fs, ch, t, half)
            expected = (amps[k, ch] / src.arrival_amplitudes[k, ch]) ** 2
            if on:
                assert e_echo / e_dir == pytest.approx(expected, rel=0.05)
            else:
                assert e_echo <= 1e-12 * e_dir
            checked += 1
    assert checked >= 10


# --------------------------------------------------------------------------------------------
# survey errors, truth TDOAs
# --------------------------------------------------------------------------------------------
def test_surveyed_positions_carry_errors_truth_uses_true_geometry():
    sc = simulate_clicks(seed=4, n_sensors=10, n_sources=1, duration_s=3.0, snr_db=np.inf,
                         n_transients=0, echo="both", position_error_m=2.0)
    err = sc.sensors.positions - sc.world.sensors_true
    assert 1.2 < np.sqrt(np.mean(err**2)) < 3.0  # sigma 2 m per axis, 30 draws
    assert np.max(np.abs(err)) < 10.0
    src = sc.sources[0]
    true_t = src.emission_times[:, None] + np.linalg.norm(
        src.positions[:, None, :] - sc.world.sensors_true[None], axis=2) / 1500.0
    assert_allclose(src.arrival_times, true_t, rtol=0, atol=1e-9)
    surveyed_t = src.emission_times[:, None] + np.linalg.norm(
        src.positions[:, None, :] - sc.sensors.positions[None], axis=2) / 1500.0
    assert np.max(np.abs(src.arrival_times - surveyed_t)) > 5e-4  # metres of error show


# --------------------------------------------------------------------------------------------
# whales and interferers
# --------------------------------------------------------------------------------------------
def test_per_whale_clicks_levels_icis_and_close_pairs():
    sc = simulate_clicks(
        seed=6, n_sensors=5, n_sources=5, duration_s=6.0, snr_db=np.inf, n_transients=0,
        echo="both", click_band_hz=(20e3, 45e3), click_duration_s=(150e-6, 400e-6),
        source_level_spread_db=6.0, ici_range_s=(0.2, 1.0), close_pair_probability=1.0,
    )
    clicks = [s.click for s in sc.sources]
    assert len({(c.f_start_hz, c.f_end_hz, c.duration_s) for c in clicks}) == 5
    for c in clicks:
        assert 20e3 <= c.f_start_hz and c.f_start_hz + 5e3 <= c.f_end_hz <= 45e3
        assert 150e-6 <= c.duration_s <= 400e-6
    levels = np.array([s.source_level_db for s in sc.sources])
    assert np.all(np.abs(levels) <= 6.0) and np.ptp(levels) > 0
    icis = np.array([s.ici_mean_s for s in sc.sources])
    assert np.all((icis >= 0.2) & (icis <= 1.0))
    for k in range(1, 5):  # probability 1: each later whale starts 20-100 m from an earlier one
        d = np.linalg.norm(sc.sources[k].start_position
                           - np.array([s.start_position for s in sc.sources[:k]]), axis=1)
        assert 20.0 - 1e-9 <= d.min() <= 100.0 + 1e-9
    floor = sc.world.floor
    for s in sc.sources:  # every whale stays in the water
        assert np.all(floor.height_above(s.positions) > 10.0) and np.all(s.positions[:, 2] < 0)


def test_explicit_whale_clicks_are_used():
    clicks = [ClickWaveform(22e3, 40e3, 300e-6), ClickWaveform(30e3, 44e3, 180e-6)]
    sc = simulate_clicks(seed=1, n_sensors=3, n_sources=2, duration_s=1.0, snr_db=np.inf,
                         whale_clicks=clicks)
    assert [s.click for s in sc.sources] == clicks


def test_interferers_recorded_apart_and_rendered():
    sc = simulate_clicks(seed=5, n_sensors=4, n_sources=1, duration_s=4.0, snr_db=np.inf,
                         n_transients=0, echo="none", n_interferers=2)
    ints = sc.world.interferers
    assert len(ints) == 2 and len(sc.sources) == 1
    for t in ints:
        assert 20e-6 <= t.duration_s <= 80e-6 and 0.05 <= t.ici_mean_s <= 1.0
        r = np.linalg.norm(t.position[None, :] - sc.world.sensors_true, axis=1)
        assert_allclose(t.arrival_times - t.emission_times[:, None],
                        np.broadcast_to(r / 1500.0, t.arrival_times.shape), rtol=0, atol=1e-9)
        assert -t.position[2] < sc.world.floor.depth_at(*t.position[:2])
        inside = [(k, ch) for k in range(t.arrival_times.shape[0]) for ch in range(4)
                  if 0.01 < t.arrival_times[k, ch] < 3.99]
        assert inside
        k, ch = inside[0]
        assert _window_energy(sc.audio, sc.fs, ch, t.arrival_times[k, ch], t.duration_s) > 0


def test_bad_range_options_raise():
    base = dict(seed=0, duration_s=0.5, snr_db=np.inf)
    for options, match in [
        ({"echo": "sideways"}, "echo"),
        ({"floor_slope_deg": -1.0}, "floor_slope_deg"),
        ({"n_interferers": 6}, "n_interferers"),
        ({"click_band_hz": (20e3, 60e3), "click_duration_s": (1e-4, 2e-4)}, "click_band_hz"),
        ({"click_band_hz": (20e3, 40e3)}, "go together"),
        ({"sound_speed": 1490.0, "sound_speed_profile": {"kind": "constant", "c0": 1500.0}},
         "not both"),
        ({"whale_clicks": [ClickWaveform()]}, "whale_clicks"),
        ({"height_above_floor_m": (5.0, 1.0)}, "height_above_floor_m"),
        ({"position_error_m": float("nan")}, "position_error_m"),
        ({"n_sources": 6}, "n_sources"),
        ({"n_sensors": 11}, "n_sensors"),
    ]:
        with pytest.raises(ValueError, match=match):
            simulate_clicks(**(base | options))


# --------------------------------------------------------------------------------------------
# varied settings
# --------------------------------------------------------------------------------------------
def test_varied_settings_within_declared_ranges_and_seeded():
    r = VARIED_RANGES
    for seed in range(30):
        s = varied_settings(seed)
        assert s == varied_settings(seed)
        assert r["n_sources"][0] <= s["n_sources"] <= r["n_sources"][1]
        assert r["n_sensors"][0] <= s["n_sensors"] <= r["n_sensors"][1]
        for name in ("duration_s", "snr_db", "floor_depth_m", "floor_slope_deg",
                     "sensor_spacing_m", "position_error_m"):
            assert r[name][0] <= s[name] <= r[name][1], name
        assert 0 <= s["n_interferers"] <= 2 and s["echo"] == "both"
        json.dumps(s)
    assert varied_settings(1) != varied_settings(2)


def test_varied_recording_is_fast():
    """60 s, 5 sensors, 3 whales of varied physics at 96 kHz: well under 30 s."""
    s = varied_settings(3) | {"duration_s": 60.0, "n_sensors": 5, "n_sources": 3}
    t0 = time.perf_counter()
    sc = simulate_clicks(**s)
    assert time.perf_counter() - t0 < 30.0
    assert sc.audio.shape == (60 * 96_000, 5) and len(sc.sources) == 3


# --------------------------------------------------------------------------------------------
# command line
# --------------------------------------------------------------------------------------------
def test_cli_clicks_options(run_cli, tmp_path):
    out = tmp_path / "a"
    code, _, err = run_cli("simulate", "clicks", "--seed", "2", "--out", out, "--duration-s", "3",
                           "--whales", "1", "--sensors", "4", "--snr-db", "20", "--echo", "surface")
    assert code == 0, err
    truth, array = read_json(out / "truth.json"), read_array(out / "array.json")
    assert truth["duration_s"] == 3.0 and truth["snr_db"] == 20.0 and truth["echo"] == "surface"
    assert len(truth["sources"]) == 1 and array.n_sensors == 4
    samples, fs = read_audio(out / "audio.flac", n_channels=4)
    assert samples.shape == (3 * 96_000, 4)
    assert np.all(np.asarray(truth["sources"][0]["bottom_echo_amplitudes"]) == 0.0)
    code, _, err = run_cli("simulate", "clicks", "--seed", "2", "--out", tmp_path / "b",
                           "--duration", "2")  # hidden alias
    assert code == 0, err
    assert read_json(tmp_path / "b" / "truth.json")["duration_s"] == 2.0


@pytest.mark.parametrize("option", [["--whales", "2"], ["--sensors", "4"], ["--snr-db", "10"],
                                    ["--echo", "none"], ["--duration-s", "5"],
                                    ["--duration", "5"]])
def test_cli_clicks_options_refused_for_other_kinds(run_cli, tmp_path, option):
    code, out, err = run_cli("simulate", "bearings", "--seed", "1", "--out", tmp_path / "x",
                             *option)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "applies to `fusion simulate clicks` only" in lines[0]
    assert not (tmp_path / "x").exists() and out == ""


def test_cli_vary_is_seeded_and_explicit_options_win(run_cli, tmp_path):
    runs = {}
    for name, seed in (("a", "7"), ("b", "7"), ("c", "8")):
        code, _, err = run_cli("simulate", "clicks", "--vary", "--seed", seed, "--out",
                               tmp_path / name, "--duration-s", "4")
        assert code == 0, err
        runs[name] = {p.name: p.read_bytes() for p in (tmp_path / name).iterdir()}
    assert runs["a"] == runs["b"]
    assert runs["a"]["truth.json"] != runs["c"]["truth.json"]
    truth = json.loads(runs["a"]["truth.json"])
    params = truth["parameters"]
    assert params["duration_s"] == 4.0 and truth["duration_s"] == 4.0
    assert params == varied_settings(7) | {"duration_s": 4.0}
    assert truth["sound_speed_profile"]["kind"] in ("munk", "thermocline")
    # array.json: surveyed positions, a few metres off the true ones; nominal speed
    array = json.loads(runs["a"]["array.json"])
    surveyed = np.array([[s["x"], s["y"], s["z"]] for s in array["sensors"]])
    err = surveyed - np.asarray(truth["sensors_true"])
    assert 0.2 * params["position_error_m"] < np.sqrt(np.mean(err**2)) < \
        2.5 * params["position_error_m"]
    assert array["sound_speed"] == truth["nominal_sound_speed"]
    for src in truth["sources"]:  # truth TDOAs: true arrival-time differences
        arr = np.asarray(src["arrival_times"])
        tau = np.asarray(src["tdoas"])
        assert_allclose(tau, np.stack([arr[:, i] - arr[:, j] for i, j in truth["pairs"]], 1))
    code, _, err = run_cli("simulate", "clicks", "--vary", "--seed", "7", "--out",
                           tmp_path / "d", "--whales", "2", "--sensors", "4", "--echo", "none",
                           "--duration-s", "3", "--snr-db", "25")
    assert code == 0, err
    t = read_json(tmp_path / "d" / "truth.json")
    assert len(t["sources"]) == 2 and len(t["sensors_true"]) == 4 and t["echo"] == "none"
    assert t["snr_db"] == 25.0 and t["duration_s"] == 3.0
    for src in t["sources"]:
        assert not np.any(src["echo_amplitudes"]) and not np.any(src["bottom_echo_amplitudes"])
        assert np.any(src["bottom_echo_arrival_times"])  # echo times still recorded


def test_cli_most_whales_and_sensors(run_cli, tmp_path):
    """--whales 5 --sensors 10 works (10 channels: audio.wav, FLAC holds 8); 6 whales or 11
    sensors are one-line errors."""
    code, out, err = run_cli("simulate", "clicks", "--seed", "1", "--out", tmp_path / "ok",
                             "--whales", "5", "--sensors", "10", "--duration-s", "3")
    assert code == 0, err
    assert any(line.endswith("audio.wav") for line in out.splitlines())
    samples, _ = read_audio(tmp_path / "ok" / "audio.wav", n_channels=10)
    assert samples.shape == (3 * 96_000, 10)
    assert len(read_json(tmp_path / "ok" / "truth.json")["sources"]) == 5
    for option in (["--whales", "6"], ["--sensors", "11"]):
        code, out, err = run_cli("simulate", "clicks", "--seed", "1", "--out", tmp_path / "bad",
                                 *option)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert not (tmp_path / "bad").exists()


def test_vary_only_draws_one_group_as_the_full_draw_does():
    from fusion.commands.simulate import VARY_GROUPS
    from fusion.simulate.whale_range.varied import VARIED_GROUPS

    assert tuple(VARIED_GROUPS) == VARY_GROUPS  # the command's light copy of the names
    every = varied_settings(11)
    grouped = [k for g in VARIED_GROUPS.values() for k in g]
    assert sorted(grouped) == sorted(set(every) - {"seed"})  # each setting in one group
    only = varied_settings(11, only=("sound-speed", "survey"))
    assert set(only) == {"seed", "sound_speed_profile", "position_error_m"}
    assert only["sound_speed_profile"] == every["sound_speed_profile"]
    assert only["position_error_m"] == every["position_error_m"]
    with pytest.raises(ValueError, match="unknown varied group"):
        varied_settings(11, only=("sound",))


def test_vary_only_sound_speed_changes_the_speed_and_nothing_else(tmp_path):
    from fusion.simulate.clicks import write_scenario

    write_scenario(tmp_path / "a", seed=5, n_sources=1, duration_s=3.0, echo="both")
    write_scenario(tmp_path / "b", seed=5, n_sources=1, duration_s=3.0, echo="both",
                   vary_only=("sound-speed",))
    ta, tb = (read_json(tmp_path / x / "truth.json") for x in "ab")
    assert ta["sound_speed_profile"] is None and tb["sound_speed_profile"] is not None
    assert tb["parameters"]["sound_speed_profile"] == varied_settings(5)["sound_speed_profile"]
    assert_allclose(ta["sensors_true"], tb["sensors_true"])
    assert ta["sources"][0]["click"] == tb["sources"][0]["click"]
    speeds = np.array(tb["sources"][0]["effective_speeds"]["direct"])
    assert 0.001 < np.max(np.abs(speeds / tb["nominal_sound_speed"] - 1)) < 0.012
    with pytest.raises(ValueError, match="--vary-only"):
        write_scenario(tmp_path / "c", seed=5, vary=True, vary_only=("survey",))
