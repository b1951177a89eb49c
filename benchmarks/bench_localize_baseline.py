"""``fusion localize`` beside a plain baseline localizer on the same simulated recordings.

For each seed a click scenario is written to a temporary folder through the library
(:func:`fusion.simulate.clicks.write_scenario` with only the options given here; while the
installed ``write_scenario`` takes the seed alone, the options ``simulate_clicks`` knows —
whales, sensors, SNR, duration — go through :func:`fusion.simulate.clicks.simulate_clicks` and
:func:`fusion.simulate.clicks.write_click_scenario`, the same files) and read back as a user
would: ``audio.flac`` and ``array.json`` go to the estimators, ``truth.json`` only to the
scores. Methods:

* ``project``: ``fusion localize`` with its defaults, run in this process on the written files
  exactly as a user runs it (replica estimated from the recording, paths decided per window;
  no sea floor unless ``--sea-floor deepest``, then ``--sea-floor-z-m``);
* ``baseline``: :func:`click_baseline.localize_recording` (``benchmarks/click_baseline.py``).

Scores, per window, as ``benchmarks/bench_localize_e2e.py`` counts them: a whale's truth is
its position at the emission whose arrivals are centred on the window centre (interpolated
between the emissions of ``truth.json``); a whale is found when a reported source lies within
10 m of it; a reported source farther than 10 m from every whale is false. Sources the project
flags unobservable or mirror-ambiguous are counted apart (``flagged``), not as reported.
CPU seconds per window: ``time.process_time`` of the whole method on the recording (audio to
sources, one BLAS thread) over its windows. For the project, and the baseline's candidate
TDOAs, also the median |TDOA error| (us) of the TDOAs (project: valid ones) that lie within
1 ms of a whale's true direct-path TDOA of the same pair at the TDOA's own time ``t`` (the
arrival at the pair's first sensor that ``fusion localize`` writes with each TDOA; the
window centre for the baseline), and the fraction that do.

Seeds: 0-9 are the baseline's tuning seeds; report on others (e.g. 7100-7109).

Usage::

    python benchmarks/bench_localize_baseline.py --seeds 7100-7109 --whales 3 \\
        [--snr-db 20] [--duration-s 30] [--echo both] [--vary] [--methods project,baseline] \\
        [--sea-floor none|deepest] [--out results.jsonl]

One JSON line per method is printed (and appended to ``--out``).
"""

from __future__ import annotations

import argparse
import inspect
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from fusion.io import read_array, read_audio, read_json
from fusion.metrics.localization import match_fixes, true_positions, true_tdoas

METHODS = ("project", "baseline")
#: options simulate_clicks takes (the fallback while write_scenario takes the seed alone)
SIMULATE_KEYS = {"duration_s", "n_sources", "n_sensors", "snr_db"}
#: write_scenario keyword -> this script's option
OPTION_FLAGS = {"duration_s": "--duration-s", "n_sources": "--whales", "n_sensors": "--sensors",
                "snr_db": "--snr-db", "echo": "--echo", "vary": "--vary",
                "vary_only": "--vary-only"}
GATE_TDOA_S = 1e-3
WITHIN_M = 10.0


def seeds_arg(text: str) -> list[int]:
    """``A-B`` (inclusive), a comma list, or both (``0-4,9``)."""
    out: list[int] = []
    for part in text.split(","):
        if "-" in part.strip()[1:]:
            a, b = part.rsplit("-", 1)
            out.extend(range(int(a), int(b) + 1))
        else:
            out.append(int(part))
    return out


def write_recording(out_dir: Path, seed: int, options: dict) -> None:
    """Write the scenario of `seed` with the user's `options` (only those set) to `out_dir`."""
    from fusion.simulate import clicks

    accepted = inspect.signature(clicks.write_scenario).parameters
    if all(k in accepted for k in options):
        clicks.write_scenario(out_dir, seed=seed, **options)
        return
    missing = sorted(k for k in options if k not in accepted and k not in SIMULATE_KEYS)
    if not missing:  # the library's simulator takes them: the same files
        clicks.write_click_scenario(out_dir, clicks.simulate_clicks(seed=seed, **options))
        return
    flags = ", ".join(OPTION_FLAGS.get(k, k) for k in missing)
    raise SystemExit(f"error: the installed fusion.simulate.clicks.write_scenario does not "
                     f"accept {flags} yet (update fusion, or drop {flags})")


