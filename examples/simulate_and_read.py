"""Simulate a small click scenario, write it in the project's formats, read it back.

Writes ``audio.flac``, ``array.json`` and ``truth.json`` (the files ``fusion simulate clicks``
writes), reads them through :mod:`fusion.io`, and summarises what a localisation run would see:
sensors, sources, clicks, the per-sensor direct-path SNR and the spread of the true TDOAs.

Run::

    python examples/simulate_and_read.py --seed 4 --duration 10 --out /tmp/clicks
"""

from __future__ import annotations

import argparse
import json
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fusion.io import read_array, read_audio, read_json
from fusion.simulate.clicks import simulate_clicks, write_click_scenario


def summarise(out_dir: Path) -> dict[str, Any]:
    """Read a written click scenario back and summarise it."""
    array = read_array(out_dir / "array.json")
    samples, fs = read_audio(out_dir / "audio.flac", n_channels=array.n_sensors)
    truth = read_json(out_dir / "truth.json")
    noise_band = truth["noise_std_band"]
    per_sensor_snr = []
    for src in truth["sources"]:
        amp = np.abs(np.asarray(src["arrival_amplitudes"]))
        snr = 20 * np.log10(np.median(amp, axis=0) / noise_band) if noise_band > 0 else amp * np.inf
        per_sensor_snr.append([round(float(v), 1) for v in snr])
    tdoas = np.concatenate([np.asarray(s["tdoas"]) for s in truth["sources"]])
    return {
        "sensors": list(array.ids),
        "sound_speed": array.sound_speed,
        "fs": fs,
        "duration_s": samples.shape[0] / fs,
        "channels": samples.shape[1],
        "n_sources": len(truth["sources"]),
        "n_clicks": sum(len(s["emission_times"]) for s in truth["sources"]),
        "n_transients": len(truth["transients"]),
        "median_direct_snr_db_per_sensor": per_sensor_snr,
        "max_abs_tdoa_s": float(np.abs(tdoas).max()),
        "file_peak": float(np.abs(samples).max()),
        "audio_scale": truth["audio_scale"],
    }


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Simulate, write, read back, print and return the summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=4)
    parser.add_argument("--duration", type=float, default=10.0, help="audio length, s")
    parser.add_argument("--sensors", type=int, default=5)
    parser.add_argument("--sources", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: temporary)")
    args = parser.parse_args(argv)

    scenario = simulate_clicks(
        seed=args.seed, duration_s=args.duration, n_sensors=args.sensors, n_sources=args.sources
    )
    if args.out is None:
        with tempfile.TemporaryDirectory() as tmp:
            write_click_scenario(Path(tmp), scenario)
            summary = summarise(Path(tmp))
    else:
        write_click_scenario(args.out, scenario)
        summary = summarise(args.out)
    print(json.dumps(summary, indent=1))
    return summary


if __name__ == "__main__":
    main()
