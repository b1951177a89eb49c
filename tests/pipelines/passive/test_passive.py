"""Tests of the passive pipeline run end to end on seeded multi-target cubes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from fusion.io import Cube
from fusion.metrics.tracks import ScoredTrack, score_tracks
from fusion.passive.acquisition import Acquisition, AcquisitionPrior, LineStarter
from fusion.passive.crossing import CrossingDetector
from fusion.passive.quality import TrackQualityIndicator
from fusion.passive.smoothing import TrackPrior
from fusion.pipelines.passive import PassivePipeline, SmootherSettings
from fusion.pipelines.passive.types import Click, PassiveResult, Scan, scans_of
from fusion.simulate.passive import LineTarget, simulate_passive

#: Two lines of one bin crossing at 90 deg at t = 150 s, a fading line, a steady line.
TARGETS = (
    LineTarget(70.0, 8.0, 300.1, 9.0),
    LineTarget(110.0, -8.0, 300.1, 8.0),
    LineTarget(120.0, -3.0, 306.2, 8.0, fade_start_s=130.0, fade_end_s=160.0),
    LineTarget(50.0, 2.0, 312.0, 8.0),
)
N_SCANS = 260


def make_pipeline(**options) -> PassivePipeline:
    return PassivePipeline(acquisition=Acquisition(), tqi=TrackQualityIndicator(),
                           crossing=CrossingDetector(J=12, K=5.0), **options)


def scenario(seed: int = 0):
    return simulate_passive(seed=seed, targets=TARGETS, n_scans=N_SCANS, n_bins=24)


def clicks_of(sc) -> list[Click]:
    return [Click(b, f, t) for b, f, t in sc.clicks]


@pytest.fixture(scope="module")
def run0():
    """The scenario of seed 0 and the pipeline's result on it."""
    sc = scenario(0)
    return sc, make_pipeline().run(sc.cube, clicks_of(sc))


def assert_same_result(a: PassiveResult, b: PassiveResult) -> None:
    assert len(a.tracks) == len(b.tracks)
    for ta, tb in zip(a.tracks, b.tracks, strict=True):
        assert ta.start == tb.start and ta.end == tb.end
        for name in ("time", "bearing_deg", "bearing_rate_deg_per_min", "sigma_bearing_deg",
                     "sigma_rate_deg_per_min", "tqi"):
            assert_array_equal(getattr(ta, name), getattr(tb, name), err_msg=name)
    assert a.alerts == b.alerts
    assert a.resolutions == b.resolutions
    assert a.n_scans == b.n_scans


def test_step_equals_run(run0):
    """Stepping scan by scan (clicks at the first step) gives exactly run()'s result."""
    sc, res = run0
    pipe = make_pipeline()
    clicks = clicks_of(sc)
    starts = []
    for i, scan in enumerate(scans_of(sc.cube)):
        out = pipe.step(scan, clicks=clicks if i == 0 else ())
        starts += out.starts
    assert_same_result(pipe.result(), res)
    assert tuple(starts) == tuple(t.start for t in res.tracks)


def test_same_seed_same_output(run0):
    """Determinism: the same seed simulates and tracks to identical output; another seed not."""
    sc, res = run0
    again = scenario(0)
    assert_array_equal(again.cube.power, sc.cube.power)
    assert_same_result(make_pipeline().run(again.cube, clicks_of(again)), res)
    other = scenario(1)
    res1 = make_pipeline().run(other.cube, clicks_of(other))
    assert not np.array_equal(res1.tracks[0].bearing_deg, res.tracks[0].bearing_deg)


def test_acquisition_estimate_is_the_first_state_prior(run0):
    """Each track starts from the acquisition of its click; its smoothed first state stays
    within two prior sigmas of that estimate, and its sigma is below the prior's."""
    sc, res = run0
    c = sc.cube
    window = Cube(power=c.power[:60], freqs=c.freqs, scan_period=c.scan_period,
                  aperture=c.aperture, sound_speed=c.sound_speed)
    for tr, (beam, freq, t) in zip(res.tracks, sc.clicks, strict=True):
        acq = Acquisition().acquire(window, beam=beam, freq_hz=freq)
        assert tr.start.time == t == tr.time[0] == 59.0
        assert tr.start.bearing_deg == pytest.approx(acq.bearing_deg, abs=1e-9)
        assert tr.start.bearing_rate_deg_per_min == pytest.approx(acq.bearing_rate_deg_per_min,
                                                                 abs=1e-9)
        assert abs(tr.bearing_deg[0] - acq.bearing_deg) <= 2.0 * tr.start.sigma_bearing_deg
        assert tr.sigma_bearing_deg[0] <= tr.start.sigma_bearing_deg


class _ShiftedPrior(AcquisitionPrior):
    """A prior 5 deg off the acquisition with a tiny sigma: the graph must follow it."""

    def prior(self, result, **kwargs) -> TrackPrior:
        p = super().prior(result, **kwargs)
        return TrackPrior(bearing=p.bearing + math.radians(5.0), rate=p.rate,
                          sigma_bearing=math.radians(0.01), sigma_rate=p.sigma_rate)


