"""Benchmark of high bearing-rate acquisition: success versus per-bin SNR with exact and perturbed
operator clicks, on varied (default) or fixed cubes, and speed.

Cubes: 64 beams x 60 scans x 16 bins by default. ``--vary`` (default): every cube draws its line
frequency (150-800 Hz), bearing rate (0-40 deg/min, either sign), noise statistics (1-4 looks,
sometimes a heavy-tailed texture) and noise level (scale, slope across the band, ripple across
beams, scan jitter) from its seed (:func:`fusion.simulate.cube_varied.simulate_varied_cube`);
``--fixed``: the original cubes (300 Hz line, white unit-mean noise of ``--averages`` looks,
``--sim-lag``). The per-bin SNR runs over a grid.

Clicks: the operator clicks the beam nearest the shown bearing and the bin nearest the line at
the latest scan; with ``--perturb half`` (default) every other click is one beam AND one bin off
(random signs), ``all`` perturbs every click, ``none`` none. The acquisition is never told the
simulator's settings: its noise degrees of freedom are estimated from the cube, its lag is the
user's ``--lag`` (default 0).

A cube is a success when ``|rate error| <= max(1 deg/min, 0.25 |true rate|)`` and ``|bearing
error| <= half a beamwidth`` at the true bearing. Reported per SNR, for exact and perturbed clicks:
the success rate (the mean) and the worst decile (the 90th percentile over cubes of the larger of
the two errors divided by its tolerance: <= 1 means at least 90 % succeed); misses by cause.
Targets: success >= 0.90 at per-bin SNR >= 3 dB with the perturbed click (varied cubes); median
acquisition time <= 20 ms.

Seeds: the design was chosen on the tuning seeds (:data:`TUNING_SEEDS`, and the dev seeds 500-559
of :func:`~fusion.simulate.cube_varied.simulate_varied_cube`); the figures in RESULTS.md come from
one run on the report seed (:data:`REPORT_SEEDS`, ``--seed 9100``), drawn after the last design
change and never used to tune. Usage::

    python benchmarks/bench_acquisition.py [--cubes 240] [--seed S] [--snrs 0,3,6,9] [--fixed]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from fusion.geometry import beamwidth_cos
from fusion.passive.acquisition import Acquisition
from fusion.simulate.cube import simulate_cube
from fusion.simulate.cube_varied import simulate_varied_cube

#: Seeds the design choices were made on (``--seed``); the report uses another.
TUNING_SEEDS = (777, 31337, 2026)
#: Base seed of the reported run (``--seed``), drawn after the last design change; not for tuning.
REPORT_SEEDS = (9100,)


def half_beamwidth_deg(theta_deg: float, wavelength: float, aperture: float) -> float:
    """Half the bearing width of the main lobe around a true bearing, deg."""
    w = beamwidth_cos(wavelength, aperture)
    u = math.cos(math.radians(theta_deg))
    lo, hi = max(-1.0, u - 0.5 * w), min(1.0, u + 0.5 * w)
    return 0.5 * math.degrees(math.acos(lo) - math.acos(hi))


def draw_case(rng: np.random.Generator, n_scans: int, scan_period: float) -> tuple[float, float]:
    """Random (start bearing, rate) whose trace stays within 10..170 deg."""
    rate = float(rng.uniform(0.0, 40.0)) * (1.0 if rng.uniform() < 0.5 else -1.0)
    span = rate * (n_scans - 1) * scan_period / 60.0
    lo, hi = 10.0 - min(span, 0.0), 170.0 - max(span, 0.0)
    return float(rng.uniform(lo, hi)), rate


def perturbed_click(sc, rng: np.random.Generator) -> tuple[int, float]:
    """The exact click moved one beam and one bin (random signs), kept inside the cube."""
    cube = sc.cube
    beam = sc.click_beam + int(rng.choice([-1, 1]))
    if not 0 <= beam < cube.n_beams:
        beam = sc.click_beam - (beam - sc.click_beam)
    k = int(np.argmin(np.abs(cube.freqs - sc.click_freq))) + int(rng.choice([-1, 1]))
    if not 0 <= k < cube.n_bins:
        k = 2 * int(np.argmin(np.abs(cube.freqs - sc.click_freq))) - k
    return beam, float(cube.freqs[k])


def _summary(rows: list[dict]) -> dict:
    ok = np.array([r["ok"] for r in rows])
    err = np.array([r["norm_err"] for r in rows])
    return {"success": round(float(ok.mean()), 4) if ok.size else None,
            "worst_decile_norm_error": round(float(np.percentile(err, 90)), 3) if err.size else None,
            "n": int(ok.size)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cubes", type=int, default=240, help="number of simulated cubes")
    ap.add_argument("--seed", type=int, default=TUNING_SEEDS[0], help="base seed")
    ap.add_argument("--snrs", default="0,3,6,9", help="per-bin SNRs, dB, comma separated")
    ap.add_argument("--fixed", action="store_true", help="the fixed cubes instead of varied ones")
    ap.add_argument("--perturb", default="half", choices=("none", "half", "all"),
                    help="clicks one beam and one bin off: none, every other one (default), all")
    ap.add_argument("--beams", type=int, default=64)
    ap.add_argument("--scans", type=int, default=60)
    ap.add_argument("--bins", type=int, default=16)
    ap.add_argument("--lag", type=float, default=0.0, help="the acquisition's lag setting, s")
    ap.add_argument("--sim-lag", type=float, default=0.0, help="--fixed: simulated lag, s")
    ap.add_argument("--averages", type=int, default=1, help="--fixed: periodogram looks per cell")
    ap.add_argument("--scan-period", type=float, default=1.0, help="time between scans, s")
    ap.add_argument("--ibw", type=float, default=None, help="IBW width, Hz (default: one bin)")
    ap.add_argument("--noise-dof", type=float, default=None,
                    help="the acquisition's noise degrees of freedom (default: estimated)")
    ap.add_argument("--freq-tolerance-bins", dest="freq_tolerance", type=int, default=1,
                    help="bins the click may be off (the acquisition's freq_tolerance_bins)")
    ap.add_argument("--trace", default="bearing", choices=("bearing", "beam"))
    ap.add_argument("--repeats", type=int, default=50, help="timed repeats")
    args = ap.parse_args(argv)
    snrs = [float(s) for s in args.snrs.split(",")]
    rng = np.random.default_rng(args.seed)
    acq = Acquisition(lag_s=args.lag, ibw_hz=args.ibw, noise_dof=args.noise_dof,
                      trace=args.trace, freq_tolerance_bins=args.freq_tolerance)
    scan_period = args.scan_period

    rows: dict[float, list[dict]] = {s: [] for s in snrs}
    causes = {s: {"default": 0, "rate": 0, "bearing": 0, "both": 0} for s in snrs}
    for i in range(args.cubes):
        snr = snrs[i % len(snrs)]
        cube_seed = int(rng.integers(2**31))
        if args.fixed:
            b0, rate = draw_case(rng, args.scans, scan_period)
            sc = simulate_cube(seed=cube_seed, n_beams=args.beams, n_scans=args.scans,
                               n_bins=args.bins, scan_period_s=scan_period, bearing0_deg=b0,
                               bearing_rate_deg_per_min=rate, snr_db=snr, lag_s=args.sim_lag,
                               n_averages=args.averages)
        else:
            sc = simulate_varied_cube(cube_seed, snr_db=snr, n_beams=args.beams,
                                      n_scans=args.scans, n_bins=args.bins,
                                      scan_period_s=scan_period)
        perturb = args.perturb == "all" or (args.perturb == "half" and (i // len(snrs)) % 2 == 1)
        beam, freq = (perturbed_click(sc, rng) if perturb else (sc.click_beam, sc.click_freq))
        res = acq.acquire(sc.cube, beam=beam, freq_hz=freq)
        truth, rate = sc.latest_bearing_deg, sc.bearing_rate_deg_per_min
        wl = sc.cube.sound_speed / sc.line_freq_hz
        tol_rate = max(1.0, 0.25 * abs(rate))
        tol_brg = half_beamwidth_deg(truth, wl, sc.cube.aperture)
        e_rate = abs(res.bearing_rate_deg_per_min - rate) / tol_rate
        e_brg = abs(res.bearing_deg - truth) / tol_brg
        ok = e_rate <= 1.0 and e_brg <= 1.0
        if not ok:
            cause = ("default" if res.default_used else "rate" if e_brg <= 1 else
                     "bearing" if e_rate <= 1 else "both")
            causes[snr][cause] += 1
            print(f"miss: snr {snr:+.0f} dB {'perturbed' if perturb else 'exact'} click, rate "
                  f"{rate:+.1f} est {res.bearing_rate_deg_per_min:+.1f}, brg {truth:.1f} est "
                  f"{res.bearing_deg:.1f}, default {res.default_used}", file=sys.stderr)
        rows[snr].append({"ok": bool(ok), "norm_err": max(e_rate, e_brg), "perturbed": perturb})

    # speed: one acquisition of a fresh cube, after warm-up
    sc = simulate_cube(seed=args.seed, n_beams=args.beams, n_scans=args.scans, n_bins=args.bins,
                       bearing0_deg=70.0, bearing_rate_deg_per_min=30.0, snr_db=3.0)
    acq.acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        acq.acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
        times.append(time.perf_counter() - t0)

    def pooled(pred, kind) -> dict:
        sel = [r for s in snrs if pred(s) for r in rows[s]
               if kind == "all" or r["perturbed"] == (kind == "perturbed")]
        return _summary(sel)

    out = {
        "benchmark": "acquisition",
        "cubes": args.cubes,
        "varied": not args.fixed,
        "perturb": args.perturb,
        "shape": [args.scans, args.beams, args.bins],
        "seed": args.seed,
        "tuning_seeds": list(TUNING_SEEDS),
        "report_seeds": list(REPORT_SEEDS),
        "per_snr_db": {f"{s:g}": {k: _summary([r for r in rows[s] if k == "all"
                                                or r["perturbed"] == (k == "perturbed")])
                                   for k in ("all", "exact", "perturbed")} for s in snrs},
        "snr_ge_3db": {k: pooled(lambda s: s >= 3, k) for k in ("all", "exact", "perturbed")},
        "misses_by_cause_vs_snr_db": {f"{s:g}": causes[s] for s in snrs},
        "median_ms_per_acquisition": round(1e3 * float(np.median(times)), 3),
        "targets": {"success_perturbed_snr_ge_3db": 0.90, "ms": 20.0},
    }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
