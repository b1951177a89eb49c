"""Bottom echoes decided from the data: known lags and levels, controls, the localize default."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fusion.clicks.echoes import (
    ECHO_Z,
    FLOOR_MARGIN_M,
    WEAK_ECHO_Z,
    bottom_echoes,
    echo_window,
)
from fusion.clicks.types import ChannelClicks

FS = 96_000.0


def _click(n=33, f=30_000.0):
    t = (np.arange(n) - n // 2) / FS
    return np.hanning(n) * np.cos(2 * np.pi * f * t)


def _audio(echo_lag_s=None, echo_db=-10.0, *, seed=0, n_ch=4, other_train=False):
    """Clicks every ~0.4 s on each channel, each followed by an echo at a fixed lag."""
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 0.02, (int(30 * FS), n_ch))
    clicks = []
    for ch in range(n_ch):
        times = np.cumsum(rng.uniform(0.35, 0.45, 70)) + 0.1
        times = times[times < 29.8]
        for t in times:
            i = int(round(t * FS))
            x[i - 16:i + 17, ch] += _click()
            if echo_lag_s is not None:
                j = i + int(round(echo_lag_s[ch] * FS))
                x[j - 16:j + 17, ch] += 10 ** (echo_db / 20) * _click()
            if other_train:  # a second source's clicks at random lags on either side
                k = i + int(rng.uniform(-0.03, 0.03) * FS)
                x[k - 16:k + 17, ch] += 0.5 * _click()
        clicks.append(ChannelClicks(ch, times, np.ones(times.size), np.full(times.size, 3e4)))
    return x, clicks


def test_known_lags_and_level_are_measured():
    """Echoes 1.5-12 ms after every click at -10 dB: lags to 0.05 ms, level to 1 dB."""
    lags = np.array([1.5e-3, 4.0e-3, 8.25e-3, 12.0e-3])
    x, clicks = _audio(lags)
    e = bottom_echoes(x, FS, clicks)
    assert e.near_floor and e.present.all()
    assert np.allclose(e.lag_s, lags, atol=5e-5)
    assert np.allclose(e.level_db, -10.0, atol=1.0)
    assert "on 4 of 4 sensors" in e.describe()


def test_no_echo_is_no_floor_even_with_other_sources_around():
    """Without echoes -- alone, or with another source's clicks at random lags -- no channel
    shows one: the control before the clicks sees the other source as often."""
    for other in (False, True):
        x, clicks = _audio(None, other_train=other, seed=3)
        e = bottom_echoes(x, FS, clicks)
        assert not e.present.any() and not e.near_floor
        assert "no bottom echo" in e.describe()


def test_half_the_channels_decide_and_few_clicks_abstain():
    """Two of four channels with an echo: near the floor; a channel with too few clicks is
    not counted (NaN)."""
    lags = np.array([3e-3, 5e-3, np.nan, np.nan])
    x, clicks = _audio(None)
    y, _ = _audio(np.nan_to_num(lags, nan=0.0))
    x[:, :2] = y[:, :2]
    assert bottom_echoes(x, FS, clicks).near_floor
    clicks[3] = ChannelClicks(3, clicks[3].times_s[:3], np.ones(3), np.full(3, 3e4))
    e = bottom_echoes(x, FS, clicks)
    assert np.isnan(e.z[3]) and e.n_clicks[3] == 0
    with pytest.raises(ValueError, match="lag_range_s"):
        bottom_echoes(x, FS, clicks, lag_range_s=(0.0, 1e-2))


@pytest.mark.parametrize("echo", ["bottom", "none"])
def test_localize_decides_the_sea_floor_from_the_recording(tmp_path, echo):
    """`fusion localize` without --sea-floor-z-m: the detection band from the estimated replica;
    a recording with bottom echoes gets the floor
    below the deepest sensor (printed, in the settings file); one without takes the hydrophones
    as bottom-mounted (the same bound, another source named); with --sea-floor-z-m, that one."""
    from fusion.cli import main

    assert main(["simulate", "clicks", "--seed", "21", "--out", str(tmp_path / "s"),
                 "--whales", "1", "--duration-s", "30", "--echo", echo]) == 0
    array = json.loads((tmp_path / "s" / "array.json").read_text())
    assert main(["localize", "--audio", str(tmp_path / "s" / "audio.flac"), "--array",
                 str(tmp_path / "s" / "array.json"), "--out", str(tmp_path / "r.json"),
                 "--quiet"]) == 0
    side = json.loads((tmp_path / "r.settings.json").read_text())
    deepest = min(s["z"] for s in array["sensors"])
    # the detection band: the estimated replica's, at least the method's width, below Nyquist
    lo, hi = side["band"]["band_hz"]
    assert side["band"]["source"] == "estimated replica"
    assert hi - lo >= side["band"]["min_width_hz"] - 1e-6 and hi <= 0.95 * 48_000.0
    if echo == "bottom":
        assert side["sea_floor"]["source"] == "bottom echoes"
        assert side["sea_floor"]["sea_floor_z"] == pytest.approx(deepest - FLOOR_MARGIN_M)
        assert side["localization"]["sea_floor_z"] == pytest.approx(deepest - FLOOR_MARGIN_M)
    else:
        assert not side["sea_floor"]["near_floor"]
        assert side["sea_floor"]["source"] == "bottom-mounted (no bottom echo heard)"
        assert side["localization"]["sea_floor_z"] == pytest.approx(deepest - FLOOR_MARGIN_M)
        assert main(["localize", "--audio", str(tmp_path / "s" / "audio.flac"), "--array",
                     str(tmp_path / "s" / "array.json"), "--out", str(tmp_path / "g.json"),
                     "--quiet", "--sea-floor-z-m", str(deepest - 500.0),
                     "--band-hz", "15000", "41000"]) == 0
        given = json.loads((tmp_path / "g.settings.json").read_text())
        assert given["band"] == {"source": "given", "band_hz": [15000.0, 41000.0]}
        assert given["sea_floor"]["source"] == "given"
        assert given["localization"]["sea_floor_z"] == pytest.approx(deepest - 500.0)


def _echoes_after(detected, direct):
    """Detections 3.9-4.1 ms after a direct click."""
    lag = detected.times_s[:, None] - direct.times_s[None]
    return int(np.sum(np.any((lag > 3.9e-3) & (lag < 4.1e-3), axis=1)))


def test_echo_window_drops_the_echoes_and_keeps_the_clicks():
    """A detector with the echo window measured from the recording keeps every direct click
    and drops the detected echoes 4 ms after them; without it, the echoes are clicks too."""
    from fusion.clicks.detect import ClickDetector
    from fusion.clicks.echoes import echo_window

    x, clicks = _audio(np.full(4, 4e-3), echo_db=-3.0)
    e = bottom_echoes(x, FS, clicks)
    window = echo_window(e)
    assert window == pytest.approx((0.25e-3, 8e-3), abs=1e-4)
    plain = ClickDetector().detect(x, FS)
    suppressed = ClickDetector(echo_window_s=window).detect(x, FS)
    assert ClickDetector().with_echo_window(window).echo_window_s == window
    for c, p, s in zip(clicks, plain, suppressed, strict=True):
        near = np.min(np.abs(s.times_s[:, None] - c.times_s[None]), axis=0)
        assert np.all(near < 1e-4)  # every direct click kept
        assert _echoes_after(s, c) == 0
        assert _echoes_after(p, c) >= 0.9 * c.times_s.size  # without the window: clicks too
    with pytest.raises(ValueError, match="echo_window_s"):
        ClickDetector(echo_window_s=(0.01, 0.001))


def _sparse_audio(lags, levels_db, *, seed):
    """Clicks about every 0.8 s (37 in 30 s) on each channel, each followed by an echo at the
    channel's lag and level (None: no echo)."""
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 0.02, (int(30 * FS), len(lags)))
    clicks = []
    for ch, (lag, db) in enumerate(zip(lags, levels_db, strict=True)):
        times = np.cumsum(rng.uniform(0.75, 0.85, 40)) + 0.1
        times = times[times < 29.8]
        for t in times:
            i = int(round(t * FS))
            x[i - 16:i + 17, ch] += _click()
            if db is not None:
                j = i + int(round(lag * FS))
                x[j - 16:j + 17, ch] += 10 ** (db / 20) * _click()
        clicks.append(ChannelClicks(ch, times, np.ones(times.size), np.full(times.size, 3e4)))
    return x, clicks


