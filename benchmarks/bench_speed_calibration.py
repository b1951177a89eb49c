"""The recording's sound-speed step of ``fusion localize`` alone, variant by variant.

Each seed's recording is simulated and localized once at the array file's speed (``fusion
localize --sound-speed array``, the windows the speed step reads back), cached in
``--cache-dir``; then each ``--variants`` entry re-solves those windows as ``fusion localize``
would (:func:`fusion.pipelines.sound_speed.calibrate_speed`) and scores them as
``bench_localize_baseline.py`` does (same truth, same 10 m gate, fixes flagged unobservable or
mirror-ambiguous left out). Variants: ``array`` (the file's speed), ``one`` (one speed,
``--no-speed-gradient --sensor-position-sigma-m 0``), ``profile`` (a speed linear in depth where
the fixes tell it, ``--sensor-position-sigma-m 0``), ``positions`` (the default since section 24
of docs/localization.md: the profile with the sensors' positions refined from the fixes, prior
``--sensor-position-sigma-m``). The figures
equal ``bench_localize_baseline.py --methods project`` on the same seeds and
options (checked on seeds 7900-7909, ``--vary-only sound-speed``, one whale).

Usage::

    python benchmarks/bench_speed_calibration.py --seeds 7900-7909 --whales 1 \\
        --vary-only sound-speed --variants array,one,profile [--cache-dir DIR] [--verbose]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_localize_baseline import WITHIN_M, Truth, seeds_arg, write_recording  # noqa: E402

from fusion.cli import main as fusion_main  # noqa: E402
from fusion.metrics.localization import match_fixes  # noqa: E402
from fusion.pipelines.sound_speed import calibrate_speed  # noqa: E402

VARIANTS = {"array": None, "one": {"gradient": False, "sensor_sigma_m": 0.0},
            "profile": {"gradient": True, "sensor_sigma_m": 0.0},
            "positions": {"gradient": True, "sensor_sigma_m": None}}


def cached(folder: Path, seed: int, options: dict) -> tuple[list, np.ndarray, float, Truth]:
    """The seed's windows at the file's speed, sensors, the file's speed and the truth."""
    if not (folder / "raw.json").exists():
        folder.mkdir(parents=True, exist_ok=True)
        write_recording(folder, seed, options)
        audio = next(folder / n for n in ("audio.flac", "audio.wav") if (folder / n).exists())
        with contextlib.redirect_stderr(io.StringIO()):
            if fusion_main(["localize", "--audio", str(audio), "--array",
                            str(folder / "array.json"), "--out", str(folder / "raw.json"),
                            "--quiet", "--sound-speed", "array"]) != 0:
                raise SystemExit(f"fusion localize failed on seed {seed}")
        audio.unlink()
    arr = json.loads((folder / "array.json").read_text())
    sensors = np.array([[s[k] for k in "xyz"] for s in arr["sensors"]], float)
    return (json.loads((folder / "raw.json").read_text())["windows"], sensors,
            float(arr["sound_speed"]), Truth(json.loads((folder / "truth.json").read_text())))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=seeds_arg, required=True, help="e.g. 7900-7909")
    ap.add_argument("--whales", type=int, default=1)
    ap.add_argument("--sensors", type=int, default=5)
    ap.add_argument("--snr-db", type=float, default=30.0)
    ap.add_argument("--duration-s", type=float, default=30.0)
    ap.add_argument("--echo", choices=("none", "surface", "bottom", "both"), default="both")
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--vary", action="store_true")
    group.add_argument("--vary-only", default=None, metavar="GROUPS")
    ap.add_argument("--variants", default="array,one,profile",
                    help=f"comma list of {', '.join(VARIANTS)}")
    ap.add_argument("--sensor-position-sigma-m", type=float, default=2.0,
                    help="prior sigma of the sensor positions of the positions variant, m")
    ap.add_argument("--cache-dir", type=Path, default=Path("bench_speed_cache"))
    ap.add_argument("--verbose", action="store_true", help="a line per seed (the speed note)")
    args = ap.parse_args(argv)
    variants = [v.strip() for v in args.variants.split(",")]
    if any(v not in VARIANTS for v in variants):
        ap.error(f"--variants: choose from {', '.join(VARIANTS)}")
    options = {"duration_s": args.duration_s, "n_sources": args.whales,
               "n_sensors": args.sensors, "snr_db": args.snr_db, "echo": args.echo}
    tag = "plain"
    if args.vary:
        options["vary"], tag = True, "vary"
    elif args.vary_only:
        options["vary_only"] = tuple(g.strip() for g in args.vary_only.split(","))
        tag = args.vary_only.replace(",", "+")
    tag += f"_w{args.whales}_s{args.sensors}_{args.snr_db:g}dB_{args.duration_s:g}s_{args.echo}"
    for v in variants:
        tot = {"found": 0, "pairs": 0, "reported": 0, "false": 0, "errors": []}
        for seed in args.seeds:
            windows, sensors, c, truth = cached(args.cache_dir / f"{tag}_{seed}", seed, options)
            kw = None if VARIANTS[v] is None else {**VARIANTS[v]}
            if kw is not None and kw.get("sensor_sigma_m", 0.0) is None:
                kw["sensor_sigma_m"] = args.sensor_position_sigma_m
            cal = None if kw is None else calibrate_speed(windows, sensors, c, **kw)
            found = 0
            for w in (windows if cal is None else [cal.apply(w) for w in windows]):
                srcs = [[s["x"], s["y"], s["z"]] for s in w["sources"]
                        if s.get("observable", True) and not s.get("mirror_ambiguous", False)]
                true = truth.positions(0.5 * (w["t_start"] + w["t_end"]))
                m = match_fixes(true, srcs, within_m=WITHIN_M)
                tot["reported"] += len(srcs)
                tot["pairs"] += len(true)
                tot["found"] += m.found
                tot["false"] += m.false
                tot["errors"] += list(m.errors_m)
                found += m.found
            if args.verbose:
                print(f"  {v} seed {seed}: {found} found | {cal.note if cal else ''}")
        print(json.dumps({"variant": v, "seeds": f"{args.seeds[0]}-{args.seeds[-1]}",
                          "case": tag, "within_10m_pct": round(100 * tot["found"]
                                                               / max(tot["pairs"], 1), 1),
                          "false_sources_pct": round(100 * tot["false"]
                                                     / max(tot["reported"], 1), 1),
                          "false": tot["false"], "reported": tot["reported"],
                          "median_error_m": (round(float(np.median(tot["errors"])), 2)
                                             if tot["errors"] else None)}), flush=True)


if __name__ == "__main__":
    main()
