"""Benchmark: the passive pipeline against the island chain on multi-target cubes with crossings.

Both chains see the same simulated cubes (:func:`fusion.simulate.passive.simulate_passive`:
``--targets`` narrowband lines over ``--scans`` one-second scans, ``--crossing-pairs`` pairs of
lines in one bin whose bearings cross, ``--fading`` lines that fade out) and the same operator
clicks (every line, at scan 59):

- **pipeline**: :class:`fusion.pipelines.passive.PassivePipeline` -- acquisition prior, fixed-lag
  GTSAM graph per track, TQI every update (``lost`` ends a track, ``uncertain`` widens its process
  noise), crossing detector, association-weighted multi-track EM through predicted crossings;
- **island chain**: acquisition, then :class:`fusion.passive.tracker.BearingTracker` (a Kalman
  filter) from the click scan on, the TQI run on its outputs and the track ended at the TQI's
  first ``lost``; no graph, no crossing handling.

Metrics (:func:`fusion.metrics.tracks.score_tracks`):

- identity outcome of every true crossing: ``kept``, ``swap``, ``lost`` (scored 25-65 s on each
  side of the crossing);
- bearing RMSE of each track against the target it was started on while that target is above
  0 dB per bin (pipeline: its fixed-lag smoothed and its filtered states);
- delay from a fading target's fall below 0 dB per bin to its track's end (``lost``), and tracks
  ended while their target was still audible;
- time per scan with 20 live tracks (``--timing-targets`` lines, four crossing pairs): median,
  mean, p95 and max over the scans after the click (the click scan itself, 20 acquisitions, is
  left out), wall-clock and CPU time of the process (the machine is shared: CPU time is the
  steadier figure); the island chain's is its trackers' and TQI's total time divided by the
  scans.

Tuning seeds (``--tuning-seeds``, default 100-104) were used to choose the pipeline's settings
(lag, episode width, context); the reported figures come from the report seeds (``--seeds``,
default 0-9), which played no part in that choice.

Prints one JSON line; per-seed lines go to stderr.

Usage::

    python benchmarks/bench_passive_pipeline.py                   # report seeds 0-9
    python benchmarks/bench_passive_pipeline.py --tuning          # the tuning seeds instead
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time

import numpy as np

from fusion.io import Cube
from fusion.metrics.tracks import PassiveScore, ScoredTrack, score_tracks
from fusion.passive.acquisition import Acquisition
from fusion.passive.crossing import CrossingDetector
from fusion.passive.quality import TrackQuality, TrackQualityIndicator
from fusion.passive.tracker import BearingTracker
from fusion.pipelines.passive import PassivePipeline, SmootherSettings, unit_noise_cubes
from fusion.pipelines.passive.types import Click, scans_of
from fusion.simulate.passive import PassiveScenario, random_targets, simulate_passive

CLICK_SCAN = 59
N_BINS = 32
FIRST_BIN_HZ = 296.0


def make_pipeline(a: argparse.Namespace) -> PassivePipeline:
    return PassivePipeline(acquisition=Acquisition(), tqi=TrackQualityIndicator(),
                           crossing=CrossingDetector(J=a.J, K=a.K),
                           smoother=SmootherSettings(lag_s=a.lag,
                                                     separation_lobes=a.separation_lobes))


#: How the pipeline's crossing episodes were resolved, over all seeds run: ``multitrack`` or
#: ``nearest: <why the graph's association was not used>`` (printed, never silent).
RESOLUTIONS: dict[str, int] = {}
#: Per seed run with ``--cube-scale`` or ``--normalize``: whether its cube was normalised.
NORMALIZED: list[bool] = []


def run_pipeline(sc: PassiveScenario, a: argparse.Namespace
                 ) -> tuple[list, list, list[tuple[float, float]]]:
    """Smoothed and filtered tracks of the pipeline, and the (wall, CPU) time of every step, s."""
    pipe = make_pipeline(a)
    clicks = [Click(b, f, t) for b, f, t in sc.clicks]
    steps, filtered = [], {}
    for i, scan in enumerate(scans_of(sc.cube)):
        t0, c0 = time.perf_counter(), time.process_time()
        out = pipe.step(scan, clicks=clicks if i == 0 else ())
        steps.append((time.perf_counter() - t0, time.process_time() - c0))
        for u in out.updates:
            filtered.setdefault(u.track_id, []).append((u.time, u.bearing_deg))
    res = pipe.result()
    for r in res.resolutions:
        key = r.method if r.method == "multitrack" else f"{r.method}: {r.fallback}"
        RESOLUTIONS[key] = RESOLUTIONS.get(key, 0) + 1
    # tracks are started in click order: track i is on the i-th clicked target
    target_of = [i for i in range(sc.n_targets) if np.isfinite(sc.snr_db[CLICK_SCAN, i])]
    smoothed, filt = [], []
    for tr in res.tracks:
        end = tr.end.time if tr.end is not None else float("inf")
        tg = target_of[tr.track_id]
        smoothed.append(ScoredTrack(tg, tr.time, tr.bearing_deg, end))
        f = np.array(filtered.get(tr.track_id, []), dtype=float).reshape(-1, 2)
        filt.append(ScoredTrack(tg, f[:, 0], f[:, 1], end))
    return smoothed, filt, steps


def run_island(sc: PassiveScenario) -> tuple[list[ScoredTrack], tuple[float, float]]:
    """Acquisition + Kalman bearing tracker + TQI per click; tracking (wall, CPU) time per
    scan, s."""
    c = sc.cube
    window = Cube(power=c.power[:CLICK_SCAN + 1], freqs=c.freqs, scan_period=c.scan_period,
                  aperture=c.aperture, sound_speed=c.sound_speed)
    acq, tracker, tqi = Acquisition(), BearingTracker(), TrackQualityIndicator()
    target_of = [i for i in range(sc.n_targets) if np.isfinite(sc.snr_db[CLICK_SCAN, i])]
    out, spent, cpu = [], 0.0, 0.0
    for tg, (beam, freq, _) in zip(target_of, sc.clicks, strict=True):
        res = acq.acquire(window, beam=beam, freq_hz=freq)
        t0, c0 = time.perf_counter(), time.process_time()
        h = tracker.track(c, bearing_deg=res.bearing_deg,
                          bearing_rate_deg_per_min=res.bearing_rate_deg_per_min, freq_hz=freq,
                          init_scan=CLICK_SCAN)
        state = tqi.run(h.amplitude, h.residual_deg).state[:, 0]
        spent += time.perf_counter() - t0
        cpu += time.process_time() - c0
        lost = np.flatnonzero(state == TrackQuality.LOST)
        n = lost[0] + 1 if lost.size else len(h)
        end = float(h.time[lost[0]]) if lost.size else float("inf")
        out.append(ScoredTrack(tg, h.time[:n], h.bearing_deg[:n], end))
    n = c.n_scans - CLICK_SCAN - 1
    return out, (spent / n, cpu / n)


def summary(scores: list[PassiveScore]) -> dict[str, float]:
    outcomes = np.concatenate([s.outcomes for s in scores])
    scored = outcomes[outcomes != "unscored"]
    delays = np.concatenate([s.lost_delay_s for s in scores])
    return {
        "crossings_scored": int(scored.size),
        "kept": int(np.sum(scored == "kept")),
        "swaps": int(np.sum(scored == "swap")),
        "lost_at_crossing": int(np.sum(scored == "lost")),
        "swap_rate": round(float(np.mean(scored == "swap")), 4) if scored.size else None,
        "rmse_deg": round(float(np.sqrt(np.mean([s.rmse_deg**2 for s in scores]))), 4),
        "fading_tracks_ended": int(np.sum(np.isfinite(delays))),
        "fading_targets": int(delays.size),
        "lost_delay_s_median": round(float(np.median(delays[np.isfinite(delays)])), 2)
        if np.isfinite(delays).any() else None,
        "lost_delay_s_max": round(float(np.max(delays[np.isfinite(delays)])), 2)
        if np.isfinite(delays).any() else None,
        "early_ends": int(sum(s.n_early_ends for s in scores)),
    }


def timing(a: argparse.Namespace) -> dict[str, float]:
    """ms per scan with `--timing-targets` live tracks, pipeline and island chain."""
    sc = simulate_passive(seed=a.timing_seed, n_scans=a.timing_scans, n_bins=48,
                          n_targets=a.timing_targets, n_crossing_pairs=4, n_fading=0)
    _, _, steps = run_pipeline(sc, a)
    wall, cpu = (1e3 * np.array(steps[CLICK_SCAN + 1:])).T
    _, (island_wall, island_cpu) = run_island(sc)
    out: dict[str, float] = {"live_tracks": a.timing_targets}
    for name, ms in (("wall", wall), ("cpu", cpu)):
        out[f"pipeline_{name}_ms_per_scan_median"] = round(float(np.median(ms)), 3)
        out[f"pipeline_{name}_ms_per_scan_mean"] = round(float(np.mean(ms)), 3)
        out[f"pipeline_{name}_ms_per_scan_p95"] = round(float(np.percentile(ms, 95)), 3)
        out[f"pipeline_{name}_ms_per_scan_max"] = round(float(np.max(ms)), 1)
    out["island_wall_ms_per_scan"] = round(1e3 * island_wall, 3)
    out["island_cpu_ms_per_scan"] = round(1e3 * island_cpu, 3)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(10)),
                    help="report seeds (default 0-9)")
    ap.add_argument("--tuning-seeds", type=int, nargs="+", default=list(range(100, 105)),
                    help="seeds the settings were chosen on (default 100-104)")
    ap.add_argument("--tuning", action="store_true", help="run the tuning seeds instead")
    ap.add_argument("--scans", type=int, default=400)
    ap.add_argument("--targets", type=int, default=8)
    ap.add_argument("--crossing-pairs", type=int, default=3)
    ap.add_argument("--fading", type=int, default=1)
    ap.add_argument("--snr-db", type=float, nargs=2, default=[6.0, 12.0],
                    help="range of the lines' per-bin SNRs, dB")
    ap.add_argument("--crossing-rate", type=float, nargs=2, default=[4.0, 10.0],
                    help="range of the crossing lines' bearing-rate magnitudes, deg/min")
    ap.add_argument("--J", type=int, default=12, help="crossing detector window, samples")
    ap.add_argument("--K", type=float, default=5.0, help="crossing detector period, s")
    ap.add_argument("--lag", type=float, default=SmootherSettings.lag_s,
                    help="fixed lag of the tracks' graphs, s")
    ap.add_argument("--separation-lobes", type=float, default=SmootherSettings.separation_lobes,
                    help="main lobes apart that end a crossing episode")
    ap.add_argument("--timing-targets", type=int, default=20)
    ap.add_argument("--timing-scans", type=int, default=200)
    ap.add_argument("--timing-seed", type=int, default=7)
    ap.add_argument("--no-timing", action="store_true")
    ap.add_argument("--cube-scale", type=float, default=1.0,
                    help="multiply the simulated cubes' power by this (a beamformer's own scale; "
                         "default 1: unit noise mean)")
    ap.add_argument("--normalize", choices=("auto", "yes", "no"), default="auto",
                    help="the cubes both chains read: normalised where their noise level is off "
                         "unit (auto, as `fusion passive` by default), always, or never")
    a = ap.parse_args(argv)
    seeds = a.tuning_seeds if a.tuning else a.seeds
    t_start = time.perf_counter()
    smoothed, filtered, island = [], [], []
    for seed in seeds:
        freqs = FIRST_BIN_HZ + np.arange(N_BINS)  # 1 Hz bins
        targets = random_targets(np.random.default_rng(seed), n_targets=a.targets,
                                 n_crossing_pairs=a.crossing_pairs, n_fading=a.fading,
                                 duration_s=float(a.scans), freqs=freqs, snr_db=tuple(a.snr_db),
                                 crossing_rate_deg_per_min=tuple(a.crossing_rate))
        sc = simulate_passive(seed=seed, targets=targets, n_scans=a.scans, n_bins=N_BINS,
                              first_bin_hz=FIRST_BIN_HZ)
        if a.cube_scale != 1.0 or a.normalize != "auto":
            cube = dataclasses.replace(sc.cube, power=sc.cube.power * a.cube_scale)
            (cube,), record, _ = unit_noise_cubes(
                [cube], {"auto": None, "yes": True, "no": False}[a.normalize], [f"seed {seed}"])
            NORMALIZED.append(record[f"seed {seed}"]["normalized"])
            sc = dataclasses.replace(sc, cube=cube)
        sm, fi, _ = run_pipeline(sc, a)
        isl, _ = run_island(sc)
        smoothed.append(score_tracks(sm, sc))
        filtered.append(score_tracks(fi, sc))
        island.append(score_tracks(isl, sc))
        print(f"seed {seed}: pipeline {smoothed[-1].outcomes.tolist()} rmse "
              f"{smoothed[-1].rmse_deg:.3f} delay {smoothed[-1].lost_delay_s.tolist()}; island "
              f"{island[-1].outcomes.tolist()} rmse {island[-1].rmse_deg:.3f} delay "
              f"{island[-1].lost_delay_s.tolist()}", file=sys.stderr)
    result: dict[str, object] = {
        "bench": "passive_pipeline",
        "seeds": seeds, "tuning_seeds": a.tuning_seeds, "seed_set": "tuning" if a.tuning else "report",
        "scans": a.scans, "targets": a.targets, "crossing_pairs": a.crossing_pairs,
        "fading": a.fading, "lag_s": a.lag, "separation_lobes": a.separation_lobes,
        "snr_db": a.snr_db, "crossing_rate_deg_per_min": a.crossing_rate,
        "pipeline": summary(smoothed),
        "pipeline_filtered_rmse_deg": summary(filtered)["rmse_deg"],
        "island": summary(island),
        "crossing_resolutions": dict(sorted(RESOLUTIONS.items())),
        "cube_scale": a.cube_scale, "normalize": a.normalize,
        "cubes_normalized": sum(NORMALIZED) if NORMALIZED else None,
    }
    if not a.no_timing:
        result["timing"] = timing(a)
    result["seconds"] = round(time.perf_counter() - t_start, 1)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
