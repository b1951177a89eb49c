"""A train-integrated delay refined on the waveforms: the train's cross-spectra summed."""

from __future__ import annotations

import numpy as np
import pytest

from fusion.clicks.train_refine import refine_train_delay
from tests.clicks.click_trains import FS, two_channel_train

T_C = 6.0


def _train(weak_amplitude: float, tau: float, rate: float, accel: float = 0.0, seed: int = 5):
    """12 s of white noise (std 1) on two channels; ~28 clicks at amplitude 6 on channel 0
    and `weak_amplitude` on channel 1, ``tau + rate u + accel u^2 / 2`` later (``u`` from
    T_C). Returns the audio and channel 0's click times."""
    def weak(emit):
        u = emit - T_C
        return emit + tau + rate * u + 0.5 * accel * u * u

    x, emit, _ = two_channel_train(weak_amplitude, weak, seed)
    return x, emit


@pytest.mark.parametrize("seed", [5, 6, 7])
def test_a_weak_train_delay_is_refined_to_a_microsecond(seed):
    """Clicks at 1.5 (noise std 1, a few dB per click: the detector finds a few of them):
    started 8 us and a drift step off, as read off the statistic's frames, the summed
    cross-spectra give the delay within 1 us and a sigma of the right size."""
    tau, rate = 0.61237, 4e-4
    x, ref = _train(1.5, tau, rate, seed=seed)
    r = refine_train_delay(x, FS, (0, 1), ref, tau + 8e-6, rate + 5e-6, T_C)
    assert r is not None and r.n_clicks >= 25
    assert abs(r.delay_s - tau) < 1e-6
    assert abs(r.rate - rate) < 3e-6
    assert 0.1e-6 < r.sigma_s < 2e-6 and r.snr > 8


def test_the_delays_curvature_is_searched():
    """A turning source bends the delay (2e-6 s/s^2: 36 us at the window's ends): a straight
    line through the train is off at its centre, the curvature search is not."""
    tau, rate, accel = 0.2, -3e-4, 1.5e-6
    x, ref = _train(1.5, tau, rate, accel=accel, seed=8)
    curved = refine_train_delay(x, FS, (0, 1), ref, tau + 3e-6, rate, T_C)
    straight = refine_train_delay(x, FS, (0, 1), ref, tau + 3e-6, rate, T_C, max_accel=0.0)
    assert curved is not None and abs(curved.delay_s - tau) < 1e-6
    assert straight is None or abs(straight.delay_s - tau) > 2.0 * abs(curved.delay_s - tau)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_no_refinement_where_the_weak_channel_holds_no_clicks(seed):
    """On noise alone the summed envelope stays below its threshold: None (the statistic's
    delay is kept)."""
    x, ref = _train(0.0, 0.3, 0.0, seed=seed)
    assert refine_train_delay(x, FS, (0, 1), ref, 0.3, 0.0, T_C) is None


@pytest.mark.parametrize("refine", [True, False])
def test_train_tdoas_refines_its_delays_on_the_waveforms(refine):
    """Through :func:`fusion.pipelines.clicks.train_tdoas.train_tdoas` (no validated TDOA:
    channel 0's detections are the reference train; channel 2 holds noise only): the weak
    channel's TDOA is within 1 us with a sigma of about 1 us when refined; read off the
    statistic (``waveform_refine=False``) its sigma is several us."""
    from fusion.clicks.detect import ClickDetector
    from fusion.geometry import SensorArray
    from fusion.pipelines.clicks.train_tdoas import train_tdoas

    tau, rate = 0.61237, 4e-4
    x2, _ = _train(1.5, tau, rate, seed=5)
    x = np.concatenate([x2, np.random.default_rng(9).standard_normal((x2.shape[0], 1))], axis=1)
    det = ClickDetector(false_alarms_per_s=0.5)
    inside = det.detect(x, FS)
    sensors = SensorArray(positions=np.array([[0.0, 0, -1000], [1500.0, 0, -1000],
                                              [0.0, 1500, -1000]]))
    out = train_tdoas([], inside, detector=det, sensors=sensors, audio=x, audio_t0_s=0.0,
                      fs=FS, t_c_s=T_C, max_rate=1.6e-3, waveform_refine=refine)
    assert [d.pair for d in out] == [(0, 1)]
    d = out[0]
    assert abs(-d.tau_s - tau) < (1e-6 if refine else 10e-6)
    assert (d.sigma_s < 2e-6) if refine else (d.sigma_s > 4e-6)
