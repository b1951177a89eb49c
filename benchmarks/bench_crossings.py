"""Benchmark of bearing-track crossing prediction and detection.

Measures, on seeded simulated scenarios (``fusion.simulate.bearings``):

- the fraction of true crossings predicted at least one sample period K before the crossing
  (target >= 0.95) and detected within J K after it (target >= 0.95), for the crossings built
  into the scenarios (bearing-rate difference >= 1.5 deg/min at the crossing) and, separately,
  for every crossing that happens between any two tracks (including grazing ones);
- the fraction of never-crossing pairs with any alert (target <= 0.05), overall and for the
  near-miss and parallel pairs alone;
- the wall and CPU time of one detector update with 1,000 tracks (all 499,500 pairs;
  target <= 50 ms);
- on recorded data (Autoferry true-bearing records, scenarios 2, 3, 5, 16, 17), the alerts
  against the crossings of the recorded bearings.

Prints one JSON line on stdout (human-readable lines on stderr)::

    python benchmarks/bench_crossings.py [--seeds 40] [--tracks 10] [--J 10] [--K 10]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from _realdata import AUTOFERRY

from fusion.geometry import wrap_deg
from fusion.io import read_table
from fusion.passive.crossing import CrossingDetector, detect_crossings, score_alerts
from fusion.simulate.bearings import simulate_bearings

ROOT = Path(__file__).resolve().parents[1]
REAL_DIRS = (
    AUTOFERRY,
    ROOT / "tests" / "data" / "autoferry",
)
REAL_TRUTH = {2: 1, 3: 2, 5: 0, 16: 0, 17: 0}


def log(msg: str) -> None:
    print(msg, file=sys.stderr)


def simulated(seeds: int, n_tracks: int, J: int, K: float, noise_deg: float) -> dict:
    """Score the detector over `seeds` scenarios."""
    planned = dict(n=0, pred=0, det=0, delays=[])
    every = dict(n=0, pred=0, det=0)
    ncp = dict(n=0, false=0, spurious=0)
    near = dict(n=0, false=0)
    par = dict(n=0, false=0)
    for seed in range(seeds):
        sc = simulate_bearings(
            seed=seed, n_tracks=n_tracks, sample_period_s=K, noise_deg=noise_deg,
            n_crossing_pairs=3, n_wrap_crossings=2, n_near_miss_pairs=1, n_parallel_pairs=1,
        )
        alerts = detect_crossings(
            {"track_id": sc.track_id, "time": sc.time, "bearing_deg": sc.bearing_deg}, J=J, K=K
        )
        t0, t1 = float(sc.truth_time[0]), float(sc.truth_time[-1])
        s_pl = score_alerts(alerts, list(sc.planned_crossings), [], J=J, K=K,
                            t_start=t0, t_end=t1)
        s_all = score_alerts(alerts, list(sc.crossings), list(sc.non_crossing_pairs),
                             J=J, K=K, t_start=t0, t_end=t1)
        planned["n"] += s_pl.n_crossings
        planned["pred"] += s_pl.n_predicted_ahead
        planned["det"] += s_pl.n_detected
        planned["delays"] += s_pl.detection_delay_s.tolist()
        every["n"] += s_all.n_crossings
        every["pred"] += s_all.n_predicted_ahead
        every["det"] += s_all.n_detected
        ncp["n"] += s_all.n_non_crossing_pairs
        ncp["false"] += s_all.n_false_pairs
        ncp["spurious"] += s_all.n_spurious_alerts
        alerted = {(a.track_a, a.track_b) for a in alerts}
        nc = set(sc.non_crossing_pairs)
        for group, pairs in ((near, sc.near_miss_pairs), (par, sc.parallel_pairs)):
            for p in pairs:
                if p in nc:
                    group["n"] += 1
                    group["false"] += int(p in alerted)
    frac = lambda a, b: round(a / b, 4) if b else None  # noqa: E731
    return {
        "planned_crossings": planned["n"],
        "planned_predicted_ahead_fraction": frac(planned["pred"], planned["n"]),
        "planned_detected_fraction": frac(planned["det"], planned["n"]),
        "planned_detection_delay_median_s": round(float(np.median(planned["delays"])), 2)
        if planned["delays"] else None,
        "all_crossings": every["n"],
        "all_predicted_ahead_fraction": frac(every["pred"], every["n"]),
        "all_detected_fraction": frac(every["det"], every["n"]),
        "non_crossing_pairs": ncp["n"],
        "false_alert_pair_fraction": frac(ncp["false"], ncp["n"]),
        "near_miss_false_fraction": frac(near["false"], near["n"]),
        "parallel_false_fraction": frac(par["false"], par["n"]),
        "spurious_alerts_on_crossing_pairs": ncp["spurious"],
    }


def timing(n_tracks: int, J: int, K: float, repeats: int) -> dict:
    """Median wall time of one update of `n_tracks` tracks (all pairs)."""
    rng = np.random.default_rng(12345)
    b0 = rng.uniform(0.0, 360.0, n_tracks)
    rate = rng.normal(0.0, 3.0 / 60.0, n_tracks)  # deg/s, sd 3 deg/min
    ids = np.arange(n_tracks)
    det = CrossingDetector(J=J, K=K)

    def bearings(i: int) -> np.ndarray:
        return b0 + rate * K * i + rng.normal(0.0, 0.5, n_tracks)

    for i in range(J):
        det.step(K * i, ids, bearings(i))
    times, cpu, n_alerts = [], [], []
    for i in range(J, J + repeats):
        b = bearings(i)
        t0, c0 = time.perf_counter(), time.process_time()
        alerts = det.step(K * i, ids, b)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        n_alerts.append(len(alerts))
    return {
        "update_tracks": n_tracks,
        "update_pairs": n_tracks * (n_tracks - 1) // 2,
        "update_ms_median": round(1e3 * float(np.median(times)), 2),
        "update_ms_min": round(1e3 * float(np.min(times)), 2),
        "update_cpu_ms_median": round(1e3 * float(np.median(cpu)), 2),
        "update_alerts_mean": round(float(np.mean(n_alerts)), 1),
    }


def _true_crossings(table, step: float = 0.01) -> list[float]:
    """Crossing times of the recorded true bearings of tracks 1 and 2 (interpolated)."""
    tid, t, b = table["track_id"], table["time"], table["bearing_deg"]
    ids = np.unique(tid)
    lo = max(t[tid == k].min() for k in ids)
    hi = min(t[tid == k].max() for k in ids)
    grid = np.arange(lo, hi, step)
    u = []
    for k in ids[:2]:
        m = tid == k
        o = np.argsort(t[m])
        u.append(np.interp(grid, t[m][o], np.degrees(np.unwrap(np.radians(b[m][o])))))
    d = wrap_deg(u[1] - u[0])
    s = np.flatnonzero((np.sign(d[:-1]) != np.sign(d[1:])) & (np.abs(d[:-1]) < 90))
    return [float(grid[i] - d[i] * step / (d[i + 1] - d[i])) for i in s]


def real(J: int, K: float) -> dict:
    """Alerts on the Autoferry true-bearing records."""
    out: dict = {}
    for root in REAL_DIRS:
        if root.exists():
            break
    else:
        return {"real_data": "not found"}
    for s, n_true in REAL_TRUTH.items():
        full = root / f"scenario{s}" / "derived_true_bearings_from_ownship.csv"
        path = full if full.exists() else root / f"scenario{s}_true_bearings.csv"
        table = read_table(path, required=("track_id", "time", "bearing_deg"), integer=("track_id",))
        truth = _true_crossings(table)
        alerts = detect_crossings(table, J=J, K=K)
        det = [a for a in alerts if a.kind == "detected"]
        pred = [a for a in alerts if a.kind == "predicted"]
        t_end = float(table["time"].max())
        out[f"s{s}"] = {
            "true_crossings_expected": n_true,
            "true_crossing_times_s": [round(x, 2) for x in truth],
            "detected": [[round(a.time, 2), round(a.t_cross, 2)] for a in det],
            "predicted": [[round(a.time, 2), round(a.t_cross, 2)] for a in pred],
            "predicted_beyond_record": sum(a.t_cross > t_end for a in pred),
        }
        log(f"real s{s}: truth {out[f's{s}']['true_crossing_times_s']} detected "
            f"{out[f's{s}']['detected']} predicted {out[f's{s}']['predicted']}")
    out["source"] = str(root)
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=40, help="simulated scenarios (default 40)")
    ap.add_argument("--tracks", type=int, default=10, help="tracks per scenario (default 10)")
    ap.add_argument("--J", type=int, default=10, help="window samples (default 10)")
    ap.add_argument("--K", type=float, default=10.0, help="sample period, s (default 10)")
    ap.add_argument("--noise-deg", type=float, default=0.5, help="bearing noise sd (default 0.5)")
    ap.add_argument("--update-tracks", type=int, default=1000, help="tracks in the timing")
    ap.add_argument("--repeats", type=int, default=20, help="timed updates (default 20)")
    ap.add_argument("--real-J", type=int, default=10, help="window on recorded data")
    ap.add_argument("--real-K", type=float, default=1.0, help="period on recorded data, s")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    res = {"J": args.J, "K": args.K, "noise_deg": args.noise_deg, "seeds": args.seeds,
           "tracks_per_scenario": args.tracks}
    res.update(simulated(args.seeds, args.tracks, args.J, args.K, args.noise_deg))
    log(f"simulated: {json.dumps(res)}")
    res.update(timing(args.update_tracks, args.J, args.K, args.repeats))
    log(f"timing: {res['update_ms_median']} ms median per update of {args.update_tracks} tracks")
    res["real"] = real(args.real_J, args.real_K)
    res["real_J"], res["real_K"] = args.real_J, args.real_K
    res["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(res))
    return res


if __name__ == "__main__":
    main()