def test_weak_echoes_count_once_one_channel_shows_an_echo():
    """One channel's echo at -10 dB, the others' at -33 dB, 37 clicks each: the others' averaged
    echoes stand 5-8 robust sigmas above the control, under the full threshold. With the weak
    evidence read (the default) the array is near the floor and the echo window covers the
    longest lag (14 ms); with every channel at the full threshold (``weak=False``, ``fusion
    localize --strong-echoes-only``) only one channel of four shows an echo: no floor, no
    suppression. Channels with no echo at all stay unheard."""
    lags = np.array([3e-3, 6e-3, 9e-3, 14e-3])
    x, clicks = _sparse_audio(lags, [-10.0, -33.0, -33.0, -33.0], seed=2)
    e = bottom_echoes(x, FS, clicks)
    assert e.present.tolist() == [True, False, False, False]
    assert np.all((e.z[1:] >= WEAK_ECHO_Z) & (e.z[1:] < ECHO_Z))
    assert e.heard.all() and e.near_floor
    assert np.allclose(e.lag_s, lags, atol=5e-5)
    lo, hi = echo_window(e)
    assert hi == pytest.approx(2 * e.lag_s[3]) and hi > lags[3]
    strict = bottom_echoes(x, FS, clicks, weak=False)
    assert np.array_equal(strict.z, e.z) and not strict.near_floor
    assert strict.heard.tolist() == [True, False, False, False]
    for seed in (0, 1, 2):  # no echo on the other channels: only the first one hears one
        x, clicks = _sparse_audio(lags, [-10.0, None, None, None], seed=seed)
        e = bottom_echoes(x, FS, clicks)
        assert e.heard.tolist() == [True, False, False, False] and not e.near_floor
