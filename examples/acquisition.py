"""Acquire a high bearing-rate narrowband target from a simulated cube, as an operator's click would.

Run ``python examples/acquisition.py [--seed S] [--rate DEG_PER_MIN] [--snr DB] [--lag S]``.
"""

from __future__ import annotations

import argparse
import json

from fusion.passive.acquisition import Acquisition
from fusion.simulate.cube import simulate_cube


def main(argv: list[str] | None = None) -> dict[str, float | bool]:
    """Simulate a cube, click the target's beam and frequency, acquire; print and return a summary."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rate", type=float, default=35.0, help="true bearing rate, deg/min")
    ap.add_argument("--snr", type=float, default=6.0, help="per-bin SNR, dB")
    ap.add_argument("--lag", type=float, default=2.0, help="spectral integration lag, s")
    args = ap.parse_args(argv)

    # 60 one-second scans of 64 beams x 16 bins; the trace crosses many beams
    scenario = simulate_cube(seed=args.seed, bearing0_deg=50.0, bearing_rate_deg_per_min=args.rate,
                             snr_db=args.snr, lag_s=args.lag)
    # the operator clicks the beam nearest the line and its bin on the latest scan
    acquisition = Acquisition(lag_s=args.lag)
    result = acquisition.acquire(scenario.cube, beam=scenario.click_beam,
                                 freq_hz=scenario.click_freq)
    best = result.best_line  # constant-bearing-rate trace: fan search, then sub-beam refinement
    summary = {
        **result.to_json(),
        "true_bearing_deg": scenario.latest_bearing_deg,
        "true_bearing_rate_deg_per_min": scenario.bearing_rate_deg_per_min,
        "clicked_beam": scenario.click_beam,
        "best_line_anchor_beam": best.anchor_beam if best else None,
        "fan_search_bearing_rate_deg_per_min": best.coarse_bearing_rate_deg_per_min if best else None,
        "refined_end_beam": best.end_beam if best and best.refined else None,
    }
    print(json.dumps(summary, indent=1))
    return summary


if __name__ == "__main__":
    main()
