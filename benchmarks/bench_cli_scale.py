"""Benchmark of ``fusion track``, ``crossings``, ``smooth`` and ``tqi`` at two input sizes each.

Writes inputs of two sizes per command, runs each command as a subprocess (``nice -n 5``,
``OPENBLAS_NUM_THREADS=1``, ``--timeout`` seconds at most per run) and reports per run the wall
time and the peak resident memory of the command (GNU ``time``'s ``%M``), and per command
the growth from the smaller to the larger size::

    time_growth = (wall_large / wall_small) / (rows_large / rows_small)

(1: linear; 2: twice the time per row at the larger size); ``rss_growth`` likewise for memory.
Interpreter start-up and imports (``fusion --help``-like overhead, about 1-2 s) are in the wall
times, so small runs flatter the growth a little; ``base_s`` (the run of a one-row input of the
same kind) is reported so it can be subtracted (``time_growth_net``).

Inputs:

* ``track``: detections of varied multistatic runs (:func:`fusion.simulate.multistatic.
  simulate_multistatic` with ``vary=True``), pings added until the count is reached, cut at a
  whole ping; sizes ``--detections`` (10,000 and 100,000).
* ``crossings`` and ``smooth``: one bearing scenario of ``max(tracks)`` tracks and
  ``max(samples)`` samples 10 s apart (:func:`fusion.simulate.bearings.simulate_bearings`, 0.5 deg
  noise, crossings, near misses and parallel pairs); smaller inputs are its first tracks and
  first samples, so all sizes share one picture. ``--bearings`` sizes ``TRACKSxSAMPLES`` (200x200
  and 200x2000 for both; ``--smooth-extra`` 1x2000 and 25x2000 for ``smooth``: growth in the
  number of tracks at a fixed length).
* ``tqi``: tracker amplitudes and residuals of the same shapes (per-cell SNR drawn per track
  between -5 and 15 dB, :func:`fusion.simulate.amplitudes.draw_amplitudes`).

The machine's load average before and after is reported beside the times (2 cores shared).

Seeds: nothing is tuned here; ``--seed`` (default 7300, a report seed) draws the scenarios.

Usage::

    nice -n 5 env OPENBLAS_NUM_THREADS=1 python benchmarks/bench_cli_scale.py --timeout 600
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fusion.io import read_table, write_table

ROOT = Path(__file__).resolve().parents[1]
TIME = "/usr/bin/time"  # GNU time: the peak memory of the command itself
PERIOD_S = 10.0


def _size(text: str) -> tuple[int, int]:
    tracks, samples = text.lower().split("x")
    return int(tracks), int(samples)


def write_detections(path: Path, *, n: int, seed: int) -> int:
    """At least `n` detections of one varied multistatic run, cut at a whole ping; the count."""
    from fusion.simulate.multistatic import simulate_multistatic

    n_pings = 64
    while True:
        sc = simulate_multistatic(seed=seed, vary=True, n_pings=n_pings)
        d = sc.detections.columns
        if len(d["event"]) >= n:
            break
        n_pings = int(n_pings * 1.3 * n / len(d["event"])) + 1
    last = d["event"][n - 1]
    keep = d["event"] <= last
    cols = ("event", "time", "x", "y", "snr_db", "score", "aspect_deg", "src_x", "src_y",
            "rcv_x", "rcv_y")
    write_table(path, {k: d[k][keep] for k in cols})
    return int(keep.sum())


def write_bearing_scenario(path: Path, *, tracks: int, samples: int, seed: int) -> None:
    """The largest bearing scenario: `tracks` tracks of `samples` samples, rows by time."""
    from fusion.simulate.bearings import simulate_bearings

    sc = simulate_bearings(
        seed=seed, n_tracks=tracks, duration_s=(samples - 1) * PERIOD_S,
        sample_period_s=PERIOD_S, n_crossing_pairs=max(1, tracks // 8),
        n_wrap_crossings=max(1, tracks // 40), n_near_miss_pairs=max(1, tracks // 16),
        n_parallel_pairs=max(0, tracks // 16))
    write_table(path, {"track_id": sc.track_id, "time": sc.time, "bearing_deg": sc.bearing_deg})


def subset(big: Path, path: Path, *, tracks: int, samples: int) -> int:
    """The first `tracks` tracks and `samples` samples of each of `big` (rows kept in order)."""
    t = read_table(big, required=("track_id", "time", "bearing_deg"), integer=("track_id",))
    ids = np.unique(t["track_id"][t["track_id"] >= 0])[:tracks]
    keep = np.isin(t["track_id"], ids)
    t0 = t["time"].min()
    keep &= t["time"] < t0 + (samples - 0.5) * PERIOD_S
    write_table(path, {k: v[keep] for k, v in t.columns.items()})
    return int(keep.sum())


def write_amplitudes(path: Path, *, tracks: int, samples: int, seed: int) -> int:
    """Tracker amplitudes/residuals of `tracks` tracks x `samples` updates, rows by time."""
    from fusion.simulate.amplitudes import draw_amplitudes, draw_residuals

    rng = np.random.default_rng(seed)
    level = rng.uniform(-5.0, 15.0, size=tracks)
    snr = level[None, :] + 3.0 * np.sin(np.linspace(0, 6, samples))[:, None]
    amp = draw_amplitudes(snr, rng=rng)
    res = draw_residuals(snr, rng=rng)
    tid = np.tile(np.arange(tracks), samples)
    time_s = np.repeat(np.arange(samples) * 1.0, tracks)
    write_table(path, {"track_id": tid, "time": time_s, "amplitude": amp.ravel(),
                       "residual": res.ravel()})
    return tracks * samples


def run_command(argv: list[str], *, timeout_s: float) -> dict:
    """Run ``python -m fusion ARGV`` niced; wall time, peak RSS (MB), exit status.

    The peak resident set is that of the command's process, read by GNU ``time`` (``%M``): a
    process forked from this one would report this interpreter's memory before its exec.
    """
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    with tempfile.NamedTemporaryFile(suffix=".rss") as rss_file:
        cmd = [TIME, "-f", "%M", "-o", rss_file.name, "nice", "-n", "5", sys.executable, "-m",
               "fusion", *argv]
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, start_new_session=True)
        status = "ok"
        try:
            _, err = proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            _, err = proc.communicate()
            status = "timeout"
        wall = time.perf_counter() - t0
        text = Path(rss_file.name).read_text().split()
    rss_kb = float(text[-1]) if text and text[-1].isdigit() else float("nan")
    err = err.decode(errors="replace").strip()
    if status == "ok" and proc.returncode != 0:
        status = f"exit {proc.returncode}: {err.splitlines()[-1] if err else ''}"
    return {"wall_s": round(wall, 2), "peak_rss_mb": round(rss_kb / 1024.0, 1), "status": status}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--detections", type=int, nargs=2, default=(10_000, 100_000))
    ap.add_argument("--bearings", type=_size, nargs=2, default=((200, 200), (200, 2000)),
                    metavar="TxS", help="crossings/smooth/tqi sizes, tracks x samples")
    ap.add_argument("--smooth-extra", type=_size, nargs=2, default=((1, 2000), (25, 2000)),
                    metavar="TxS", help="two more smooth sizes (growth with the track count)")
    ap.add_argument("--commands", nargs="+", default=["track", "crossings", "smooth", "tqi"],
                    choices=["track", "crossings", "smooth", "tqi"])
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per run")
    ap.add_argument("--seed", type=int, default=7300, help="scenario seed (report seed)")
    ap.add_argument("--workdir", type=Path, default=None,
                    help="folder for inputs and outputs (default: a temporary folder); inputs "
                         "already there are reused")
    args = ap.parse_args(argv)

    work = args.workdir or Path(tempfile.mkdtemp(prefix="bench_cli_scale-"))
    work.mkdir(parents=True, exist_ok=True)
    load_before = os.getloadavg()
    runs: dict[str, dict] = {}
    growth: dict[str, dict] = {}

    def measure(name: str, argv: list[str], rows: int) -> dict:
        r = run_command(argv, timeout_s=args.timeout)
        r["rows"] = rows
        runs[name] = r
        print(f"# {name}: {r}", file=sys.stderr, flush=True)
        return r

    def grow(name: str, small: dict, large: dict, base: dict) -> None:
        if small["status"] != "ok" or large["status"] != "ok":
            growth[name] = {"status": "incomplete"}
            return
        size = large["rows"] / small["rows"]
        net_small = max(small["wall_s"] - base["wall_s"], 1e-3)
        net_large = max(large["wall_s"] - base["wall_s"], 1e-3)
        growth[name] = {
            "size_ratio": round(size, 2),
            "time_ratio": round(large["wall_s"] / small["wall_s"], 2),
            "time_growth": round(large["wall_s"] / small["wall_s"] / size, 2),
            "time_growth_net": round(net_large / net_small / size, 2),
            "rss_ratio": round(large["peak_rss_mb"] / small["peak_rss_mb"], 2),
        }

    if "track" in args.commands:
        base_in = work / "det_base.csv"
        write_table(base_in, {"event": [0], "time": [0.0], "x": [0.0], "y": [0.0]})
        base = measure("track base (1 detection)",
                       ["track", "--detections", str(base_in), "--out", str(work / "o.csv")], 1)
        sizes = []
        for n in args.detections:
            f = work / f"det_{n}_{args.seed}.csv"
            rows = write_detections(f, n=n, seed=args.seed)
            sizes.append(measure(f"track {n}", ["track", "--detections", str(f),
                                                "--out", str(work / "o.csv")], rows))
        grow("track", sizes[0], sizes[1], base)

    bearing_sizes = list(args.bearings)
    smooth_sizes = bearing_sizes + list(args.smooth_extra)
    if {"crossings", "smooth"} & set(args.commands):
        t_max = max(t for t, _ in smooth_sizes)
        s_max = max(s for _, s in smooth_sizes)
        big = work / f"bearings_{t_max}x{s_max}_{args.seed}.csv"
        if not big.exists():
            write_bearing_scenario(big, tracks=t_max, samples=s_max, seed=args.seed)
        files = {}
        for t, s in smooth_sizes:
            f = work / f"bearings_{t}x{s}_{args.seed}.csv"
            files[(t, s)] = (f, subset(big, f, tracks=t, samples=s))
        base_in = work / "bearings_base.csv"
        n_base = 12  # the fewest samples fusion crossings accepts (J = 10 at K = 10 s)
        write_table(base_in, {"track_id": np.repeat([0, 1], n_base),
                              "time": np.tile(np.arange(n_base) * PERIOD_S, 2),
                              "bearing_deg": np.concatenate([10.0 + 0.1 * np.arange(n_base),
                                                             20.0 - 0.1 * np.arange(n_base)])})
        for cmd in ("crossings", "smooth"):
            if cmd not in args.commands:
                continue
            base = measure(f"{cmd} base (2 tracks x {n_base})",
                           [cmd, "--bearings", str(base_in), "--out", str(work / "o.csv")],
                           2 * n_base)
            sizes = {}
            for t, s in (bearing_sizes if cmd == "crossings" else smooth_sizes):
                f, rows = files[(t, s)]
                sizes[(t, s)] = measure(f"{cmd} {t}x{s}", [cmd, "--bearings", str(f), "--out",
                                                          str(work / "o.csv")], rows)
            a, b = bearing_sizes
            grow(f"{cmd} {a[0]}x{a[1]} -> {b[0]}x{b[1]}", sizes[a], sizes[b], base)
            if cmd == "smooth":
                a, b = args.smooth_extra
                grow(f"smooth {a[0]}x{a[1]} -> {b[0]}x{b[1]}", sizes[a], sizes[b], base)

    if "tqi" in args.commands:
        base_in = work / "amp_base.csv"
        write_amplitudes(base_in, tracks=1, samples=1, seed=args.seed)
        base = measure("tqi base (1 row)", ["tqi", "--amplitudes", str(base_in), "--out",
                                            str(work / "o.csv")], 1)
        sizes = []
        for t, s in bearing_sizes:
            f = work / f"amp_{t}x{s}_{args.seed}.csv"
            rows = write_amplitudes(f, tracks=t, samples=s, seed=args.seed)
            sizes.append(measure(f"tqi {t}x{s}", ["tqi", "--amplitudes", str(f), "--out",
                                                  str(work / "o.csv")], rows))
        grow("tqi", sizes[0], sizes[1], base)

    result = {"load_avg_before": [round(x, 2) for x in load_before],
              "load_avg_after": [round(x, 2) for x in os.getloadavg()],
              "timeout_s": args.timeout, "seed": args.seed, "runs": runs, "growth": growth}
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
