"""Benchmark of bearings-only TMA: accuracy, consistency, observability warnings, speed.

Seeded scenarios of :func:`fusion.simulate.tma.simulate_tma` (own-ship two-leg manoeuvre, a
constant-velocity target at 3-8 km, 1 deg bearings every 20 s for 30 min). Measures, per target
model (``single`` and ``chain``):

* the median and 90th percentile of the relative range error at the final time;
* the fraction of runs whose NEES lies inside the two-sided 95 % chi-square interval, both for the
  4-dof state ``[x, y, vx, vy]`` and the 2-dof position, at the final time;
* the time per run.

The no-manoeuvre case (same scenarios, straight own-ship) reports the fraction of runs that
raised the unobservability warning. With ``--realdata DIR`` (the Autoferry folder) it also runs
TMA on the ferry's real track with bearings to the GNSS-tracked boats (GNSS-derived bearings plus
Gaussian noise). Prints one JSON line on stdout; human lines on stderr.

Usage::

    python benchmarks/bench_tma.py --runs 50 --seed 1000 --realdata ../shared/realdata/autoferry_sensor_fusion
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

from fusion.metrics.localization import nees, nees_interval
from fusion.passive.tma import BearingsOnlyTMA, OwnshipTrack
from fusion.simulate.tma import simulate_tma


def run_simulated(runs: int, seed0: int, motion: str, manoeuvre: bool) -> dict:
    """Run `runs` seeded scenarios; return the summary numbers."""
    lo4, hi4 = nees_interval(4, level=0.95)
    lo2, hi2 = nees_interval(2, level=0.95)
    rel_err, in4, in2, warned, secs = [], [], [], [], []
    for seed in range(seed0, seed0 + runs):
        sc = simulate_tma(seed=seed, manoeuvre=manoeuvre)
        tma = BearingsOnlyTMA(bearing_sigma_deg=sc.bearing_sigma_deg, motion=motion)
        t0 = time.perf_counter()
        res = tma.estimate(sc.times, sc.bearings, OwnshipTrack(sc.ownship_times, sc.ownship_xy))
        secs.append(time.perf_counter() - t0)
        rel_err.append(abs(res.range[-1] - sc.true_range[-1]) / sc.true_range[-1])
        e = res.states[-1] - sc.truth[-1]
        n4 = nees(e, res.covariances[-1])
        n2 = nees(e[:2], res.covariances[-1, :2, :2])
        in4.append(lo4 <= n4 <= hi4)
        in2.append(lo2 <= n2 <= hi2)
        warned.append(not res.observable)
    rel = np.array(rel_err)
    return {
        "runs": runs,
        "median_range_err_pct": round(100 * float(np.median(rel)), 3),
        "p90_range_err_pct": round(100 * float(np.percentile(rel, 90)), 3),
        "nees4_in_95pct_frac": round(float(np.mean(in4)), 3),
        "nees2_pos_in_95pct_frac": round(float(np.mean(in2)), 3),
        "warned_frac": round(float(np.mean(warned)), 3),
        "mean_s_per_run": round(float(np.mean(secs)), 4),
    }


def run_realdata(folder: Path, *, sigma_deg: float, seed: int) -> list[dict]:
    """TMA on the Autoferry ferry track, GNSS-derived bearings (1 Hz) + noise, per target."""
    from fusion.datasets.autoferry import load_autoferry
    from fusion.io import read_table

    rng = np.random.default_rng(seed)
    out = []
    for scen in ("scenario2", "scenario3", "scenario16", "scenario17", "scenario5"):
        rec = load_autoferry(folder / scen)
        own = rec.ownship()
        track = OwnshipTrack(own["time"], np.column_stack([own["x"], own["y"]]))
        d = read_table(folder / scen / "derived_true_bearings_from_ownship.csv",
                       required=("track_id", "time", "bearing_deg", "range_m"))
        for tid in np.unique(d["track_id"]).astype(int):
            m = d["track_id"] == tid
            t, b, r = d["time"][m], np.unwrap(np.radians(d["bearing_deg"][m])), d["range_m"][m]
            grid = np.arange(max(t[0], own["time"][0]), min(t[-1], own["time"][-1]), 1.0)
            z = np.interp(grid, t, b) + rng.normal(0.0, np.radians(sigma_deg), grid.size)
            r_end = float(np.interp(grid[-1], t, r))
            row = {"scenario": scen, "target": int(tid), "n": int(grid.size),
                   "true_final_range_m": round(r_end, 1)}
            for motion, q in (("single", 1e-6), ("chain", 1e-2)):
                res = BearingsOnlyTMA(bearing_sigma_deg=sigma_deg, motion=motion, q=q).estimate(
                    grid, z, track
                )
                row[f"{motion}_range_err_pct"] = round(100 * float(res.range[-1] - r_end) / r_end, 1)
                row[f"{motion}_observable"] = bool(res.observable)
            row["ownship_manoeuvre_m"] = round(float(res.ownship_manoeuvre_m), 1)
            out.append(row)
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print one JSON line."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=50, help="seeded runs per case (default 50)")
    p.add_argument("--seed", type=int, default=1000, help="first seed (default 1000)")
    p.add_argument("--realdata", type=Path, default=None, help="Autoferry folder (optional)")
    p.add_argument("--real-sigma-deg", type=float, default=0.5,
                   help="noise added to the GNSS-derived bearings, deg (default 0.5)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)  # the no-manoeuvre case warns on every run
    result = {"benchmark": "tma", "date": "2026-11-22"}
    for motion in ("single", "chain"):
        result[f"manoeuvre_{motion}"] = run_simulated(args.runs, args.seed, motion, True)
        print(f"manoeuvre {motion}: {result[f'manoeuvre_{motion}']}", file=sys.stderr)
    result["no_manoeuvre_single"] = run_simulated(args.runs, args.seed, "single", False)
    print(f"no manoeuvre: {result['no_manoeuvre_single']}", file=sys.stderr)
    if args.realdata is not None:
        result["autoferry"] = run_realdata(args.realdata, sigma_deg=args.real_sigma_deg,
                                           seed=args.seed)
        for row in result["autoferry"]:
            print(f"autoferry: {row}", file=sys.stderr)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
