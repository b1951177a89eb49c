"""Shared pieces of the passive tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def traffic_interval_scores():
    """``scores(seed, **options)``: the interval scores of ``fusion crossings`` with `options`
    (settings estimated as the command does) on the manoeuvring-traffic scenario `seed`."""
    from fusion.metrics.crossings import score_intervals
    from fusion.passive.crossing import crossing_settings, detect_crossings
    from fusion.simulate.bearings import simulate_traffic

    def scores(seed: int, **options):
        sc = simulate_traffic(seed=seed)
        cols = {"track_id": sc.track_id, "time": sc.time, "bearing_deg": sc.bearing_deg}
        crossings = [(c.track_a, c.track_b, c.t_cross) for c in sc.crossings]
        st = crossing_settings(sc.track_id, sc.time, **options)
        alerts = detect_crossings(cols, **st.detector_options())
        K = sc.sample_period_s
        return score_intervals(alerts, crossings, tol_s=K, lead_min_s=K)

    return scores


@pytest.fixture(scope="session")
def window_lines():
    """``fit(t, b)``: the sliding-window line statistics and windows of tracks 0..m-1 whose
    bearings (rad, shape (m, len(t))) are sampled at times `t`, one window over all of them."""
    import numpy as np

    from fusion.passive.line_fit import SlidingLineFit

    def fit(t, b):
        lines = SlidingLineFit(window=t.size)
        ids = np.arange(b.shape[0])
        for k, tk in enumerate(t):
            lines.update(ids, float(tk), b[:, k])
        return lines.stats(ids, float(t[-1])), lines.windows(ids, float(t[-1]))

    return fit
