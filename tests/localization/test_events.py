"""Tests of the event localizer: waveform TDOAs, closure, solve, surface check, files, real data."""

from __future__ import annotations

import argparse
import csv
import json
import logging
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from factors.tdoa.model import predicted_tdoas
from fusion.commands.localize_events import add_event_options, event_document, run_events
from fusion.geometry import SensorArray
from fusion.io import read_array, read_audio_files, write_json
from fusion.localization.event_tdoa import bandpass, closure_screen, estimate_band, pair_tdoas
from fusion.localization.events import Event, EventFix, EventLocalizer

XAV = Path(__file__).resolve().parents[1] / "data" / "xav"
FS = 32_000.0


@pytest.fixture(scope="module")
def xav() -> SensorArray:
    """The 6-hydrophone, 1.7 m XAV frame (c = 1484 m/s)."""
    return read_array(XAV / "array.json")


def burst_audio(sensors: np.ndarray, source: np.ndarray, c: float, fs: float, *, t0: float = 0.5,
                dur: float = 1.0, burst_s: float = 0.08, band: tuple = (200.0, 2000.0),
                snr_db: float = 30.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A band-limited noise burst at `t0` on sensor-range delays (exact, in frequency) + noise.

    Returns the audio (n, n_sensors) and the true arrival delays (n_sensors,) in s.
    `snr_db` is the burst's power over the in-band noise power.
    """
    rng = np.random.default_rng(seed)
    n = int(round(dur * fs))
    t = np.arange(n) / fs
    f = np.fft.rfftfreq(n, 1.0 / fs)
    spec = (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size))
    spec *= (f >= band[0]) & (f <= band[1])
    w = np.fft.rfft(np.fft.irfft(spec, n) * np.exp(-0.5 * ((t - t0) / (burst_s / 4)) ** 2))
    delays = np.linalg.norm(np.asarray(source) - sensors, axis=1) / c
    x = np.stack([np.fft.irfft(w * np.exp(-2j * np.pi * f * d), n) for d in delays], axis=1)
    x /= x.std()
    noise_sd = np.sqrt(10 ** (-snr_db / 10) / ((band[1] - band[0]) / (fs / 2)))
    return x + noise_sd * rng.standard_normal(x.shape), delays


def test_synthetic_tdoas_and_position(xav):
    """Sub-sample delays on the 1.7 m frame: every TDOA within 1 us, the source within 1 cm."""
    src = np.array([0.9, -0.6, -0.9])
    x, delays = burst_audio(xav.positions, src, xav.sound_speed, FS, snr_db=40.0)
    fix = EventLocalizer().localize(x, FS, xav, [Event(0.46, 0.54, 200.0, 2000.0)])[0]
    true = predicted_tdoas(src, xav.positions, fix.tdoas.pairs, c=xav.sound_speed)
    frac = np.abs(true * FS - np.round(true * FS))
    assert np.median(frac) > 0.1  # the delays really are between samples
    np.testing.assert_allclose(fix.tdoas.taus, true, atol=1e-6)
    assert fix.n_used == 15 and fix.observable and fix.in_region and fix.surface_agrees
    assert np.linalg.norm(fix.position - src) < 0.01
    assert np.all((fix.interval_95[:, 0] <= src) & (src <= fix.interval_95[:, 1]))
    assert fix.band_source == "given" and fix.band_hz == (200.0, 2000.0)
    assert np.linalg.norm(fix.surface_peak - src) < 0.05


def test_tuple_event_without_band_is_estimated(xav):
    """An event given as (t_start, t_end) gets an estimated band and the same source."""
    src = np.array([-1.2, 0.4, -0.7])
    x, _ = burst_audio(xav.positions, src, xav.sound_speed, FS, snr_db=20.0, t0=1.5, dur=2.0)
    fix = EventLocalizer(surface=False).localize(x, FS, xav, [(1.46, 1.54)])[0]
    assert fix.band_source == "estimated" and fix.surface_agrees is None  # check not run
    assert fix.band_hz[0] < 300.0 and 1800.0 < fix.band_hz[1] < 2400.0
    assert np.linalg.norm(fix.position - src) < 0.01


def test_estimate_band_finds_burst_band(xav):
    """The band estimate brackets a 300-3000 Hz burst at 10 dB SNR to within 150 Hz."""
    x, _ = burst_audio(xav.positions, np.array([0.5, 0.5, -1.0]), xav.sound_speed, FS,
                       snr_db=10.0, band=(300.0, 3000.0), dur=2.0, t0=1.5, seed=3)
    lo, hi = estimate_band(x[int(1.46 * FS):int(1.54 * FS)], x[int(0.4 * FS):int(1.4 * FS)], FS)
    assert abs(lo - 300.0) < 150.0 and abs(hi - 3000.0) < 150.0
    assert estimate_band(x[:20], x[:2000], FS) is None  # too short to tell


def test_tdoa_sigmas_match_scatter(xav):
    """Carter-bound sigmas from the data match the scatter of the TDOAs over noise seeds."""
    src = np.array([0.3, 1.1, -1.0])
    true = predicted_tdoas(src, xav.positions, np.array(xav.pairs()), c=xav.sound_speed)
    z = []
    for seed in range(24):
        x, _ = burst_audio(xav.positions, src, xav.sound_speed, FS, snr_db=3.0, seed=seed)
        seg = bandpass(x, FS, (200.0, 2000.0))[int(0.455 * FS):int(0.545 * FS)]
        m = pair_tdoas(seg, FS, xav.positions, xav.sound_speed, band_hz=(200.0, 2000.0))
        z.append((m.taus - true) / m.sigmas)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.7 < rms < 1.4


def test_covariance_covers_truth(xav):
    """The 95 % intervals hold the truth (coverage >= 0.9), errors within about one sigma."""
    rng = np.random.default_rng(7)
    hits, z = [], []
    loc = EventLocalizer(surface=False)
    for seed in range(16):
        src = np.array([rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5), rng.uniform(-1.5, -0.8)])
        x, _ = burst_audio(xav.positions, src, xav.sound_speed, FS, snr_db=5.0, seed=seed)
        fix = loc.localize(x, FS, xav, [Event(0.46, 0.54, 200.0, 2000.0)])[0]
        hits.append((fix.interval_95[:, 0] <= src) & (src <= fix.interval_95[:, 1]))
        z.append((fix.position - src) / np.sqrt(np.diag(fix.covariance)))
    assert np.mean(hits) >= 0.9
    assert 0.4 < float(np.sqrt(np.mean(np.square(z)))) < 1.3


def test_scale_invariance(xav):
    """The same audio on a 1000x larger array at 1/1000 the rate gives 1000x the answer."""
    src = np.array([0.9, -0.6, -0.9])
    x, _ = burst_audio(xav.positions, src, xav.sound_speed, FS, snr_db=20.0)
    k = 1000.0
    a = EventLocalizer().localize(x, FS, xav, [Event(0.46, 0.54, 200.0, 2000.0)])[0]
    big = SensorArray(xav.positions * k, xav.sound_speed)
    b = EventLocalizer(band_floor_hz=10.0 / k).localize(
        x, FS / k, big, [Event(0.46 * k, 0.54 * k, 200.0 / k, 2000.0 / k)])[0]
    np.testing.assert_allclose(b.tdoas.taus, a.tdoas.taus * k, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(b.position, a.position * k, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(b.covariance, a.covariance * k * k, rtol=1e-5, atol=1e-9)
    assert a.surface_agrees and b.surface_agrees


def test_lag_restricted_to_physical_range(xav):
    """A stronger copy at an impossible delay is ignored; the weaker physical one is found."""
    rng = np.random.default_rng(5)
    n = 16000
    s = bandpass(rng.standard_normal((n, 1)), FS, (200.0, 4000.0))[:, 0]
    d_max = np.linalg.norm(xav.positions[0] - xav.positions[1]) / xav.sound_speed * FS  # samples
    y = np.zeros((n, 6))
    y[:, 0] = s
    y[:, 1] = 0.5 * np.roll(s, 10) + 1.0 * np.roll(s, int(d_max) + 200)  # t_0 - t_1 = -10 samples
    m = pair_tdoas(y, FS, xav.positions, xav.sound_speed, band_hz=(200.0, 4000.0),
                   pairs=[(0, 1), (1, 0)])
    np.testing.assert_allclose(m.taus, [-10 / FS, 10 / FS], atol=0.05 / FS)
    assert not m.at_edge.any()


def test_closure_screen_drops_the_corrupted_pair(xav):
    """Triangle closure sets aside exactly the one TDOA corrupted by 100 sigma."""
    pairs = np.array(xav.pairs())
    taus = predicted_tdoas([0.4, -0.2, -1.1], xav.positions, pairs, c=xav.sound_speed)
    taus = taus + np.random.default_rng(2).normal(0.0, 1e-6, taus.size)
    sig = np.full(taus.size, 1e-6)
    keep, rms = closure_screen(pairs, taus, sig, np.ones(taus.size, bool))
    assert keep.all() and rms < 4e-6
    bad = taus.copy()
    bad[4] += 1e-4
    keep, rms = closure_screen(pairs, bad, sig, np.ones(taus.size, bool))
    assert np.flatnonzero(~keep).tolist() == [4] and rms > 1e-5


def test_localize_rejects_bad_input(xav):
    """Wrong audio shape, non-finite samples, an event after the end and bad events raise."""
    x = np.zeros((1000, 6))
    loc = EventLocalizer()
    with pytest.raises(ValueError, match="shape"):
        loc.localize(np.zeros((1000, 5)), FS, xav, [(0.0, 0.01)])
    with pytest.raises(ValueError, match="NaN"):
        loc.localize(np.full((1000, 6), np.nan), FS, xav, [(0.0, 0.01)])
    with pytest.raises(ValueError, match="after the end"):
        loc.localize(x, FS, xav, [(1.0, 1.1)])
    with pytest.raises(ValueError, match="t_start < t_end"):
        Event(0.2, 0.1)
    with pytest.raises(ValueError, match="below f_high"):
        Event(0.1, 0.2, 500.0, 100.0)
    with pytest.raises(ValueError, match="delay_margin"):
        EventLocalizer(delay_margin=0.5)


# ------------------------------------------------------------------ multi-file audio
def _write(path: Path, n: int, fs: int, channels: int = 1, seed: int = 0) -> np.ndarray:
    x = np.random.default_rng(seed).uniform(-0.5, 0.5, (n, channels))
    sf.write(path, x, fs, subtype="PCM_24")
    return sf.read(path, dtype="float64", always_2d=True)[0]


def test_read_audio_files_trims_to_shortest_with_warning(tmp_path, caplog):
    """Mono files of different lengths are stacked in order, trimmed, with one warning."""
    cols = [_write(tmp_path / f"h{k}.wav", n, 8000, seed=k)
            for k, n in enumerate((1003, 1000, 1001))]
    with caplog.at_level(logging.WARNING, logger="fusion.io.audio"):
        x, fs = read_audio_files([tmp_path / f"h{k}.wav" for k in range(3)], 3)
    assert fs == 8000.0 and x.shape == (1000, 3)
    np.testing.assert_array_equal(x, np.column_stack([c[:1000, 0] for c in cols]))
    assert sum("trimmed to the shortest" in r.message for r in caplog.records) == 1


def test_read_audio_files_errors(tmp_path):
    """A sample-rate mismatch names the files; wrong counts and stereo files are refused."""
    _write(tmp_path / "a.wav", 100, 8000)
    _write(tmp_path / "b.wav", 100, 16000)
    _write(tmp_path / "s.wav", 100, 8000, channels=2)
    with pytest.raises(ValueError, match=r"different sample rates: .*a\.wav \(8000 Hz\).*b\.wav"):
        read_audio_files([tmp_path / "a.wav", tmp_path / "b.wav"], 2)
    with pytest.raises(ValueError, match=r"1 channel\(s\) but the array has 2 sensors"):
        read_audio_files([tmp_path / "a.wav"], 2)
    with pytest.raises(ValueError, match="expected a mono file"):
        read_audio_files([tmp_path / "a.wav", tmp_path / "s.wav"], 2)
    with pytest.raises(FileNotFoundError):
        read_audio_files([tmp_path / "a.wav", tmp_path / "none.wav"], 2)


# ------------------------------------------------------------------ command and JSON
def _parse(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    p.add_argument("--audio", type=Path, nargs="+")
    p.add_argument("--array", type=Path)
    p.add_argument("--events", type=Path)
    p.add_argument("--out", type=Path)
    add_event_options(p)
    return p.parse_args(argv)


def test_run_events_writes_json(tmp_path, xav):
    """One multichannel file and an events CSV without bands give the documented JSON."""
    src = np.array([-0.7, 0.8, -1.2])
    x, _ = burst_audio(xav.positions, src, xav.sound_speed, FS, snr_db=30.0, t0=1.5, dur=2.0)
    sf.write(tmp_path / "a.wav", x / np.abs(x).max() * 0.9, int(FS), subtype="PCM_24")
    (tmp_path / "e.csv").write_text("t_start,t_end\n1.46,1.54\n")
    args = _parse(["--audio", str(tmp_path / "a.wav"), "--array", str(XAV / "array.json"),
                   "--events", str(tmp_path / "e.csv"), "--out", str(tmp_path / "r.json")])
    assert run_events(args) == 0
    ev = json.loads((tmp_path / "r.json").read_text())["events"][0]
    assert np.linalg.norm([ev["x"] - src[0], ev["y"] - src[1], ev["z"] - src[2]]) < 0.01
    assert ev["band_source"] == "estimated" and len(ev["tdoas"]) == 15 and ev["tdoas_used"] == 15
    assert ev["interval_95"]["z"][0] < src[2] < ev["interval_95"]["z"][1]
    assert np.shape(ev["cov"]) == (3, 3) and ev["observable"] and ev["surface_agrees"]


def test_event_document_nan_is_null(tmp_path, xav):
    """An unobservable fix (NaN covariance and interval) is written with nulls."""
    x, _ = burst_audio(xav.positions, np.array([0.2, 0.3, -1.0]), xav.sound_speed, FS)
    fix = EventLocalizer(surface=False).localize(x, FS, xav, [Event(0.46, 0.54, 200, 2000)])[0]
    bad = EventFix(**{**fix.__dict__, "covariance": np.full((3, 3), np.nan),
                      "interval_95": np.full((3, 2), np.nan), "observable": False})
    doc = event_document([bad], sound_speed=xav.sound_speed, fs=FS)
    write_json(tmp_path / "r.json", doc)
    ev = json.loads((tmp_path / "r.json").read_text())["events"][0]
    assert ev["cov"][0][0] is None and ev["interval_95"]["x"] == [None, None]
    assert ev["x"] == pytest.approx(fix.position[0])


def test_unobservable_event_has_no_position(tmp_path, xav):
    """A source 3 km from the 1.7 m frame: range is not observable; no runaway position written."""
    x, _ = burst_audio(xav.positions, np.array([3000.0, 0.0, 0.0]), xav.sound_speed, FS)
    fix = EventLocalizer(surface=False).localize(x, FS, xav, [Event(0.4, 0.6, 200, 2000)])[0]
    assert not fix.observable and fix.n_used >= 10
    assert np.all(np.isnan(fix.position)) and np.all(np.isnan(fix.interval_95))
    write_json(tmp_path / "r.json", event_document([fix], sound_speed=xav.sound_speed, fs=FS))
    ev = json.loads((tmp_path / "r.json").read_text())["events"][0]
    assert ev["x"] is None and ev["y"] is None and ev["z"] is None and not ev["in_region"]


# ------------------------------------------------------------------ recorded data
@pytest.mark.parametrize("cut", ["cut1", "cut2"])
def test_xav_kept_events_inside_published_intervals(tmp_path, cut):
    """Recorded fish sounds (trimmed XAV copy): every kept localization is inside its interval."""
    files = sorted(XAV.glob(f"{cut}_AMAR173.*.flac"), key=lambda p: int(p.name.split(".")[1]))
    args = _parse(["--audio", *map(str, files), "--array", str(XAV / "array.json"),
                   "--events", str(XAV / f"{cut}_events.csv"), "--out", str(tmp_path / "r.json")])
    assert run_events(args) == 0
    events = json.loads((tmp_path / "r.json").read_text())["events"]
    rows = list(csv.DictReader((XAV / f"{cut}_events.csv").open()))
    assert len(events) == len(rows)
    kept = [(r, e) for r, e in zip(rows, events, strict=True)
            if r["kept_by_notebook_filter"] == "True"]
    assert len(kept) >= 3
    for r, e in kept:
        for axis in "xyz":
            lo, hi = float(r[f"{axis}_err_low_m"]), float(r[f"{axis}_err_high_m"])
            assert lo <= e[axis] <= hi, (r["detection_index"], axis, e[axis], lo, hi)
        assert e["observable"] and e["surface_agrees"] and e["tdoas_used"] >= 14
        assert 2e-5 < e["residual_rms_s"] < 1.2e-4  # the data's TDOA-fit level, 40-60 us
