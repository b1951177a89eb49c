"""Track quality of many simulated narrowband trackers, with and without hysteresis.

Simulates tracker outputs (cell power and bearing residual per update) for tracks passing through
strong, near-threshold, manoeuvre and lost conditions, runs the track quality indicator on all of
them at once, and compares it with the single-threshold variant: how often each changes state,
and how the states line up with the true conditions.

Run::

    python examples/track_quality.py
"""

from __future__ import annotations

import numpy as np

from fusion.passive.quality import TrackQuality, TrackQualityIndicator
from fusion.simulate.amplitudes import simulate_amplitudes


def main(n_tracks: int = 20, seed: int = 7) -> dict[str, float]:
    """Simulate, run both TQI variants, print and return a summary."""
    sc = simulate_amplitudes(seed=seed, n_tracks=n_tracks)
    # one column per track: every track here has updates at the same times
    ids = np.unique(sc.track_id)
    n_updates = np.bincount(sc.track_id).max()
    amp = np.full((n_updates, ids.size), np.nan)
    res = np.full((n_updates, ids.size), np.nan)
    valid = np.zeros((n_updates, ids.size), dtype=bool)
    truth = np.full((n_updates, ids.size), "", dtype=object)
    for j, tid in enumerate(ids):
        rows = sc.track_id == tid
        m = int(rows.sum())
        amp[:m, j], res[:m, j], valid[:m, j] = sc.amplitude[rows], sc.residual_deg[rows], True
        truth[:m, j] = sc.condition[rows]

    with_h = TrackQualityIndicator().run(amp, res, valid=valid)
    single = TrackQualityIndicator(hysteresis=False).run(amp, res, valid=valid)
    lost = with_h.state == TrackQuality.LOST
    summary = {
        "tracks": float(ids.size),
        "changes_hysteresis": float(with_h.n_changes().sum()),
        "changes_single_threshold": float(single.n_changes().sum()),
        "lost_when_strong": float(np.mean(lost[valid & (truth == "strong")])),
        "lost_when_lost": float(np.mean(lost[valid & (truth == "lost")])),
    }
    for k, v in summary.items():
        print(f"{k:>26}: {v:g}")
    return summary


if __name__ == "__main__":
    main()