class Truth:
    """Whale positions and direct-path TDOAs at a time, from ``truth.json``
    (:func:`fusion.metrics.localization.true_positions`, :func:`~.true_tdoas`)."""

    def __init__(self, doc: dict) -> None:
        self.doc = doc

    def positions(self, t_mid: float) -> np.ndarray:
        """(n_whales, 3): each whale where it emitted the click whose mean arrival is `t_mid`."""
        return true_positions(self.doc, t_mid)

    def tdoas(self, t_mid: float, i: int, j: int) -> np.ndarray:
        """Each whale's ``t_i - t_j`` with its arrival at sensor i at `t_mid`, s."""
        return true_tdoas(self.doc, i, j, t_mid)


def score_window(truth: np.ndarray, sources: list, st: dict) -> None:
    """Add one window's counts (:func:`fusion.metrics.localization.match_fixes`) to `st`."""
    m = match_fixes(truth, sources, within_m=WITHIN_M)
    st["reported"] += len(sources)
    st["pairs"] += len(truth)
    st["found"] += m.found
    st["false"] += m.false
    st["errors"].extend(m.errors_m)


def score_tdoas(truth: Truth, tdoas: list[tuple[int, int, float, float]], st: dict) -> None:
    """|error| of each TDOA ``(i, j, tau, t)`` at its own time ``t`` (arrival at sensor i),
    against the true direct-path TDOAs of its pair, when one lies within 1 ms."""
    for i, j, tau, t in tdoas:
        e = np.abs(truth.tdoas(t, i, j) - tau)
        st["tdoas"] += 1
        if e.min() <= GATE_TDOA_S:
            st["tdoa_err_us"].append(float(e.min()) * 1e6)


#: Extra ``fusion localize`` options of the project's runs (``--project-options``: ablations).
PROJECT_OPTIONS: list[str] = []


def run_project(folder: Path, audio_path: Path, sensors, sea_floor_z):
    """``fusion localize`` as a user runs it (its defaults; ``--sea-floor-z-m`` when given) on
    the written files: per window (t_start, t_end, sources, flagged, valid TDOAs with t)."""
    import contextlib
    import io

    from fusion.cli import main as fusion_main

    out = folder / "project.json"
    argv = ["localize", "--audio", str(audio_path), "--array", str(folder / "array.json"),
            "--out", str(out), "--quiet"]
    if sea_floor_z is not None:
        argv += ["--sea-floor-z-m", repr(sea_floor_z)]
    argv += PROJECT_OPTIONS
    with contextlib.redirect_stderr(io.StringIO()):
        if fusion_main(argv) != 0:
            raise SystemExit(f"fusion localize failed on {audio_path}")
    rows = []
    for w in read_json(out)["windows"]:
        every = w["sources"]
        srcs = [[s["x"], s["y"], s["z"]] for s in every
                if s.get("observable", True) and not s.get("mirror_ambiguous", False)]
        valid = [(d["pair"][0], d["pair"][1], d["tau"], d["t"]) for d in w["tdoas"] if d["valid"]]
        rows.append((w["t_start"], w["t_end"], srcs, len(every) - len(srcs), valid))
    return rows


