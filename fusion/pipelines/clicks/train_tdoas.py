"""A window's TDOAs of weakly heard sensors from integrated click trains.

Where the validated TDOAs of a window (those of eight clicks or more) span fewer than four
sensors (no 3-D fix without more), the click train of a sensor that hears the whale well -- the
clicks of its strongest validated TDOA, or, where nothing validated, the clicks detected on the
sensor with the most of them -- is the reference; every sensor outside the validated ones gets
the detection statistic (each frame clipped at the detection threshold) summed along that train
over its pair's possible delays and drifts (:func:`fusion.clicks.train_integration.train_delay`).
A delay whose sum stands above the sum's own noise at the false-alarm probability becomes a TDOA
of the pair (``passes`` True, ``train_z`` its excess), its sigma from the peak's curvature; it
is then associated across time, like the others, before a fix may use it.
``docs/localization.md`` section 19.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from fusion.clicks.detect import ClickDetector
from fusion.clicks.train_integration import TRAIN_FALSE_ALARMS, TrainDelay, train_delay
from fusion.clicks.train_refine import refine_train_delay
from fusion.clicks.types import ChannelClicks
from fusion.clicks.window import WindowTdoa
from fusion.geometry import SensorArray

__all__ = ["TRAIN_DELAY_MARGIN_S", "TRAIN_REFINE_SIGMA_FLOOR_S", "train_tdoas"]

#: Added to the separation / sound speed bound of a pair's delay, s.
TRAIN_DELAY_MARGIN_S = 2e-3
#: Added in quadrature to a waveform-refined delay's sigma, s: on the 15-dB tuning windows
#: (seeds 0-1, 19 delays) the errors were 1.7 times the sigma from the sum's own noise alone.
TRAIN_REFINE_SIGMA_FLOOR_S = 1e-6


def _reference_trains(tdoas: Sequence[WindowTdoa], inside: Sequence[ChannelClicks],
                      min_clicks: int) -> list[tuple[int, NDArray[np.float64]]]:
    """(sensor, click times) of the reference trains: the first sensor's clicks of the
    strongest validated TDOA of each group of validated TDOAs sharing sensors; without a
    validated TDOA, the clicks of the sensor with the most detections."""
    passed = sorted((d for d in tdoas if d.passes), key=lambda d: -d.n_clicks)
    out: list[tuple[int, NDArray[np.float64]]] = []
    used: set[int] = set()
    for d in passed:
        if used & set(d.pair):
            used |= set(d.pair)
            continue
        used |= set(d.pair)
        if d.click_times_s.size >= min_clicks:
            out.append((d.pair[0], np.asarray(d.click_times_s, dtype=float)))
    if not passed and inside:
        m = int(np.argmax([c.n_clicks for c in inside]))
        if inside[m].n_clicks >= min_clicks:
            out.append((m, np.asarray(inside[m].times_s, dtype=float)))
    return out


def _as_tdoa(m: int, k: int, ref: NDArray[np.float64], dl: TrainDelay) -> WindowTdoa:
    """The pair's TDOA (``t_i - t_j``, i < j, at the window centre on sensor i's clock)."""
    if m < k:  # t_m - t_k = -(delay + r (t_m - t_c))
        pair, tau, rate, times = (m, k), -dl.delay_s, -dl.rate, ref
    else:  # t_k - t_m at t_k = t_c: delay + r (t_c - delay - t_c)
        pair, tau, rate = (k, m), dl.delay_s * (1.0 - dl.rate), dl.rate
        times = dl.times_at_weak(ref)
    return WindowTdoa(pair=pair, tau_s=float(tau), tau_coarse_s=float(tau),
                      sigma_s=dl.sigma_s, crb_s=math.nan, snr_db=math.nan, rate=float(rate),
                      scm_peak=math.nan, n_clicks=dl.n_clicks, features=np.full(4, np.nan),
                      llr=math.nan, passes=True, click_times_s=np.sort(times), t_s=dl.t_c_s,
                      train_z=dl.z)


def train_tdoas(
    tdoas: Sequence[WindowTdoa],
    inside: Sequence[ChannelClicks],
    *,
    detector: ClickDetector,
    sensors: SensorArray,
    audio: NDArray,
    audio_t0_s: float,
    fs: float,
    t_c_s: float,
    max_rate: float,
    false_alarms: float = TRAIN_FALSE_ALARMS,
    min_clicks: int = 8,
    waveform_refine: bool = True,
    band_hz: tuple[float, float] = (20e3, 46e3),
) -> list[WindowTdoa]:
    """The train-integrated TDOAs of one window (see the module notes); empty where the
    validated `tdoas` of `min_clicks` clicks or more span four sensors or more.

    `inside` are the window's detected clicks per channel, `audio` (n, sensors) covers the
    window from `audio_t0_s`, `t_c_s` is the window centre, `max_rate` the largest drift.
    With `waveform_refine` each delay found is refined on the waveforms in `band_hz`
    (:func:`fusion.clicks.train_refine.refine_train_delay`; its sigma with
    :data:`TRAIN_REFINE_SIGMA_FLOOR_S` in quadrature); where that fails the statistic's
    delay is kept.
    """
    # the sensors of validated trains of `min_clicks` or more (a partial train admitted by
    # closure support, 2-9 clicks, does not hold a sensor back from integration)
    strong = [d for d in tdoas if d.passes and d.n_clicks >= min_clicks]
    spanned = {s for d in strong for s in d.pair}
    if len(spanned) >= 4:
        return []
    trains = _reference_trains(strong, inside, min_clicks)
    if not trains:
        return []
    weak = sorted(set(range(sensors.n_sensors)) - spanned
                  - ({trains[0][0]} if not spanned else set()))
    if not weak:
        return []
    times, stat = detector.statistic(audio[:, weak], fs, t0=audio_t0_s)
    if times.size < 3:
        return []
    hop = float(times[1] - times[0])
    smooth = detector.nfft / float(fs)
    pos, c = sensors.positions, float(sensors.sound_speed)
    cap = detector.threshold_at(float(fs))  # a frame above it would be a detected click
    out: list[WindowTdoa] = []
    for m, ref in trains:
        for n, k in enumerate(weak):
            if k == m:
                continue
            bound = float(np.linalg.norm(pos[m] - pos[k])) / c + TRAIN_DELAY_MARGIN_S
            dl = train_delay(stat[n], float(times[0]), hop, ref, max_delay_s=bound,
                             t_c_s=t_c_s, max_rate=max_rate, smooth_s=smooth,
                             false_alarms=false_alarms, min_clicks=min_clicks, cap=cap)
            if dl is None:
                continue
            if waveform_refine:
                rf = refine_train_delay(audio, fs, (m, k), ref, dl.delay_s, dl.rate, t_c_s,
                                        audio_t0_s=audio_t0_s, band_hz=band_hz)
                if rf is not None:
                    dl = dataclasses.replace(
                        dl, delay_s=rf.delay_s, rate=rf.rate,
                        sigma_s=math.hypot(rf.sigma_s, TRAIN_REFINE_SIGMA_FLOOR_S))
            out.append(_as_tdoa(m, k, ref, dl))
    return out

