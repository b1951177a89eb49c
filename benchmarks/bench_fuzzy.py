"""Benchmark of the fuzzy association engine: agreement and speed.

Agreement: the default rule base ("Target tracking using fuzzy logic
association", Sections 4-6) is evaluated on random inputs; its exact
centroids are compared with scikit-fuzzy's centroid (``skfuzzy.defuzz``) and
with ``np.trapezoid`` of the same aggregated set sampled on fine grids. A
system with smooth (Gaussian, sigmoid) output sets checks the quadrature path.

Speed: one ``evaluate`` call ranking every (track, detection) candidate of a
ping, 200 detections x 20 tracks = 4,000 candidates by default.

Prints one JSON line of measured figures; details go to stderr.

Usage::

    python benchmarks/bench_fuzzy.py [--n-random 1000] [--seed 0]
        [--n-detections 200] [--n-tracks 20] [--repeats 50]
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import skfuzzy as fuzz

from fusion.active.fuzzy import (
    FuzzySystem,
    Gaussian,
    LeftShoulder,
    LinguisticVariable,
    RightShoulder,
    Rule,
    Sigmoid,
    Triangular,
)
from fusion.active.rulebase import default_association_system


def random_inputs(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """Uniform inputs over the default system's universes."""
    return {
        "likelihood": rng.uniform(0.0, 1.0, n),
        "score": rng.uniform(0.0, 1.0, n),
        "aspect_deg": rng.uniform(0.0, 180.0, n),
        "snr_db": rng.uniform(0.0, 40.0, n),
        "hotspot_distance_m": rng.uniform(0.0, 2000.0, n),
    }


def aggregated(system: FuzzySystem, alpha: np.ndarray, y: np.ndarray) -> np.ndarray:
    """max_t min(alpha_t, mu_t(y)) sampled on y, one row per candidate (n, G)."""
    sets = np.stack([mf(y) for mf in system.output.terms.values()])
    return np.max(np.fmin(alpha.T[:, :, None], sets[None]), axis=1)


def agreement(n: int, seed: int, skfuzzy_grid: int, fine_grid: int) -> dict[str, float]:
    """Max |exact - reference| for the default system and a smooth-output system."""
    rng = np.random.default_rng(seed)
    system = default_association_system()
    result = system.evaluate(random_inputs(rng, n))
    crisp, alpha = result.crisp, result.activations

    y_sk = np.linspace(0.0, 1.0, skfuzzy_grid)
    # Output sets from skfuzzy's own generators, independent of fusion's.
    sk_sets = np.stack([fuzz.trimf(y_sk, [0, 0, 0.5]), fuzz.trimf(y_sk, [0, 0.5, 1]),
                        fuzz.trimf(y_sk, [0.5, 1, 1])])
    sk = np.array([
        fuzz.defuzz(y_sk, np.max(np.fmin(alpha[:, j][:, None], sk_sets), axis=0), "centroid")
        for j in range(n)
    ])
    y = np.linspace(0.0, 1.0, fine_grid)
    trap = np.empty(n)
    for start in range(0, n, 50):
        agg = aggregated(system, alpha[:, start:start + 50], y)
        trap[start:start + 50] = np.trapezoid(agg * y, y, axis=1) / np.trapezoid(agg, y, axis=1)

    x = LinguisticVariable("x", (0.0, 1.0), {"lo": LeftShoulder(0, 1), "hi": RightShoulder(0, 1)})
    output = LinguisticVariable(
        "y", (0.0, 10.0),
        {"lo": Sigmoid(3.0, -2.0), "mid": Gaussian(5.0, 1.2), "hi": Triangular(6.0, 9.0, 10.0)},
    )
    smooth = FuzzySystem([x], output, [Rule(x["lo"], "lo"), Rule(x["hi"], "hi", weight=0.7),
                                       Rule(x["hi"], "mid", weight=0.9)])
    n_smooth = min(n, 200)
    res = smooth.evaluate({"x": rng.uniform(0.0, 1.0, n_smooth)})
    ys = np.linspace(0.0, 10.0, 1_000_001)
    ref = np.empty(n_smooth)
    for start in range(0, n_smooth, 10):
        agg = aggregated(smooth, res.activations[:, start:start + 10], ys)
        ref[start:start + 10] = np.trapezoid(agg * ys, ys, axis=1) / np.trapezoid(agg, ys, axis=1)
    return {
        "max_abs_diff_vs_skfuzzy_defuzz": float(np.max(np.abs(crisp - sk))),
        "max_abs_diff_vs_trapezoid": float(np.max(np.abs(crisp - trap))),
        "smooth_max_rel_diff_vs_trapezoid": float(np.max(np.abs(res.crisp - ref)) / 10.0),
    }


def speed(n_candidates: int, seed: int, repeats: int) -> dict[str, float]:
    """Wall time of one evaluate call on n_candidates (median and best of repeats)."""
    system = default_association_system()
    inputs = random_inputs(np.random.default_rng(seed + 1), n_candidates)
    system.evaluate(inputs)  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        system.evaluate(inputs)
        times.append(time.perf_counter() - t0)
    # Load context: the same machine's time for one million float64 multiplies.
    a = np.random.default_rng(seed).random(1_000_000)
    ref = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        np.multiply(a, a)
        ref.append(time.perf_counter() - t0)
    return {
        "evaluate_ms_median": 1e3 * float(np.median(times)),
        "evaluate_ms_min": 1e3 * float(np.min(times)),
        "numpy_multiply_1e6_ms_median": 1e3 * float(np.median(ref)),
    }


def main(argv: list[str] | None = None) -> dict[str, float]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-random", type=int, default=1000, help="random inputs for agreement")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-detections", type=int, default=200)
    parser.add_argument("--n-tracks", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--skfuzzy-grid", type=int, default=4001, help="points for skfuzzy.defuzz")
    parser.add_argument("--fine-grid", type=int, default=200_001, help="points for np.trapezoid")
    args = parser.parse_args(argv)

    out: dict[str, float] = {"n_random": args.n_random, "seed": args.seed}
    t0 = time.perf_counter()
    out.update(agreement(args.n_random, args.seed, args.skfuzzy_grid, args.fine_grid))
    print(f"agreement checks took {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    n_candidates = args.n_detections * args.n_tracks
    out["n_candidates"] = n_candidates
    out.update(speed(n_candidates, args.seed, args.repeats))
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
