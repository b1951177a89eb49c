"""Demo part ``smoothing``: tracks from unlabeled bearing detections through crossings.

Four seeded bearing tracks with two crossing pairs, missed detections and clutter
(:func:`fusion.simulate.bearings.simulate_bearings`) are formed into tracks and smoothed jointly
by :class:`fusion.passive.smoothing.MultiTrackSmoother`; identities through the true crossings
are scored by :func:`fusion.metrics.crossings.crossing_outcomes`.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from fusion.geometry import wrap_angle
from fusion.io import write_table
from fusion.metrics.crossings import crossing_outcomes
from fusion.passive.smoothing import MultiTrackSmoother
from fusion.report.figures import bearing_band, ensure_visible
from fusion.simulate.bearings import simulate_bearings

__all__ = ["run_demo"]

logger = logging.getLogger(__name__)


def run_demo(out_dir: Path, *, seed: int) -> dict:
    """Demo part: tracks from unlabeled detections through crossings, bearing-time figure.

    Writes ``smoothed.csv`` and ``smoothing.png`` (raw detections, smoothed tracks with 1-sigma
    bands, true crossings, and the crossing alerts of :mod:`fusion.passive.crossing` when
    present) into `out_dir`; returns tracks, swaps, lost tracks and RMSE.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    sc = simulate_bearings(seed=seed, n_tracks=4, duration_s=1200.0, n_crossing_pairs=2,
                           n_wrap_crossings=0, n_near_miss_pairs=0, p_detect=0.9,
                           clutter_rate=0.2)
    sigma = np.radians(sc.noise_deg)
    res = MultiTrackSmoother(sigma_bearing=sigma, q=1e-9,
                             clutter_density=0.2 / (2 * np.pi)).run(
        sc.time, np.radians(sc.bearing_deg))
    cr = [(c.track_a, c.track_b, c.t_cross) for c in sc.crossings]
    outcomes = crossing_outcomes(sc.track_id, res.labels, sc.time, cr,
                                 guard_s=15 * sc.sample_period_s,
                                 window_s=20 * sc.sample_period_s)
    cols = {
        "track_id": np.concatenate([np.full(len(tr), tr.track_id) for tr in res.tracks]),
        "time": np.concatenate([tr.times for tr in res.tracks]),
        "bearing_deg": np.concatenate([np.mod(np.degrees(tr.bearing), 360) for tr in res.tracks]),
        "bearing_rate_deg_per_min": np.concatenate([np.degrees(tr.rate) * 60 for tr in res.tracks]),
        "sigma_bearing_deg": np.concatenate([np.degrees(tr.sigma_bearing) for tr in res.tracks]),
    }
    write_table(out_dir / "smoothed.csv", cols)
    fig, ax = plt.subplots(figsize=(7, 8))
    ax.plot(sc.bearing_deg, sc.time, ".", color="0.6", ms=2, label="detections (unlabeled)")
    for tr in res.tracks:
        bearing_band(ax, tr.times, np.mod(np.degrees(tr.bearing), 360),
                     np.degrees(tr.sigma_bearing), lw=1.2, label=f"track {tr.track_id}")
    for a, _b, tc in cr:
        k = int(np.argmin(np.abs(sc.truth_time - tc)))
        ax.plot(sc.truth_bearing_deg[a, k], tc, "kx", ms=8)
    n_alerts = 0
    try:
        from fusion.passive.crossing import detect_crossings

        alerts = detect_crossings(cols)
        det = [al for al in alerts if str(al.kind) == "detected"]
        n_alerts = len(alerts)
        for al in det:
            sel = (cols["track_id"] == al.track_a)
            if sel.any():
                ax.axhline(al.t_cross, color="r", lw=0.5, alpha=0.4)
    except ImportError:  # the crossing module is optional for this figure
        logger.info("fusion.passive.crossing not available; no alerts drawn")
    ax.set_xlabel("bearing (deg)")
    ax.set_ylabel("time (s)")
    ax.invert_yaxis()
    ax.set_title("Smoothed tracks (1-sigma bands); x: true crossings; red: crossing alerts")
    ax.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    ensure_visible(fig)
    fig.savefig(out_dir / "smoothing.png", dpi=110)
    plt.close(fig)
    rmse = []
    for tr in res.tracks:
        k = np.searchsorted(sc.truth_time, tr.times)
        rmse.append(min(float(np.degrees(np.sqrt(np.mean(wrap_angle(
            tr.bearing - np.radians(sc.truth_bearing_deg[m, k])) ** 2))))
            for m in range(sc.n_tracks)))
    return {"tracks": len(res.tracks), "true_tracks": sc.n_tracks, "crossings": len(cr),
            "swaps": int(np.sum(outcomes == "swap")), "lost": int(np.sum(outcomes == "lost")),
            "crossing_alerts": n_alerts,
            "median_track_rmse_deg": round(float(np.median(rmse)), 4),
            "raw_noise_deg": sc.noise_deg}
