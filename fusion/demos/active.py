"""Demo part ``active``: fuzzy association against Kalman-only tracking of a multistatic scenario."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fusion.io import write_table
from fusion.metrics.multistatic import score_tracks
from fusion.simulate.multistatic import simulate_multistatic, write_scenario


def run_demo(out_dir: Path, *, seed: int) -> dict:
    """Demo part ``active``: fuzzy vs Kalman-only tracking of one 22-ping scenario.

    Writes ``detections.csv``, ``tracks_fuzzy.csv``, ``tracks_kalman.csv`` and
    ``plan_view.png`` (detections by origin, clutter-map hotspots, confirmed tracks and truth).

    Returns
    -------
    dict
        Coverage and false-track counts of both modes, detections per ping.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fusion.active.tracker import Tracker

    out = Path(out_dir)
    paths = write_scenario(out, seed=seed)
    sc = simulate_multistatic(seed=seed)
    summary: dict = {"detections_per_ping": round(len(sc.detections) / len(sc.truth), 2)}
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.5), sharex=True, sharey=True)
    d = sc.detections
    for ax, mode in zip(axes, ("fuzzy", "kalman"), strict=True):
        tracker = Tracker(mode=mode)
        res = tracker.run(d)
        cols = res.columns()
        write_table(out / f"tracks_{mode}.csv", cols)
        s = score_tracks(cols, sc.truth)
        summary[f"{mode}_coverage"] = round(s.coverage, 3)
        summary[f"{mode}_false_tracks"] = s.false_tracks
        for origin, style in (("clutter", dict(c="0.7", s=6)), ("hotspot", dict(c="tab:orange", s=8)),
                              ("target", dict(c="tab:blue", s=10))):
            m = d["origin"] == origin
            ax.scatter(d["x"][m], d["y"][m], label=f"{origin} detections", **style)
        ax.plot(sc.truth["x"], sc.truth["y"], "k-", lw=2, label="target truth")
        hs = res.pings[-1].hotspots
        if len(hs):
            ax.scatter(hs[:, 0], hs[:, 1], marker="s", facecolors="none", edgecolors="red", s=60,
                       label="clutter-map hotspots")
        conf = cols["status"] == "confirmed"
        for i, tid in enumerate(np.unique(cols["track_id"][conf])):
            m = conf & (cols["track_id"] == tid)
            ax.plot(cols["x"][m], cols["y"][m], "-", color="tab:green",
                    lw=1.5, label="confirmed tracks" if i == 0 else None)
        ax.plot(*sc.source, "k*", ms=14, label="source")
        ax.plot(sc.receivers[:, 0], sc.receivers[:, 1], "k^", ms=9, label="receivers")
        ax.set_title(f"{mode}: coverage {s.coverage:.0%}, false tracks {s.false_tracks}")
        ax.set_xlabel("x east (m)")
        ax.set_aspect("equal")
    axes[0].set_ylabel("y north (m)")
    axes[0].legend(loc="lower left", fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "plan_view.png", dpi=110)
    plt.close(fig)
    summary["files"] = [p.name for p in paths] + ["plan_view.png"]
    return summary
