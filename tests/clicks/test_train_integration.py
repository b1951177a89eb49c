"""Train integration: a sensor's delay from clicks below the detection threshold."""

from __future__ import annotations

import numpy as np
import pytest

from fusion.clicks.detect import ClickDetector
from fusion.clicks.train_integration import train_delay
from tests.clicks.click_trains import FS, two_channel_train

TAU_S = 0.61237  # t_weak - t_strong at the window centre
RATE = 4e-4
T_C = 6.0


def _two_sensors(weak_amplitude: float, seed: int = 5):
    """12 s of white noise (std 1) on two channels; 28 clicks with jittered intervals at
    amplitude 6 on channel 0 and `weak_amplitude` on channel 1, TAU_S later, drifting at
    RATE. Returns the audio and the weak channel's true arrival times."""
    x, _, weak = two_channel_train(weak_amplitude, lambda emit: emit + TAU_S + RATE * (emit - T_C),
                                   seed)
    return x, weak


def _detected(found, true_times) -> int:
    if not found.size:
        return 0
    return int(np.sum(np.min(np.abs(found[:, None] - true_times[None]), axis=0) < 3e-4))


def test_a_train_below_the_detection_threshold_gives_its_delay():
    """The weak channel's clicks are at 1.5 (noise std 1): the detector finds at most 3 of
    them; summed along the strong channel's detected train (its 5 or so noise detections
    included) its statistic gives the delay within 10 us, the drift within its grid step,
    well above the false-alarm level."""
    x, weak = _two_sensors(1.5)
    det = ClickDetector(false_alarms_per_s=0.5)
    clicks = det.detect(x, FS)
    assert _detected(clicks[1].times_s, weak) <= 3
    times, stat = det.statistic(x, FS)
    d = train_delay(stat[1], times[0], times[1] - times[0], clicks[0].times_s,
                    max_delay_s=1.5, t_c_s=T_C, smooth_s=det.nfft / FS,
                    cap=det.threshold_at(FS))
    assert d is not None and d.z > d.z_threshold + 3.0
    assert abs(d.delay_s - TAU_S) < 10e-6
    assert abs(d.rate - RATE) < 2e-5
    assert 0.5e-6 < d.sigma_s < 10e-6
    # the weak channel's arrivals of the strong channel's clicks, as the delay places them
    placed = d.times_at_weak(clicks[0].times_s)
    assert _detected(placed, weak) >= 25


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_no_delay_where_the_weak_sensor_holds_no_clicks(seed):
    """The same search on a channel of noise alone finds nothing (false-alarm probability
    1e-3 a search)."""
    x, _ = _two_sensors(0.0, seed=seed)
    det = ClickDetector(false_alarms_per_s=0.5)
    clicks = det.detect(x, FS)
    times, stat = det.statistic(x, FS)
    assert train_delay(stat[1], times[0], times[1] - times[0], clicks[0].times_s,
                       max_delay_s=1.5, t_c_s=T_C, smooth_s=det.nfft / FS,
                       cap=det.threshold_at(FS)) is None


def test_the_cap_keeps_a_transient_from_making_a_delay():
    """A single loud transient on the weak channel (statistic in the hundreds) put a peak in
    the sum wherever one reference click meets it; clipped at the detection threshold it
    does not."""
    x, _ = _two_sensors(0.0, seed=4)
    x[int(5.0 * FS):int(5.0 * FS) + 40, 1] += 40.0 * np.sin(2e5 * np.arange(40) / FS)
    det = ClickDetector(false_alarms_per_s=0.5)
    clicks = det.detect(x, FS)
    times, stat = det.statistic(x, FS)
    kw = dict(max_delay_s=1.5, t_c_s=T_C, smooth_s=det.nfft / FS, max_rate=0.0)
    assert stat[1].max() > 50
    assert train_delay(stat[1], times[0], times[1] - times[0], clicks[0].times_s, **kw) is not None
    assert train_delay(stat[1], times[0], times[1] - times[0], clicks[0].times_s,
                       cap=det.threshold_at(FS), **kw) is None


def test_statistic_is_the_one_detect_thresholds():
    """Every detected click sits on a local maximum of :meth:`ClickDetector.statistic` at or
    above the threshold, with the power the detector reports."""
    x, _ = _two_sensors(3.0)
    det = ClickDetector(false_alarms_per_s=0.5)
    clicks = det.detect(x, FS)
    times, stat = det.statistic(x, FS)
    for ch in range(2):
        j = np.searchsorted(times, clicks[ch].times_s)
        near = np.where(np.abs(times[j - 1] - clicks[ch].times_s)
                        < np.abs(times[np.minimum(j, times.size - 1)] - clicks[ch].times_s),
                        j - 1, j)
        assert np.allclose(stat[ch][near], clicks[ch].power, rtol=1e-5)
        assert np.all(stat[ch][near] >= det.threshold_at(FS))


def test_front_end_places_the_weakly_heard_sensors_of_a_window():
    """Tuning seed 4 at 24 dB (one whale, floor and surface echoes, 16 s): sensors 1 and 4
    hear the whale 10 and 16 dB below the best one and their trains are detected in 2-14 of
    ~33 clicks, so the validated click-map TDOAs span sensors 0, 2 and 3 in every window (no
    fix). Summed along sensor 0's train, sensor 1 gives a valid TDOA in all three windows and
    sensor 4 in two (spans 5, 5, 4), each within three sigmas of the true direct-path delay;
    without train integration none."""
    from fusion.pipelines.clicks import LLR_THRESHOLD, ClickFrontEnd, default_validator
    from fusion.pipelines.clicks.training import scenario_labels
    from fusion.simulate.clicks import simulate_clicks

    sc = simulate_clicks(seed=4, n_sensors=5, n_sources=1, duration_s=16.0, snr_db=24.0,
                         echo="both")
    labels = scenario_labels(sc)
    spans = {}
    for on in (True, False):
        fe = ClickFrontEnd(detector=ClickDetector(false_alarms_per_s=0.5),
                           validator=default_validator(LLR_THRESHOLD), train_integration=on)
        windows = fe.run_array(sc.audio, sc.fs, sc.sensors)
        spans[on] = [len({s for t in w.valid_tdoas for s in t.pair}) for w in windows]
        trains = [(w, t) for w in windows for t in w.valid_tdoas if np.isfinite(t.train_z)]
        if not on:
            assert not trains
            continue
        assert sorted({w.t_start for w, t in trains if t.pair == (0, 1)}) == [0.0, 2.0, 4.0]
        for w, t in trains:
            ref = labels.tau_at(t.pair, t.t_s, w.t_start, w.t_end)
            assert np.min(np.abs(ref - t.tau_s)) < 3.0 * t.sigma_s
    assert spans[False] == [3, 3, 3] and min(spans[True]) >= 4 and sum(spans[True]) >= 13
