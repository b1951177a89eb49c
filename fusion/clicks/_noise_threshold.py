"""The detection threshold of :class:`fusion.clicks.detect.ClickDetector` at a false-alarm rate.

The band statistic is normalised by a per-bin background, so in Gaussian noise its law depends
only on the detector itself: the replica, the band, the STFT and the background estimate. The
threshold that passes a given number of noise clicks per second is therefore measured once per
sample rate on the detector's own output for seeded white Gaussian noise (`duration_s` of one
channel): the level between the ``n``-th and ``(n + 1)``-th strongest noise clicks, ``n`` the
rate times the duration. A narrow band (fewer, more correlated bins) gets a higher threshold than
a wide one for the same rate, which a fixed threshold does not (``docs/localization.md``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["NOISE_DURATION_S", "NOISE_SEED", "noise_threshold"]

#: Seconds of one channel of white Gaussian noise the threshold is measured on.
NOISE_DURATION_S = 30.0
#: Seed of that noise (the threshold is a property of the detector, not of a draw).
NOISE_SEED = 20261203


def noise_threshold(detector: Any, fs: float, false_alarms_per_s: float, *,
                    duration_s: float = NOISE_DURATION_S, seed: int = NOISE_SEED) -> float:
    """Threshold at which `detector` (a :class:`~fusion.clicks.detect.ClickDetector`)
    finds `false_alarms_per_s` clicks per second in white Gaussian noise sampled at `fs`
    (its centre-frequency and ringing screens applied)."""
    n_false = int(np.ceil(false_alarms_per_s * duration_s))
    if n_false < 1:
        raise ValueError(f"false_alarms_per_s * duration_s must reach 1, got "
                         f"{false_alarms_per_s} * {duration_s}")
    x = np.random.default_rng(seed).standard_normal((int(round(duration_s * fs)), 1))
    level = 3.0
    while True:
        probe = detector._copy(threshold=level, false_alarms_per_s=None, echo_window_s=None,
                               _noise_thresholds={})
        power = np.sort(probe.detect(x, fs)[0].power)[::-1]
        if power.size > n_false or level < 1.05:
            break
        level = 1.0 + 0.5 * (level - 1.0)
    if power.size <= n_false:
        return float(level)
    return float(0.5 * (power[n_false - 1] + power[n_false]))
