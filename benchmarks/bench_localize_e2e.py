"""Whale localization end to end from simulated audio: one whale, three whales, methods compared.

Runs the click front end (:class:`fusion.pipelines.clicks.ClickFrontEnd`, shipped validator) once
per scenario and then every localization method of
:class:`fusion.localization.localize.MultiSourceLocalizer` on the same valid TDOAs through
:class:`fusion.pipelines.localization.ClickLocalization`. Truth is used only to score: a whale's
position for a window is its position at the emission whose arrivals are centred on the window
(window centre minus the mean travel time).

Seeds: tuning 0-99 was used while building, seeds 0-4 (three whales) and 0-9 (one whale) for
reading the TDOAs along surface-reflected paths and its settings (``whale_localizer``); seeds
7000-7009 were the report seeds, but they were run three times across the surface-path design
change (commits 94aaf9a, 44ca8ef, 22c5c48), so they are retired as report seeds (see
``benchmarks/RESULTS.md``); new reports draw new seeds.

The localizer is that of ``fusion localize``'s defaults
(:class:`fusion.pipelines.localization.LocalizerSettings`, i.e.
:func:`fusion.pipelines.localization.whale_localizer` for these arrays below the surface): TDOAs
read along direct and surface-reflected paths (the surface at z = 0), and, with
``--water-column bottom`` (default; ``fusion localize --sea-floor-z-m``), the sea floor at the
deepest hydrophone (the simulated arrays are bottom-mounted: what a user
knows of the deployment, not of the whales). ``competition-direct`` is the competition reading
direct paths only, with the same water column (``--direct-only``, the earlier default).

Cases:

* ``one``: one whale inside the array (start within 0.6 array radii of the centre), SNR 15-30 dB,
  5 sensors: median 3-D error of the sources matched within 50 m (target <= 5 m);

SNR (``--snr-def``): by default the median per-click peak SNR at the weakest sensor of the
array (every sensor hears the whale at least that well); ``reference`` uses the simulator's
definition at 1 km, where the far sensors of a 1.5 km ring hear the clicks 10-25 dB lower and
mostly below the detector's reach;
* ``three``: three whales at once, 5 sensors, SNR 20-30 dB: fraction of (window, whale) localised
  within 10 m (target >= 0.9), false sources (not within 10 m of any whale) as a fraction of
  reported sources (target <= 0.05); for every method. Sources the output flags unobservable or
  mirror-ambiguous are counted apart (``flagged``), not as reported fixes;
* localization stage time per window (CPU, one thread; target <= 100 ms).

Usage: ``python benchmarks/bench_localize_e2e.py [--seeds 7000-7009] [--snr-def sensor]``
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from threadpoolctl import threadpool_limits

from fusion.pipelines.clicks import ClickFrontEnd
from fusion.pipelines.localization import ClickLocalization, LocalizerSettings
from fusion.simulate.clicks import simulate_clicks

METHODS = ("competition", "eq18", "eq17", "lsq", "competition-direct")


def seeds_arg(text: str) -> list[int]:
    """``A-B`` (inclusive) or a comma list."""
    if "-" in text:
        a, b = (int(v) for v in text.split("-"))
        return list(range(a, b + 1))
    return [int(v) for v in text.split(",")]


def truth_at(sc, t_mid: float) -> np.ndarray:
    """Each whale's position at the emission whose arrivals are centred on `t_mid`."""
    out = []
    for s in sc.sources:
        p = s.position_at([t_mid])[0]
        for _ in range(3):  # emission time = t_mid - mean travel time (fixed point)
            r = np.linalg.norm(sc.sensors.positions - p, axis=1).mean() / sc.sensors.sound_speed
            p = s.position_at([t_mid - r])[0]
        out.append(p)
    return np.array(out)


def scenario(seed: int, n_sources: int, snr_db: float, duration: float, snr_def: str):
    """A 5-sensor scenario at `snr_db`: at the reference range (``reference``), or as the
    median per-click peak SNR at the weakest (whale, sensor) of the array (``sensor``)."""
    sc = simulate_clicks(seed=seed, n_sensors=5, n_sources=n_sources, duration_s=duration,
                         snr_db=snr_db)
    if snr_def == "reference":
        return sc
    weakest = min(float(np.min(np.median(np.abs(s.arrival_amplitudes), axis=0)))
                  for s in sc.sources) / sc.noise_std_band
    # the draws do not depend on the SNR: the same seed gives the same geometry and clicks
    return simulate_clicks(seed=seed, n_sensors=5, n_sources=n_sources, duration_s=duration,
                           snr_db=snr_db + snr_db - 20.0 * np.log10(weakest))


