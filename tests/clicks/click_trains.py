"""Test-only: a strong and a weak click train in white noise on two channels."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from fusion.simulate.clicks import ClickWaveform

FS = 96_000.0


def two_channel_train(weak_amplitude: float, weak_times: Callable[[np.ndarray], np.ndarray],
                      seed: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """12 s of white noise (std 1) on two channels; ~28 clicks with jittered intervals
    (0.30-0.45 s) at amplitude 6 on channel 0 and `weak_amplitude` on channel 1 at
    ``weak_times(emit)``. Returns the audio, channel 0's and channel 1's click times."""
    rng = np.random.default_rng(seed)
    n = int(12.0 * FS)
    t = np.arange(n) / FS
    emit = 0.3 + np.cumsum(rng.uniform(0.3, 0.45, 40))
    emit = emit[emit < 11.0]
    weak = weak_times(emit)
    x = rng.standard_normal((n, 2))
    click = ClickWaveform()
    for ch, a, times in ((0, 6.0, emit), (1, weak_amplitude, weak)):
        for at in times:
            i0 = int(at * FS) - 100
            if i0 + 200 < n:
                x[i0:i0 + 200, ch] += a * click.evaluate(t[i0:i0 + 200] - at)
    return x, emit, weak
