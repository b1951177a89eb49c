"""Demo part ``passive``: the passive pipeline on a simulated multi-target cube, with a figure.

Six narrowband lines over 400 one-second scans (two crossing pairs, one fading line) are clicked at
scan 59; the pipeline (:class:`fusion.pipelines.passive.PassivePipeline`) tracks them and its
smoothed tracks, TQI states, crossing alerts and resolved crossings are drawn on a bearing-time
figure over the truth.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fusion.io import atomic_output, write_table
from fusion.report.figures import state_legend, tqi_markers

__all__ = ["run_demo"]


def run_demo(out_dir: Path, *, seed: int) -> dict:
    """Run the passive pipeline on a seeded scenario; write tracks, alerts and ``passive.png``.

    A demo part (:mod:`fusion.demos`: `out_dir`, `seed`).

    Returns
    -------
    dict
        Measured numbers: tracks, crossings kept/swapped, bearing RMSE against the truth (deg),
        delay of the fading track's end after its line fell below 0 dB (s), alerts, episodes
        resolved by the multi-track graph and by nearest assignment.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fusion.metrics.tracks import ScoredTrack, score_tracks
    from fusion.passive.acquisition import Acquisition
    from fusion.passive.crossing import CrossingDetector
    from fusion.passive.quality import TrackQualityIndicator
    from fusion.pipelines.passive import PassivePipeline
    from fusion.pipelines.passive.types import Click
    from fusion.simulate.passive import simulate_passive

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sc = simulate_passive(seed=seed)
    pipe = PassivePipeline(acquisition=Acquisition(), tqi=TrackQualityIndicator(),
                           crossing=CrossingDetector(J=12, K=5.0))
    res = pipe.run(sc.cube, [Click(b, f, t) for b, f, t in sc.clicks])
    write_table(out_dir / "tracks.csv", res.track_columns())
    write_table(out_dir / "alerts.csv", res.alert_columns())
    score = score_tracks([ScoredTrack(t.track_id, t.time, t.bearing_deg,
                                      t.end.time if t.end else math.inf) for t in res.tracks], sc)

    fig, ax = plt.subplots(figsize=(9, 6.5))
    for i in range(sc.n_targets):
        on = np.isfinite(sc.snr_db[:, i])
        ax.plot(sc.bearing_deg[on, i], sc.time[on], "k--", lw=0.7, alpha=0.6)
    for tr in res.tracks:  # colour: the track; marker: its TQI state
        colour = f"C{tr.track_id % 10}"
        ax.plot(tr.bearing_deg, tr.time, "-", lw=0.6, color=colour, alpha=0.6)
        tqi_markers(ax, tr.bearing_deg, tr.time, tr.tqi, color=colour, ms=2.5)
        ax.annotate(str(tr.track_id), (tr.bearing_deg[-1], tr.time[-1]), fontsize=8,
                    color=colour, xytext=(3, -3), textcoords="offset points")
        if tr.end is not None:
            ax.plot(tr.bearing_deg[-1], tr.time[-1], "*", color="k", ms=9)
    by_id = {t.track_id: t for t in res.tracks}
    for a in res.alerts:
        tr = by_id[a.track_a]
        k = int(np.argmin(np.abs(tr.time - a.time)))  # on track a when the alert was raised
        style = ("v", "k") if a.kind == "predicted" else ("D", "k")
        ax.plot(tr.bearing_deg[k], a.time, style[0], color=style[1], mfc="none", ms=8)
    for r in res.resolutions:
        for tid in r.tracks:
            tr = by_id[tid]
            k = (tr.time >= r.t_start) & (tr.time <= r.t_end)
            ax.plot(tr.bearing_deg[k], tr.time[k], "-", color="0.5", lw=6, alpha=0.25)
    state_legend(ax)
    ax.plot([], [], "k--", lw=0.7, label="truth")
    ax.plot([], [], "v", color="k", mfc="none", label="crossing predicted (alert time)")
    ax.plot([], [], "D", color="k", mfc="none", label="crossing detected (alert time)")
    ax.plot([], [], "-", color="0.5", lw=6, alpha=0.25, label="crossing episode")
    ax.plot([], [], "*", color="k", label="track ended (lost)")
    lo, hi = np.nanmin(sc.bearing_deg), np.nanmax(sc.bearing_deg)
    ax.set_xlim(max(0.0, lo - 5.0), min(180.0, hi + 5.0))
    ax.set_xlabel("bearing from the forward axis, deg")
    ax.set_ylabel("time, s")
    ax.invert_yaxis()
    ax.set_title(f"Passive pipeline: {len(res.tracks)} tracks, crossings "
                 f"{score.outcomes.tolist()} (seed {seed})")
    ax.legend(fontsize=7, loc="lower left", ncol=2)
    fig.tight_layout()
    with atomic_output(out_dir / "passive.png") as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    delays = score.lost_delay_s[np.isfinite(score.lost_delay_s)]
    return {
        "tracks": len(res.tracks),
        "true_crossings": int(score.outcomes.size),
        "kept": int(np.sum(score.outcomes == "kept")),
        "swaps": score.n_swaps,
        "rmse_deg": round(score.rmse_deg, 3),
        "fading_end_delay_s": round(float(delays[0]), 1) if delays.size else None,
        "tracks_ended_early": score.n_early_ends,
        "alerts": len(res.alerts),
        "episodes_multitrack": sum(r.method == "multitrack" for r in res.resolutions),
        "episodes_nearest": sum(r.method == "nearest" for r in res.resolutions),
    }