def run_baseline(folder: Path, audio_path: Path, sensors, sea_floor_z):
    """The baseline: per window (t_start, t_end, sources, 0, candidate TDOAs at the centre)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from click_baseline import localize_recording

    audio, fs = read_audio(audio_path, n_channels=sensors.n_sensors)
    res = localize_recording(audio, fs, sensors.positions, sensors.sound_speed,
                             sea_floor_z=sea_floor_z)
    return [(w["t_start"], w["t_end"], w["sources"], 0,
             [(i, j, tau, 0.5 * (w["t_start"] + w["t_end"]))
              for (i, j), taus in w["tdoas"].items() for tau in taus])
            for w in res]


RUNNERS = {"project": run_project, "baseline": run_baseline}


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=seeds_arg, required=True,
                    help="seeds, e.g. 7100-7109 or 0,3,5 (0-9: the baseline's tuning seeds)")
    ap.add_argument("--whales", type=int, default=None, help="whales (default: the simulator's)")
    ap.add_argument("--sensors", type=int, default=None, help="sensors (default: the simulator's)")
    ap.add_argument("--snr-db", type=float, default=None, help="SNR (default: the simulator's)")
    ap.add_argument("--duration-s", type=float, default=None,
                    help="recording length, s (default: the simulator's)")
    ap.add_argument("--echo", choices=("none", "surface", "bottom", "both"), default=None,
                    help="echo paths (default: the simulator's)")
    ap.add_argument("--vary", action="store_true", help="the simulator's varied scenarios")
    ap.add_argument("--vary-only", default=None, metavar="GROUPS",
                    help="vary only these effects (fusion simulate clicks --vary-only), e.g. "
                         "sound-speed or click-shape")
    ap.add_argument("--methods", default="project,baseline",
                    help="comma list of project, baseline")
    ap.add_argument("--sea-floor", choices=("none", "deepest"), default="none",
                    help="sea floor handed to both methods: unknown (default, as fusion "
                         "localize's default) or at the deepest hydrophone")
    ap.add_argument("--project-options", default="", metavar="'OPTS'",
                    help="extra fusion localize options of the project's runs, e.g. "
                         "'--replica generic' or '--max-tdoa-rate 0' (ablations)")
    ap.add_argument("--out", type=Path, default=None, help="JSON lines file to append to")
    args = ap.parse_args(argv)
    PROJECT_OPTIONS[:] = args.project_options.split()
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        ap.error(f"--methods: unknown {bad}; choose from {', '.join(METHODS)}")
    options = {k: v for k, v in (("duration_s", args.duration_s), ("n_sources", args.whales),
                                 ("n_sensors", args.sensors), ("snr_db", args.snr_db),
                                 ("echo", args.echo)) if v is not None}
    if args.vary:
        options["vary"] = True
    if args.vary_only:
        options["vary_only"] = tuple(g.strip() for g in args.vary_only.split(","))

    stats = {m: {"found": 0, "pairs": 0, "reported": 0, "false": 0, "flagged": 0,
                 "errors": [], "windows": 0, "cpu_s": 0.0, "tdoas": 0, "tdoa_err_us": []}
             for m in methods}
    whales, snrs = set(), []
    for seed in args.seeds:
        with tempfile.TemporaryDirectory(prefix="bench_baseline_") as tmp:
            folder = Path(tmp)
            write_recording(folder, seed, options)
            sensors = read_array(folder / "array.json")
            audio_path = next(folder / n for n in ("audio.flac", "audio.wav")
                              if (folder / n).exists())  # > 8 channels: WAV
            doc = read_json(folder / "truth.json")
            truth = Truth(doc)
            whales.add(len(doc["sources"]))
            snrs.append(doc["snr_db"])
            floor = (float(np.min(sensors.positions[:, 2])) if args.sea_floor == "deepest"
                     else None)
            for m in methods:
                st = stats[m]
                with threadpool_limits(1):
                    t0 = time.process_time()
                    windows = RUNNERS[m](folder, audio_path, sensors, floor)
                    st["cpu_s"] += time.process_time() - t0
                for t_start, t_end, srcs, flagged, tdoas in windows:
                    t_mid = 0.5 * (t_start + t_end)
                    st["windows"] += 1
                    st["flagged"] += flagged
                    score_window(truth.positions(t_mid), srcs, st)
                    score_tdoas(truth, tdoas, st)
    lines = []
    seeds = args.seeds
    seed_text = (f"{seeds[0]}-{seeds[-1]}" if seeds == list(range(seeds[0], seeds[-1] + 1))
                 else ",".join(map(str, seeds)))
    snr_set = sorted({s for s in snrs}, key=lambda v: (v is None, v))
    for m in methods:
        st = stats[m]
        line = {
            "method": m, "seeds": seed_text, "whales": sorted(whales),
            "snr_db": snr_set[0] if len(snr_set) == 1 else snr_set,
            "echo": args.echo or "default", "vary": bool(args.vary), "vary_only": args.vary_only,
            "duration_s": args.duration_s, "sea_floor": args.sea_floor,
            **({"project_options": args.project_options}
               if m == "project" and args.project_options else {}),
            "windows": st["windows"],
            "within_10m_pct": round(100.0 * st["found"] / max(st["pairs"], 1), 1),
            "false_sources_pct": round(100.0 * st["false"] / max(st["reported"], 1), 1),
            "reported": st["reported"], "flagged": st["flagged"],
            "median_error_m": (round(float(np.median(st["errors"])), 3) if st["errors"]
                               else None),
            "cpu_s_per_window": round(st["cpu_s"] / max(st["windows"], 1), 3),
            "median_tdoa_error_us": (round(float(np.median(st["tdoa_err_us"])), 2)
                                     if st["tdoa_err_us"] else None),
            "tdoas_within_1ms": round(len(st["tdoa_err_us"]) / max(st["tdoas"], 1), 3),
            "tdoas": st["tdoas"],
        }
        lines.append(line)
        text = json.dumps(line)
        print(text, flush=True)
        if args.out is not None:
            with open(args.out, "a", encoding="utf-8") as fh:  # append, never overwrite
                fh.write(text + "\n")
    return lines


if __name__ == "__main__":
    main()
