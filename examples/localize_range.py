"""Localize whales on a simulated bottom-mounted range the way a user runs ``fusion localize``.

A recording is simulated with the physics of a real range -- hydrophones a few metres above the
sea floor with bottom and surface echoes (``fusion simulate clicks --echo both``), or every varied
assumption at once (``--vary``: sloping floor, depth-dependent sound speed the localizer does not
know, several click shapes, surveyed sensor positions a few metres off, other species' clicks) --
and written to disk. ``fusion localize`` then runs on the files with its defaults: it estimates
the click replica from the recording, measures the bottom echoes (echo suppression and, when the
sensors stand near the floor, the sea floor), compensates delay drift, and reads TDOAs along
surface paths only in windows the direct paths leave unexplained. The truth is read only to score.

Usage::

    python examples/localize_range.py [--seed 3] [--whales 2] [--echo both] [--vary]
        [--vary-only sound-speed]
        [--duration-s 30] [--out DIR]

Prints the command's own report (replica, bottom echoes, counts) and one JSON line of scores:
windows, whales found within 10 m, false fixes, the median error of found fixes and the median
|TDOA error| at each TDOA's own time ``t``, and the sound speed the command estimated beside
the array file's.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
from pathlib import Path

import numpy as np

from fusion.cli import main as fusion
from fusion.metrics.localization import match_fixes, true_positions, true_tdoas


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--whales", type=int, default=2)
    ap.add_argument("--echo", choices=("none", "surface", "bottom", "both"), default="both")
    ap.add_argument("--vary", action="store_true", help="every varied assumption at once")
    ap.add_argument("--vary-only", default=None, metavar="GROUPS",
                    help="one varied effect at a time, e.g. sound-speed (fusion simulate clicks "
                         "--vary-only)")
    ap.add_argument("--duration-s", type=float, default=30.0)
    ap.add_argument("--out", type=Path, default=None, help="keep the files here")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.out or Path(tmp)
        scen = folder / "range"
        sim = ["simulate", "clicks", "--seed", str(args.seed), "--out", str(scen),
               "--duration-s", str(args.duration_s)]
        sim += ["--vary"] if args.vary else ["--whales", str(args.whales), "--echo", args.echo]
        sim += ["--vary-only", args.vary_only] if args.vary_only else []
        with contextlib.redirect_stdout(io.StringIO()):  # the written paths
            assert fusion(sim) == 0
        audio = next(p for p in (scen / "audio.flac", scen / "audio.wav") if p.exists())
        result = folder / "localization.json"
        assert fusion(["localize", "--audio", str(audio), "--array", str(scen / "array.json"),
                       "--out", str(result), "--quiet"]) == 0
        doc = json.loads(result.read_text())
        truth = json.loads((scen / "truth.json").read_text())
        side = json.loads((folder / "localization.settings.json").read_text())
    found = pairs = false = reported = 0
    errors, tdoa_errors = [], []
    for w in doc["windows"]:
        t_mid = 0.5 * (w["t_start"] + w["t_end"])
        fixes = [[s["x"], s["y"], s["z"]] for s in w["sources"]
                 if s.get("observable", True) and not s.get("mirror_ambiguous", False)]
        m = match_fixes(true_positions(truth, t_mid), fixes)
        found, pairs = found + m.found, pairs + len(truth["sources"])
        false, reported = false + m.false, reported + len(fixes)
        errors += m.errors_m
        for d in w["tdoas"]:
            if d["valid"]:
                e = np.min(np.abs(true_tdoas(truth, *d["pair"], d["t"]) - d["tau"]))
                if e < 1e-3:
                    tdoa_errors.append(float(e) * 1e6)
    summary = {
        "windows": len(doc["windows"]), "whales": len(truth["sources"]),
        "found_within_10m": f"{found}/{pairs}", "false_fixes": f"{false}/{reported}",
        "median_error_m": round(float(np.median(errors)), 3) if errors else None,
        "median_tdoa_error_us": round(float(np.median(tdoa_errors)), 3) if tdoa_errors else None,
        "found_fraction": found / max(pairs, 1), "false_fraction": false / max(reported, 1),
        "sound_speed_mps": round(next(iter(side["sound_speed"].values()))["speed_mps"], 2),
        "array_file_sound_speed_mps": truth["nominal_sound_speed"],
    }
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    main()
