"""Physical checks of the click-scenario simulator (fusion.simulate.clicks)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.fft
from numpy.testing import assert_allclose
from scipy.signal import correlate, correlation_lags, hilbert, resample

from fusion.cli import main
from fusion.geometry import propagation_delay, tdoa
from fusion.io import read_array, read_audio, read_json, read_table
from fusion.simulate.clicks import (
    ClickScenario,
    ClickWaveform,
    draw_emission_times,
    simulate_clicks,
    write_click_scenario,
)


@pytest.fixture(scope="module")
def clean() -> ClickScenario:
    """Noise-free, one source, four sensors, no transients."""
    return simulate_clicks(
        seed=3, n_sensors=4, n_sources=1, duration_s=4.0, snr_db=np.inf, n_transients=0
    )


@pytest.fixture(scope="module")
def loud() -> ClickScenario:
    """Two sources on five sensors at high SNR (noise present)."""
    return simulate_clicks(seed=5, n_sensors=5, n_sources=2, duration_s=6.0, snr_db=40.0,
                           n_transients=0)


def _all_arrivals(sc: ClickScenario, ch: int) -> np.ndarray:
    """Every click arrival (direct and echo, all sources) and transient on a channel."""
    ts = [s.arrival_times[:, ch] for s in sc.sources]
    ts += [s.echo_arrival_times[:, ch] for s in sc.sources]
    ts.append(sc.transient_times[sc.transient_channels == ch])
    return np.concatenate(ts)


def _isolated(sc: ClickScenario, ch: int, t: float, gap_s: float) -> bool:
    """True if `t` is the only arrival on channel `ch` within `gap_s`."""
    return int(np.sum(np.abs(_all_arrivals(sc, ch) - t) < gap_s)) == 1


def _inside(sc: ClickScenario, t: float, margin_s: float) -> bool:
    return margin_s < t < sc.duration_s - margin_s


# --------------------------------------------------------------------------------------------
# geometry and timing
# --------------------------------------------------------------------------------------------
def test_arrival_differences_equal_geometric_tdoa(loud):
    """Simulated arrival-time differences equal fusion.geometry.tdoa at each emission position."""
    pos_s, c, pairs = loud.sensors.positions, loud.sensors.sound_speed, loud.pairs()
    for s in loud.sources:
        measured = s.arrival_times[:, [i for i, _ in pairs]] - s.arrival_times[:, [j for _, j in pairs]]
        assert_allclose(measured, tdoa(s.positions, pos_s, pairs, c), rtol=0, atol=1e-12)
        assert_allclose(s.tdoas(pairs), measured, rtol=0, atol=0)
        assert_allclose(
            s.arrival_times - s.emission_times[:, None], propagation_delay(s.positions, pos_s, c),
            rtol=0, atol=1e-12,
        )


def test_tdoa_antisymmetric(loud):
    """TDOA(i, j) = -TDOA(j, i) for every click."""
    s = loud.sources[0]
    assert_allclose(s.tdoas([(0, 3)]), -s.tdoas([(3, 0)]), rtol=0, atol=0)


def test_layout_is_bottom_mounted_and_kilometres_apart():
    """Hydrophones 1500-1700 m deep, at least ~1 km apart, sources 500-1200 m deep, 1-2 m/s."""
    for n_sensors, seed in itertools.product((3, 5, 8), (0, 1, 2)):
        sc = simulate_clicks(seed=seed, n_sensors=n_sensors, n_sources=3, duration_s=0.5,
                             snr_db=np.inf, n_transients=0)
        z = sc.sensors.positions[:, 2]
        assert np.all((z <= -1500.0) & (z >= -1700.0))
        d = [np.linalg.norm(p - q) for p, q in itertools.combinations(sc.sensors.positions, 2)]
        assert min(d) > 800.0
        for s in sc.sources:
            assert 500.0 <= -s.start_position[2] <= 1200.0
            assert 1.0 <= s.speed_mps <= 2.0


def test_motion_model_speed_and_positions(clean):
    """Positions at emissions follow position_at, and the horizontal speed is the drawn speed."""
    s = clean.sources[0]
    assert_allclose(s.position_at(s.emission_times), s.positions, rtol=0, atol=1e-9)
    t = np.linspace(0.0, 10.0, 1001)
    p = s.position_at(t)
    v = np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1) / np.diff(t)
    assert_allclose(v, s.speed_mps, rtol=1e-6)
    assert_allclose(np.diff(p[:, 2]) / np.diff(t), s.vertical_rate_mps, rtol=1e-6, atol=1e-12)


def test_emission_intervals_mean_and_jitter():
    """Gamma intervals have the requested mean and standard deviation."""
    rng = np.random.default_rng(11)
    t = draw_emission_times(ici_mean_s=0.37, ici_jitter_s=0.05, t_start_s=0.0, t_end_s=4000.0,
                            rng=rng)
    ici = np.diff(t)
    n = ici.size
    assert n > 10_000 and np.all(ici > 0) and t[-1] < 4000.0
    assert abs(ici.mean() - 0.37) < 4 * 0.05 / np.sqrt(n)
    assert abs(ici.std(ddof=1) / 0.05 - 1.0) < 0.05


def test_emission_intervals_in_scenario():
    """Each source's click train has the scenario's ICI mean and jitter; jitter 0 is periodic."""
    sc = simulate_clicks(seed=7, n_sensors=3, n_sources=3, duration_s=40.0, snr_db=np.inf,
                         n_transients=0, ici_s=0.40, ici_jitter_s=0.04)
    ici = np.concatenate([np.diff(s.emission_times) for s in sc.sources])
    assert ici.size > 300
    assert abs(ici.mean() - 0.40) < 4 * 0.04 / np.sqrt(ici.size)
    assert abs(ici.std(ddof=1) / 0.04 - 1.0) < 0.2
    t = draw_emission_times(ici_mean_s=0.37, ici_jitter_s=0.0, t_start_s=0.0, t_end_s=10.0,
                            rng=np.random.default_rng(0))
    assert_allclose(np.diff(t), 0.37, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# waveform and audio
# --------------------------------------------------------------------------------------------
def test_xcorr_peak_at_truth_tdoa_within_one_sample(loud):
    """The cross-correlation envelope of two channels around an isolated loud click peaks at
    the true TDOA within one sample."""
    fs = loud.fs
    half, search = int(0.002 * fs), int(0.004 * fs)
    checked = 0
    for s in loud.sources:
        for i, j in loud.pairs():
            for k in range(s.n_clicks):
                ti, tj = s.arrival_times[k, i], s.arrival_times[k, j]
                snr = np.abs(s.arrival_amplitudes[k, [i, j]]).min() / loud.noise_std_band
                if (snr < 30 or not (_inside(loud, ti, 0.05) and _inside(loud, tj, 0.05))
                        or not _isolated(loud, i, ti, 0.01) or not _isolated(loud, j, tj, 0.01)):
                    continue
                a = int(round(ti * fs)) - half
                b = int(round(tj * fs)) - half - search
                x = loud.audio[a:a + 2 * half, i].astype(float)
                y = loud.audio[b:b + 2 * (half + search), j].astype(float)
                # envelope of the cross-correlation: the carrier (2.7 samples per cycle at
                # 35 kHz) makes the raw peak ambiguous by one cycle, the envelope is not
                cc = np.abs(hilbert(correlate(y, x, mode="full")))
                lag = correlation_lags(y.size, x.size, mode="full")[np.argmax(cc)]
                # y's click sits `lag` samples after x's: t_j - t_i = (b + lag - a) / fs
                tau_measured = -(b + lag - a) / fs
                assert abs(tau_measured - (ti - tj)) <= 1.0 / fs
                checked += 1
                if checked >= 12:
                    return
    assert checked >= 3


def test_fractional_delay_is_sub_sample(clean):
    """Band-limited (x16) cross-correlation of a noise-free click pair recovers the TDOA to
    0.1 sample: clicks are placed at their exact, not rounded, arrival times."""
    fs, up = clean.fs, 16
    s = clean.sources[0]
    errs = []
    for k in range(s.n_clicks):
        ti, tj = s.arrival_times[k, 0], s.arrival_times[k, 2]
        if not (_inside(clean, ti, 0.01) and _inside(clean, tj, 0.01)):
            continue
        if not (_isolated(clean, 0, ti, 0.003) and _isolated(clean, 2, tj, 0.003)):
            continue
        a, b = int(np.floor(ti * fs)) - 64, int(np.floor(tj * fs)) - 64
        x = resample(clean.audio[a:a + 128, 0].astype(float), 128 * up)
        y = resample(clean.audio[b:b + 128, 2].astype(float), 128 * up)
        cc = correlate(y, x, mode="full")
        lag = correlation_lags(y.size, x.size, mode="full")[np.argmax(cc)]
        tau_measured = -((b - a) + lag / up) / fs
        errs.append((tau_measured - (ti - tj)) * fs)
    assert len(errs) >= 3
    assert np.max(np.abs(errs)) < 0.1
    # the true TDOAs are not whole samples, so rounding placement would have failed above
    frac = np.abs(np.mod(s.tdoas([(0, 2)])[:, 0] * fs + 0.5, 1.0) - 0.5)
    assert frac.max() > 0.2


def test_click_spectrum_concentrated_in_band(clean):
    """Click energy lies in 25-45 kHz; its power-weighted mean frequency (the method's eq. 2)
    is near the band centre."""
    fs = clean.fs
    n = 4096
    f = np.fft.rfftfreq(n, 1.0 / fs)
    band = (f >= 25e3) & (f <= 45e3)
    r = clean.click.replica(fs)
    p = np.abs(np.fft.rfft(r, n)) ** 2
    assert p[band].sum() / p.sum() > 0.97
    # a received click in the noise-free audio
    s = clean.sources[0]
    for k in range(s.n_clicks):
        t = s.arrival_times[k, 1]
        if _inside(clean, t, 0.01) and _isolated(clean, 1, t, 0.003):
            break
    a = int(round(t * fs)) - 96
    seg = clean.audio[a:a + 192, 1].astype(float)
    p = np.abs(np.fft.rfft(seg, n)) ** 2
    assert p[band].sum() / p.sum() > 0.97
    assert abs((p * f).sum() / p.sum() - 35e3) < 1e3
    # instantaneous frequency rises through the click (an upsweep)
    d = clean.click.duration_s
    tau = np.linspace(-d, d, 8001)
    z = hilbert(clean.click.evaluate(tau))
    inst_f = np.gradient(np.unwrap(np.angle(z)), tau) / (2 * np.pi)
    mid = np.abs(tau) < 0.3 * d
    assert_allclose(inst_f[mid], 35e3 + 20e3 / d * tau[mid], rtol=0, atol=500.0)


def test_click_peak_amplitude_and_spreading(clean):
    """Direct-path peak = source level x (r_ref / r) x absorption, and the audio carries it."""
    s = clean.sources[0]
    r = np.linalg.norm(s.positions[:, None, :] - clean.sensors.positions[None], axis=2)
    expected = s.source_amplitudes[:, None] * (1000.0 / r) * 10 ** (-8.0 * (r - 1000.0) / 20000)
    assert_allclose(s.arrival_amplitudes, expected, rtol=1e-12)
    fs = clean.fs
    checked = 0
    for k in range(s.n_clicks):
        t = s.arrival_times[k, 3]
        if _inside(clean, t, 0.01) and _isolated(clean, 3, t, 0.003):
            a = int(round(t * fs)) - 64
            env = np.abs(hilbert(clean.audio[a:a + 128, 3].astype(float)))
            assert_allclose(env.max(), s.arrival_amplitudes[k, 3], rtol=0.03)
            checked += 1
    assert checked >= 3


def test_surface_echo_image_source_delay_and_sign(clean):
    """The surface echo arrives later by the image-source path difference, inverted, with the
    amplitude of the image path times the reflection coefficient."""
    s, fs, c = clean.sources[0], clean.fs, clean.sensors.sound_speed
    pos_s = clean.sensors.positions
    image = s.positions * np.array([1.0, 1.0, -1.0])
    r_d = np.linalg.norm(s.positions[:, None] - pos_s[None], axis=2)
    r_s = np.linalg.norm(image[:, None] - pos_s[None], axis=2)
    assert_allclose(s.echo_arrival_times - s.arrival_times, (r_s - r_d) / c, rtol=0, atol=1e-12)
    assert np.all(s.echo_arrival_times > s.arrival_times + 0.1)
    ratio_expected = -0.9 * (r_d / r_s) * 10 ** (-8.0 * (r_s - r_d) / 20000)
    assert_allclose(s.echo_amplitudes / s.arrival_amplitudes, ratio_expected, rtol=1e-12)
    checked = 0
    for k, ch in itertools.product(range(s.n_clicks), range(clean.n_sensors)):
        td, te = s.arrival_times[k, ch], s.echo_arrival_times[k, ch]
        if not (_inside(clean, td, 0.01) and _inside(clean, te, 0.01)):
            continue
        if not (_isolated(clean, ch, td, 0.003) and _isolated(clean, ch, te, 0.003)):
            continue
        a = int(round(td * fs)) - 64
        x = clean.audio[a:a + 128, ch].astype(float)
        b = int(round(te * fs)) - 64 - 32
        y = clean.audio[b:b + 192, ch].astype(float)
        env = np.abs(hilbert(correlate(y, x, mode="full")))
        lag = correlation_lags(y.size, x.size, mode="full")[np.argmax(env)]
        assert abs((b + lag - a) / fs - (te - td)) <= 1.0 / fs
        # least-squares gain of the echo segment on the click template at the echo time:
        # the direct amplitude times the image-path ratio, negative (phase inverted)
        w = clean.click.evaluate(np.arange(b, b + 192) / fs - te)
        gain = np.dot(y, w) / np.dot(w, w)
        assert gain < 0
        assert_allclose(gain, s.arrival_amplitudes[k, ch] * ratio_expected[k, ch], rtol=0.01)
        checked += 1
    assert checked >= 3


def test_snr_definition_and_noise_band():
    """Noise (audio minus the same scenario without noise) has in-click-band std
    10^(-snr/20) and no power outside noise_band_hz."""
    kw = dict(seed=9, n_sensors=3, n_sources=1, duration_s=2.0, n_transients=2)
    noisy = simulate_clicks(snr_db=20.0, **kw)
    quiet = simulate_clicks(snr_db=np.inf, **kw)
    noise = noisy.audio.astype(float) - quiet.audio.astype(float)
    assert noisy.noise_std_band == pytest.approx(0.1)
    spec = np.fft.rfft(noise, axis=0)
    f = np.fft.rfftfreq(noise.shape[0], 1.0 / noisy.fs)
    for lo, hi, target in ((25e3, 45e3, 0.1), (0.0, noisy.fs / 2, noisy.noise_std)):
        sel = np.zeros_like(spec)
        m = (f >= lo) & (f <= hi)
        sel[m] = spec[m]
        x = np.fft.irfft(sel, noise.shape[0], axis=0)
        assert_allclose(x.std(axis=0), target, rtol=0.02)
    out_of_band = (f < 900.0) | (f > 46_100.0)
    assert np.abs(spec[out_of_band]).max() < 1e-3 * np.abs(spec).max()


def test_transients_on_single_channels():
    """Each false transient appears, at its amplitude, on its own channel only."""
    sc = simulate_clicks(seed=4, n_sensors=4, n_sources=1, duration_s=6.0, snr_db=np.inf,
                         n_transients=6, surface_reflection=0.0)
    assert sc.transient_times.size == 6
    fs = sc.fs
    checked = 0
    for t, ch, amp in zip(sc.transient_times, sc.transient_channels, sc.transient_amplitudes,
                          strict=True):
        a, b = int(np.floor(t * fs)), int(np.ceil((t + 0.0013) * fs))
        if not _isolated(sc, ch, t, 0.003):
            continue
        if any(np.any(np.abs(_all_arrivals(sc, c) - t) < 0.003)
               for c in range(sc.n_sensors) if c != ch):
            continue
        seg = sc.audio[a:b].astype(float)
        assert_allclose(np.abs(seg[:, ch]).max(), amp, rtol=0.25)
        others = np.delete(seg, ch, axis=1)
        assert np.all(others == 0.0)
        checked += 1
    assert checked >= 3


def test_seeded_determinism():
    """Same seed and options: identical audio and truth; another seed: different audio."""
    kw = dict(n_sensors=3, n_sources=2, duration_s=1.5, snr_db=25.0, n_transients=3)
    a, b = simulate_clicks(seed=21, **kw), simulate_clicks(seed=21, **kw)
    c = simulate_clicks(seed=22, **kw)
    assert np.array_equal(a.audio, b.audio)
    assert a.audio.dtype == np.float32
    assert np.array_equal(a.sources[1].arrival_times, b.sources[1].arrival_times)
    assert np.array_equal(a.sensors.positions, b.sensors.positions)
    assert not np.array_equal(a.audio, c.audio)


def test_results_are_read_only(clean):
    """Scenario arrays cannot be modified in place."""
    with pytest.raises(ValueError, match="read-only"):
        clean.audio[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        clean.sources[0].arrival_times[0, 0] = 0.0


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"n_sensors": 2}, "n_sensors"),
        ({"n_sensors": 11}, "n_sensors"),
        ({"n_sources": 0}, "n_sources"),
        ({"n_sources": 6}, "n_sources"),
        ({"duration_s": -1.0}, "duration_s"),
        ({"fs": 48_000.0}, "fs=48000"),
        ({"snr_db": float("nan")}, "snr_db"),
        ({"n_transients": -1}, "n_transients"),
        ({"surface_reflection": 1.5}, "surface_reflection"),
        ({"noise_band_hz": (1_000.0, 20_000.0)}, "does not overlap"),
        ({"ici_s": 0.0}, "ici_s"),
        ({"depth_range_m": (900.0, 500.0)}, "depth_range_m"),
    ],
)
def test_bad_options_raise(options, match):
    """Out-of-range options raise ValueError naming the option."""
    kw = dict(seed=0, duration_s=0.5, snr_db=np.inf) | options
    with pytest.raises(ValueError, match=match):
        simulate_clicks(**kw)


def test_click_waveform_validation():
    """A down-sweep or non-positive duration is rejected."""
    with pytest.raises(ValueError, match="upwards"):
        ClickWaveform(f_start_hz=45e3, f_end_hz=25e3)
    with pytest.raises(ValueError, match="positive"):
        ClickWaveform(duration_s=0.0)


# --------------------------------------------------------------------------------------------
# files and command line
# --------------------------------------------------------------------------------------------
def test_cli_simulate_clicks_round_trip(tmp_path, capsys):
    """`fusion simulate clicks` writes FLAC/array/truth that read back through fusion.io and
    match the in-memory scenario (channels, sample rate, samples up to 24-bit rounding)."""
    out = tmp_path / "sc"
    assert main(["simulate", "clicks", "--seed", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out.split()
    names = ("audio.flac", "array.json", "truth.json", "tdoa_labels.csv")
    assert sorted(printed) == sorted(str(out / n) for n in names)
    array = read_array(out / "array.json")
    samples, fs = read_audio(out / "audio.flac", n_channels=array.n_sensors)
    truth = read_json(out / "truth.json")
    sc = simulate_clicks(seed=1)
    assert fs == 96_000.0 and samples.shape == sc.audio.shape == (30 * 96_000, 5)
    assert_allclose(array.positions, sc.sensors.positions, rtol=0, atol=1e-9)
    scale = truth["audio_scale"]
    assert np.abs(samples).max() == pytest.approx(0.5, abs=1e-6)
    assert_allclose(samples / scale, sc.audio, rtol=0, atol=1.0 / (2**23 * scale))
    pairs = truth["pairs"]
    for src in truth["sources"]:
        expected = tdoa(np.asarray(src["positions"]), array.positions, pairs, array.sound_speed)
        assert_allclose(np.asarray(src["tdoas"]), expected, rtol=0, atol=1e-12)
        assert np.asarray(src["arrival_times"]).shape == (len(src["emission_times"]), 5)


def test_cli_bad_output_path_exit_2(tmp_path, capsys):
    """An output path that is a file: exit code 2 and one line on stderr."""
    f = tmp_path / "not_a_dir"
    f.write_text("x")
    assert main(["simulate", "clicks", "--seed", "1", "--out", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a folder" in err[0]


def test_write_click_scenario_small(tmp_path):
    """A small written scenario keeps its channel count and the noise-free zero samples."""
    sc = simulate_clicks(seed=2, n_sensors=3, n_sources=1, duration_s=1.0, snr_db=np.inf,
                         n_transients=0)
    paths = write_click_scenario(tmp_path, sc)
    assert [p.name for p in paths] == ["audio.flac", "array.json", "truth.json", "tdoa_labels.csv"]
    labels = read_table(paths[3], required=("time", "i", "j", "tau", "source"),
                        integer=("i", "j", "source"))
    arr = sc.sources[0].arrival_times
    assert labels.n_rows == arr.shape[0] * 3  # every click of every pair
    first = labels.select((labels["i"] == 0) & (labels["j"] == 2))
    assert_allclose(first["tau"], arr[:, 0] - arr[:, 2], atol=1e-9)
    samples, fs = read_audio(paths[0], n_channels=3)
    assert samples.shape == (96_000, 3) and fs == sc.fs
    truth = read_json(paths[2])
    assert truth["snr_db"] is None and truth["noise_std"] == 0.0
    assert_allclose(samples / truth["audio_scale"], sc.audio, atol=1.0 / (2**23 * truth["audio_scale"]))


def _xcorr_delay(x: np.ndarray, y: np.ndarray, fs: float, *, upsample: int = 32) -> float:
    """Delay of `y` relative to `x` (s) at the peak of their band-limited interpolated
    cross-correlation (zero-padded cross-spectrum)."""
    n = scipy.fft.next_fast_len(len(x) + len(y))
    cross = np.conj(scipy.fft.rfft(x, n)) * scipy.fft.rfft(y, n)
    cc = scipy.fft.irfft(cross, n * upsample)
    k = int(np.argmax(cc))
    if k > n * upsample // 2:
        k -= n * upsample
    return k / (fs * upsample)


def test_written_audio_carries_geometric_tdoas(tmp_path):
    """Windows cut at the true arrivals of isolated strong clicks in the written FLAC give
    cross-correlation TDOAs within a small fraction of a sample of the geometric TDOAs."""
    sc = simulate_clicks(seed=0, duration_s=12.0)
    write_click_scenario(tmp_path, sc)
    samples, fs = read_audio(tmp_path / "audio.flac", n_channels=sc.n_sensors)
    src = sc.sources[0]
    amp = np.median(np.abs(src.arrival_amplitudes), axis=0)
    i, j = sorted(int(v) for v in np.argsort(amp)[::-1][:2])
    every = [np.concatenate([s.arrival_times[:, ch] for s in sc.sources]
                            + [s.echo_arrival_times[:, ch] for s in sc.sources]
                            + [sc.transient_times[sc.transient_channels == ch]])
             for ch in range(sc.n_sensors)]
    half, search = int(0.002 * fs), int(0.005 * fs)
    errs = []
    for k in range(src.n_clicks):
        ti, tj = src.arrival_times[k, i], src.arrival_times[k, j]
        if min(abs(src.arrival_amplitudes[k, i]), abs(src.arrival_amplitudes[k, j])) < \
                10 * sc.noise_std_band:
            continue
        if any(np.sum(np.abs(every[ch] - t) < 0.02) != 1 for ch, t in ((i, ti), (j, tj))):
            continue  # another arrival nearby
        a0, b0 = int(round(ti * fs)) - half, int(round(tj * fs)) - half - search
        if a0 < 0 or b0 < 0 or max(a0 + 2 * half, b0 + 2 * (half + search)) >= samples.shape[0]:
            continue
        d = _xcorr_delay(samples[a0:a0 + 2 * half, i], samples[b0:b0 + 2 * (half + search), j], fs)
        errs.append((ti - tj) + d + (b0 - a0) / fs)
    errs = np.abs(np.asarray(errs))
    assert errs.size >= 5
    assert np.max(errs) < 0.25 / fs  # well inside one sample (10.4 us)
