"""Whale localization end to end: sources near the truth, tracks with the whale's speed."""

from __future__ import annotations

import numpy as np
import pytest

from fusion.pipelines.localization import (
    ClickLocalization,
    result_document,
    track_windows,
    whale_localizer,
)
from fusion.simulate.clicks import simulate_clicks


@pytest.fixture(scope="module")
def localized():
    """Two whales, a bottom-mounted 5-sensor array, 30 s at 30 dB, every window localized.

    The sea floor is the deepest hydrophone's depth (what a user knows of the deployment).
    """
    sc = simulate_clicks(seed=0, n_sensors=5, n_sources=2, duration_s=30.0, snr_db=30.0)
    bottom = float(sc.sensors.positions[:, 2].min())
    pipe = ClickLocalization(localizer=whale_localizer(bottom_z=bottom))
    windows = pipe.front_end.run_array(sc.audio, sc.fs, sc.sensors)
    return sc, [pipe.localize(w, sc.sensors) for w in windows]


def test_observable_sources_lie_on_a_whale(localized):
    """Every source flagged observable is within 5 m of one of the whales' tracks."""
    sc, lws = localized
    fixes = [(lw, f) for lw in lws if lw.output is not None for f in lw.output.sources
             if f.observable]
    assert len(fixes) >= 5
    for lw, f in fixes:
        mid = 0.5 * (lw.window.t_start + lw.window.t_end)
        times = np.linspace(mid - 4.0, mid, 81)  # emission times around the window
        d = min(np.min(np.linalg.norm(s.position_at(times) - f.position, axis=1))
                for s in sc.sources)
        assert d < 5.0


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
