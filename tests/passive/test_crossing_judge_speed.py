"""The verdicts of the ladder's lower windows come from fewer terms (issue 19, 2026-12-03
evening: the 1,000-track update): ``judge_pairs(only_resolved=True)`` below the allowance gate
skips the allowances, which only widen, and must give the verdicts of the full judgement."""

from __future__ import annotations

import numpy as np

from fusion.passive.crossing import CrossingDetector, crossing_settings_from_steps
from fusion.passive.crossing.judge import judge_pairs


def _detector(n_tracks: int = 150, seed: int = 3) -> tuple[CrossingDetector, np.ndarray, float]:
    """Default detector after the longest window filled: straight tracks plus a few that turn
    (so the manoeuvre and curvature terms are not zero)."""
    rng = np.random.default_rng(seed)
    K = 4.0
    st = crossing_settings_from_steps(K, 3600.0)
    det = CrossingDetector(**st.detector_options())
    b0 = rng.uniform(0.0, 360.0, n_tracks)
    rate = rng.normal(0.0, 3.0 / 60.0, n_tracks)
    turn = np.where(rng.random(n_tracks) < 0.3, rng.normal(0.0, 1e-4, n_tracks), 0.0)
    ids = np.arange(n_tracks)
    n = st.J * 2 ** (st.n_windows - 1) + 5
    t = 0.0
    for i in range(n):
        t = K * i
        det.step(t, ids, b0 + rate * t + turn * t * t + rng.normal(0.0, 0.5, n_tracks))
    return det, ids, t


def test_lower_window_verdicts_unchanged_by_the_shortcut():
    det, ids, t = _detector()
    ia, ib = np.triu_indices(ids.size, k=1)
    n_checked = 0
    for level, (fit, J) in enumerate(zip(det.fits, det.windows, strict=True)):
        span = J * det.K
        if det.allowance_gate_level is not None and level >= det.allowance_gate_level:
            break
        model = det._models(fit, ids, t, curves=level < det.curve_windows)
        back = min(span, det.horizon_s, det.lead_windows * span)
        lead = min(det.horizon_s, det.lead_windows * span)
        full = judge_pairs(det, model, ia, ib, back_s=back, reach_s=lead, span_s=span)
        fast = judge_pairs(det, model, ia, ib, back_s=back, reach_s=lead, span_s=span,
                           only_resolved=True)
        np.testing.assert_array_equal(fast[3], full[3])
        n_checked += int(full[3].sum())
    assert n_checked > 100  # resolved pairs were compared, not only unresolved ones
