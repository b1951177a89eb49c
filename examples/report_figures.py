"""Figures of command outputs: simulate bearing tracks, smooth them, find crossings, draw all three.

Writes a seeded bearing-time scenario (``bearings.csv``), runs ``fusion smooth`` and ``fusion
crossings`` on it exactly as on the command line, then ``fusion report`` on each output:
``smoothed.png`` (tracks with 1-sigma bands, the raw bearings, the alerts), ``crossings.png`` and
``crossings_bearing_time.png``. Prints the figures written as JSON.

    python examples/report_figures.py [--seed 1] [--tracks 4] [--minutes 20] [--out report-demo]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from fusion.cli import main as fusion
from fusion.io import write_table
from fusion.simulate.bearings import simulate_bearings


def main(argv: list[str] | None = None) -> dict:
    """Run the example; returns {"alerts": n, "figures": [paths]}."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--tracks", type=int, default=4)
    ap.add_argument("--minutes", type=float, default=20.0)
    ap.add_argument("--out", type=Path, default=Path("report-demo"))
    args = ap.parse_args(argv)

    out = args.out
    sc = simulate_bearings(seed=args.seed, n_tracks=args.tracks, duration_s=60.0 * args.minutes,
                           n_crossing_pairs=1, n_wrap_crossings=0, n_near_miss_pairs=0)
    bearings = write_table(out / "bearings.csv", {"track_id": sc.track_id, "time": sc.time,
                                                  "bearing_deg": sc.bearing_deg})
    smoothed, alerts = out / "smoothed.csv", out / "alerts.csv"
    steps = [
        ["smooth", "--bearings", bearings, "--out", smoothed],
        ["crossings", "--bearings", bearings, "--out", alerts],
        ["report", smoothed, "--bearings", bearings, "--alerts", alerts, "--out", out / "figures"],
        ["report", alerts, "--bearings", bearings, "--out", out / "figures"],
    ]
    for step in steps:
        print("fusion", *step)
        if fusion([str(a) for a in step]) != 0:
            raise SystemExit(f"fusion {step[0]} failed")
    n_alerts = sum(1 for _ in alerts.open(encoding="utf-8")) - 1
    summary = {"alerts": n_alerts,
               "figures": sorted(str(p) for p in (out / "figures").glob("*.png"))}
    print(json.dumps(summary, indent=1))
    return summary


if __name__ == "__main__":
    main()