def test_prior_enters_the_graph():
    """A pipeline given a prior 5 deg off puts its first state there (to the prior's 0.01 deg)."""
    sc = simulate_passive(seed=3, targets=TARGETS[3:], n_scans=80, n_bins=24)
    res = make_pipeline(prior=_ShiftedPrior()).run(sc.cube, clicks_of(sc))
    tr = res.tracks[0]
    assert tr.bearing_deg[0] == pytest.approx(tr.start.bearing_deg, abs=0.02)
    assert tr.start.bearing_deg - sc.bearing_deg[59, 0] == pytest.approx(5.0, abs=1.0)


def test_fading_target_ends_lost(run0):
    """The fading line's track ends `lost` within 40 updates of the line falling below 0 dB;
    the other tracks live to the end."""
    sc, res = run0
    fading = res.tracks[2]
    assert fading.end is not None
    assert fading.tqi[-1] == "lost"
    assert 0.0 < fading.end.time - sc.gone_s[2] <= 40.0
    assert [t.end for t in res.tracks if t.track_id != 2] == [None, None, None]
    assert np.all(fading.tqi[1:-1] != "lost")


def test_crossing_keeps_identities(run0):
    """The two crossing lines keep their identities: scored `kept`, resolved by an episode."""
    sc, res = run0
    scored = [ScoredTrack(t.track_id, t.time, t.bearing_deg,
                          t.end.time if t.end else math.inf) for t in res.tracks]
    score = score_tracks(scored, sc)
    assert score.outcomes.tolist() == ["kept"]
    assert any(set(r.tracks) == {0, 1} and abs(r.t_cross - 150.0) < 20.0
               for r in res.resolutions)
    assert score.rmse_deg < 0.5
    # after the crossing each track is on its own line
    for i in (0, 1):
        k = res.tracks[i].time >= 200.0
        assert_allclose(res.tracks[i].bearing_deg[k],
                        sc.bearing_deg[res.tracks[i].time[k].astype(int), i], atol=1.5)


def test_alerts_predict_the_crossing(run0):
    """The crossing detector inside the pipeline predicts the true crossing ahead of time."""
    _, res = run0
    pred = [a for a in res.alerts if (a.track_a, a.track_b) == (0, 1) and a.kind == "predicted"]
    assert pred and pred[0].time < 150.0
    assert abs(pred[0].t_cross - 150.0) < 15.0
    cols = res.alert_columns()
    assert list(cols) == ["time", "track_a", "track_b", "t_cross", "kind"]
    assert len(cols["time"]) == len(res.alerts)


def test_track_columns(run0):
    """The tracks table has one row per state with the file's columns and TQI labels."""
    _, res = run0
    cols = res.track_columns()
    assert list(cols) == ["track_id", "time", "bearing_deg", "bearing_rate_deg_per_min",
                          "sigma_bearing_deg", "tqi"]
    assert len(cols["time"]) == sum(len(t) for t in res.tracks)
    assert set(cols["tqi"]) <= {"", "lost", "uncertain", "low_snr", "strong"}
    assert np.all(cols["sigma_bearing_deg"] > 0)


def test_auto_start_finds_the_lines():
    """Without clicks, the line starter and the acquisition start one track per line."""
    sc = simulate_passive(seed=4, targets=(TARGETS[0], TARGETS[3]), n_scans=100, n_bins=24)
    pipe = make_pipeline(starter=LineStarter(window_scans=30, every_scans=10))
    res = pipe.run(sc.cube)
    assert len(res.tracks) == 2
    assert {t.start.source for t in res.tracks} == {"auto"}
    got = sorted(t.bearing_deg[-1] for t in res.tracks)
    want = sorted(sc.bearing_deg[-1])
    assert_allclose(got, want, atol=1.0)


def test_click_waits_for_the_acquisition_window():
    """A click at t = 10 s is served once 60 scans are held, at t = 59 s."""
    sc = simulate_passive(seed=5, targets=TARGETS[3:], n_scans=70, n_bins=24)
    b, f, _ = sc.clicks[0]
    res = make_pipeline().run(sc.cube, [Click(b, f, 10.0)])
    assert res.tracks[0].start.time == 59.0


def test_bad_inputs():
    """Bad scans, clicks and settings are refused with messages naming the problem."""
    sc = simulate_passive(seed=6, targets=TARGETS[3:], n_scans=10, n_bins=24, click_scan=5)
    pipe = make_pipeline()
    scans = list(scans_of(sc.cube))
    with pytest.raises(ValueError, match="outside the beams"):
        pipe.step(scans[0], clicks=[Click(99, 312.0)])
    pipe.reset()
    pipe.step(scans[1])
    with pytest.raises(ValueError, match="not after the previous"):
        pipe.step(scans[0])
    with pytest.raises(ValueError, match="outside the band"):
        pipe.step(scans[2], clicks=[Click(3, 1000.0)])
    with pytest.raises(ValueError, match="shape"):
        Scan(power=np.ones((4, 3)), time=0.0, freqs=np.ones(2), scan_period=1.0, aperture=50.0)
    with pytest.raises(ValueError, match="lag_s"):
        SmootherSettings(lag_s=-1.0)
    short = make_pipeline(smoother=SmootherSettings(lag_s=20.0))
    with pytest.raises(ValueError, match="too short"):
        short.step(scans[0])
    with pytest.raises(ValueError, match="does not continue"):
        list(scans_of([sc.cube, Cube(power=sc.cube.power[:, :-1], freqs=sc.cube.freqs,
                                     scan_period=1.0, aperture=50.0)]))
