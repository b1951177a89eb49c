"""Tests of partly filled windows of the ladder (issue 19, 2026-12-03 evening: slow crossings):
``CrossingDetector(window_fill=...)``, ``--window-fill``."""

from __future__ import annotations

import numpy as np
import pytest

from fusion.passive.crossing import CrossingDetector, crossing_settings_from_steps


def _first_prediction(fill: float, *, tc: float = 300.0, rate_deg_per_min: float = 1.0,
                      amp_deg: float = 0.5, K: float = 4.0):
    """First ``predicted`` alert of two tracks that start at 0 s and cross at `tc` (bearing
    rates differ by `rate_deg_per_min`; deterministic +-`amp_deg` alternating errors, so the
    lines are exact and the intervals as wide as for noise of that size)."""
    st = crossing_settings_from_steps(K, 3600.0, window_fill=fill)
    det = CrossingDetector(**st.detector_options())
    r = rate_deg_per_min / 60.0
    for i in range(int(tc / K)):
        t = i * K
        e = amp_deg * (1 if i % 2 else -1)
        b = np.array([100.0 + 0.02 * (t - tc) + e, 100.0 + (0.02 + r) * (t - tc) - e])
        for a in det.step(t, [0, 1], b):
            if a.kind.value == "predicted":
                return t, a
    return None


def test_window_need_full_shortest_then_more_than_the_fill():
    det = CrossingDetector(J=10, K=1.0, n_windows=4, window_fill=0.5)
    assert det.window_need == (10, 11, 21, 41)  # more than the window below holds
    assert CrossingDetector(J=10, K=1.0, n_windows=4).window_need == (10, 20, 40, 80)
    assert CrossingDetector(J=10, K=1.0, n_windows=3, window_fill=0.2).window_need == (10, 10, 10)
    with pytest.raises(ValueError, match="window_fill"):
        CrossingDetector(J=10, K=1.0, window_fill=0.0)
    with pytest.raises(ValueError, match="window_fill"):
        crossing_settings_from_steps(1.0, 100.0, window_fill=1.5)


def test_young_tracks_warned_earlier_with_partly_filled_windows():
    """Tracks 300 s old at their crossing (1 deg/min apart, 0.5 deg errors): the 320 s window
    that resolves them is never full before the crossing. Only full windows: the first
    prediction comes less than 10 s ahead; partly filled: more than 60 s ahead, and its
    interval holds the crossing."""
    tc = 300.0
    full = _first_prediction(1.0, tc=tc)
    part = _first_prediction(0.5, tc=tc)
    assert part is not None
    t, a = part
    assert tc - t > 60.0
    assert a.t_cross_low <= tc <= a.t_cross_high
    assert abs(a.t_cross - tc) < 10.0
    assert full is None or tc - full[0] < 10.0
