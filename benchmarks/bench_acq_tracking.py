"""Benchmark: narrowband tracker initialised by acquisition vs by the default, at high bearing rates.

For every case a cube is simulated long enough for the acquisition window plus the tracking run
(``--window`` + ``--track-scans`` scans). The acquisition (:class:`fusion.passive.acquisition.
Acquisition`) sees only the first ``--window`` scans and the operator's click at the latest of
them (the beam nearest the shown bearing, the bin nearest the line). The bearing tracker
(:class:`fusion.passive.tracker.BearingTracker`) then starts from

- the acquisition's bearing, bearing rate and frequency, or
- the default initialisation: the clicked beam's bearing and bearing rate 0,

and follows the next ``--track-scans`` scans; the track quality indicator (hysteresis, default
design SNRs) watches it. A case is *kept* when the TQI is never ``lost`` over those scans.
Also reported: the fraction whose final bearing is within one beamwidth of the truth.

Bearing rates are drawn uniformly in ``[--min-rate, --max-rate]`` deg/min with a random sign,
start bearings so that the target stays within 15-165 deg, per-bin SNR from ``--snr-db``.

Prints one JSON line; human-readable lines go to stderr.

Usage::

    python benchmarks/bench_acq_tracking.py --cases 40 --seed 0
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from fusion.geometry import bearing_from_beam
from fusion.io import Cube
from fusion.passive.acquisition import Acquisition
from fusion.passive.quality import TrackQuality, TrackQualityIndicator
from fusion.passive.tracker import BearingTracker, beamwidth_deg
from fusion.simulate.cube import simulate_cube


def run_case(seed: int, *, rate: float, snr_db: float, window: int, track_scans: int,
             rng: np.random.Generator) -> dict[str, float | bool]:
    n_scans = window + track_scans + 1
    span = abs(rate) * (n_scans - 1) / 60.0
    lo, hi = 15.0, 165.0
    start = rng.uniform(lo + (span if rate < 0 else 0.0), hi - (span if rate > 0 else 0.0))
    sc = simulate_cube(seed=seed, n_scans=n_scans, bearing0_deg=start,
                       bearing_rate_deg_per_min=rate, snr_db=snr_db)
    c = sc.cube
    n_beams = c.n_beams
    latest = window - 1
    click_beam = int(np.clip(np.floor(sc.beam_track[latest] + 0.5), 0, n_beams - 1))
    sub = Cube(power=c.power[:window], freqs=c.freqs, scan_period=c.scan_period,
               aperture=c.aperture, sound_speed=c.sound_speed)
    acq = Acquisition().acquire(sub, beam=click_beam, freq_hz=sc.click_freq)
    inits = {
        "acquisition": (acq.bearing_deg, acq.bearing_rate_deg_per_min),
        "default": (float(np.degrees(bearing_from_beam(click_beam, n_beams))), 0.0),
    }
    tracker = BearingTracker()
    tqi = TrackQualityIndicator()
    wl = c.sound_speed / sc.click_freq
    out: dict[str, float | bool] = {"acq_default_used": bool(acq.default_used),
                                    "acq_rate_error": acq.bearing_rate_deg_per_min - rate}
    for name, (brg, rt) in inits.items():
        h = tracker.track(c, bearing_deg=brg, bearing_rate_deg_per_min=rt,
                          freq_hz=sc.click_freq, init_scan=latest, n_scans=track_scans)
        states = tqi.run(h.amplitude, h.residual_deg).state[:, 0]
        truth = sc.shown_bearing_deg[h.scan[-1]]
        bw = float(beamwidth_deg(truth, wavelength=wl, aperture=c.aperture))
        out[f"{name}_kept"] = bool(np.all(states != TrackQuality.LOST))
        out[f"{name}_on_target"] = bool(abs(h.bearing_deg[-1] - truth) <= bw)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", type=int, default=40, help="cases per SNR")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--snr-db", type=float, nargs="+", default=[3.0, 6.0, 9.0],
                    help="per-bin SNRs of the line, dB")
    ap.add_argument("--min-rate", type=float, default=15.0, help="deg/min")
    ap.add_argument("--max-rate", type=float, default=40.0, help="deg/min")
    ap.add_argument("--window", type=int, default=60, help="acquisition window, scans")
    ap.add_argument("--track-scans", type=int, default=60, help="tracking run, scans")
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    t0 = time.perf_counter()
    result: dict[str, object] = {"bench": "acq_tracking", "cases_per_snr": a.cases,
                                 "seed": a.seed, "window_scans": a.window,
                                 "track_scans": a.track_scans,
                                 "rate_range_deg_per_min": [a.min_rate, a.max_rate]}
    per_snr = {}
    for snr in a.snr_db:
        rows = []
        for _ in range(a.cases):
            rate = rng.uniform(a.min_rate, a.max_rate) * rng.choice([-1.0, 1.0])
            rows.append(run_case(int(rng.integers(2**31)), rate=rate, snr_db=snr,
                                 window=a.window, track_scans=a.track_scans, rng=rng))
        summary = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]
                   if isinstance(rows[0][k], bool)}
        summary["acq_rate_rmse"] = float(np.sqrt(np.mean([r["acq_rate_error"] ** 2
                                                          for r in rows])))
        per_snr[f"{snr:g}"] = summary
        print(f"snr {snr:g} dB: " + ", ".join(f"{k}={v:.3f}" for k, v in summary.items()),
              file=sys.stderr)
    result["per_snr_db"] = per_snr
    result["seconds"] = round(time.perf_counter() - t0, 2)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