def localizer_for(method: str, sensors, water_column: str) -> LocalizerSettings:
    """The ``fusion localize`` settings benchmarked as `method` for an array (module docstring).

    ``competition`` with ``--water-column bottom`` is ``fusion localize --sea-floor-z-m Z`` (Z the
    deepest hydrophone); ``competition-direct`` adds ``--direct-only``, the others ``--method``.
    """
    bottom = float(np.min(sensors.positions[:, 2])) if water_column == "bottom" else None
    if method == "competition-direct":
        return LocalizerSettings(method="competition", surface_paths=False, sea_floor_z=bottom)
    return LocalizerSettings(method=method, sea_floor_z=bottom)


def run_case(seeds: list[int], n_sources: int, snr_range: tuple[float, float],
             duration: float, snr_def: str, water_column: str) -> dict:
    """Score every method on the scenarios of one case."""
    fe = ClickFrontEnd()
    stats = {m: {"errors": [], "found": 0, "pairs": 0, "reported": 0, "false": 0, "flagged": 0,
                 "ms": []}
             for m in METHODS}
    for seed in seeds:
        rng = np.random.default_rng([seed, 5])
        sc = scenario(seed, n_sources, float(rng.uniform(*snr_range)), duration, snr_def)
        windows = fe.run_array(sc.audio, sc.fs, sc.sensors)
        for m in METHODS:
            pipe = ClickLocalization(front_end=fe,
                                     localizer=localizer_for(m, sc.sensors, water_column))
            st = stats[m]
            for w in windows:
                truth = truth_at(sc, 0.5 * (w.t_start + w.t_end))
                with threadpool_limits(1):
                    t0 = time.process_time()
                    lw = pipe.localize(w, sc.sensors)
                    st["ms"].append((time.process_time() - t0) * 1e3)
                every = [] if lw.output is None else list(lw.output.sources)
                # sources flagged unobservable or mirror-ambiguous are reported as such in the
                # output; they are counted apart, not as fixes
                srcs = [s.position for s in every if s.observable and not s.mirror_ambiguous]
                st["flagged"] += len(every) - len(srcs)
                st["reported"] += len(srcs)
                st["pairs"] += len(truth)
                for p in srcs:
                    d = np.linalg.norm(truth - p, axis=1)
                    if d.min() > 10.0:
                        st["false"] += 1
                    if d.min() < 50.0:
                        st["errors"].append(float(d.min()))
                for q in truth:
                    if any(np.linalg.norm(q - p) < 10.0 for p in srcs):
                        st["found"] += 1
    out = {}
    for m, st in stats.items():
        out[m] = {
            "median_error_m": round(float(np.median(st["errors"])), 3) if st["errors"] else None,
            "found_within_10m": round(st["found"] / max(st["pairs"], 1), 4),
            "false_fraction": round(st["false"] / max(st["reported"], 1), 4),
            "reported": st["reported"],
            "flagged": st["flagged"],
            "ms_per_window_median": round(float(np.median(st["ms"])), 2),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=seeds_arg, default=seeds_arg("7000-7009"))
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--snr-def", choices=("sensor", "reference"), default="sensor",
                    help="SNR of a scenario: median per-click peak SNR at the weakest sensor "
                         "(default) or at the simulator's 1 km reference range")
    ap.add_argument("--water-column", choices=("bottom", "none"), default="bottom",
                    help="sea floor at the deepest hydrophone (bottom-mounted arrays, default) "
                         "or unknown (only the surface bounds the search)")
    ap.add_argument("--cases", default="one,three", help="comma list of one, three")
    args = ap.parse_args()
    res = {"seeds": f"{args.seeds[0]}-{args.seeds[-1]}", "snr_def": args.snr_def,
           "water_column": args.water_column}
    for case, n, snr in (("one", 1, (15.0, 30.0)), ("three", 3, (20.0, 30.0))):
        if case in args.cases.split(","):
            res[case] = run_case(args.seeds, n, snr, args.duration, args.snr_def,
                                 args.water_column)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
