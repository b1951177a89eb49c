"""Benchmark of ``fusion localize`` on long recordings: speed, peak memory, Dask, resume.

Writes long 5-channel 96 kHz FLAC recordings without holding them in memory (one simulated
scenario of ``--base-s`` seconds, :func:`fusion.simulate.clicks.simulate_clicks`, repeated and
written block by block with ``soundfile.SoundFile``; the repeat is the only thing the audio
does not show), then runs ``fusion localize`` on each as a subprocess, serially (the default)
and with ``--workers N`` (a local Dask cluster), and reports per run:

* ``wall_s`` and ``x_real_time`` (audio duration over wall time; the Dask cluster's start-up
  included);
* ``cpu_s`` (user + system CPU time of the run and the processes it waited for: its Dask
  workers) and ``x_real_time_cpu`` (audio duration over ``cpu_s`` divided by the workers, at
  least 1: the speed on that many unshared cores); the 2 cores of the machine are shared, so
  CPU time says more than wall time under load;
* ``peak_rss_mb``: the largest resident set of any one process of the run (``wait4``'s
  ``ru_maxrss``: the command itself when serial, the largest worker with Dask);
* ``peak_total_rss_mb``: the sum over the run's process tree, sampled every 0.1 s (psutil);
* whether the outputs of the serial and Dask runs of one recording are byte-identical.

Then, on the shortest recording, a serial run killed (SIGKILL) once about a third of its chunks
are recorded and run again: ``resume_identical`` says whether the result is byte-identical to the
uninterrupted run. ``memory_ratio`` is the serial peak of the longest recording over that of the
shortest (streaming: about 1). The machine's load average is reported beside the times (the 2
cores are shared).

Seeds: nothing here is tuned; ``--seed`` (default 1000, a report seed) draws the scenario.

Usage::

    python benchmarks/bench_localize_scale.py --minutes 10 60 --workers 2
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import psutil
import soundfile as sf

from fusion.io import write_array
from fusion.simulate.clicks import FILE_PEAK, simulate_clicks

ROOT = Path(__file__).resolve().parents[1]


def write_long_recording(path: Path, array_path: Path, *, minutes: float, base_s: float,
                         seed: int, block_s: float = 10.0) -> float:
    """Write `minutes` of 5-channel audio (one scenario repeated) block by block; its seconds.

    A file already there with that length (and its array) is kept: its name carries the seed
    and scenario length, which make the same audio.
    """
    total_s = minutes * 60.0
    if path.exists() and array_path.exists() and sf.info(str(path)).frames == int(round(
            total_s * 96000.0)):
        return sf.info(str(path)).frames / 96000.0
    sc = simulate_clicks(seed=seed, n_sensors=5, n_sources=2, duration_s=base_s)
    write_array(array_path, sc.sensors)
    scale = np.float32(FILE_PEAK / float(np.max(np.abs(sc.audio))))
    base = sc.audio * scale
    total = int(round(minutes * 60.0 * sc.fs))
    block = int(round(block_s * sc.fs))
    with sf.SoundFile(str(path), "w", samplerate=int(sc.fs), channels=base.shape[1],
                      format="FLAC", subtype="PCM_24") as f:
        done = 0
        while done < total:
            a = done % base.shape[0]
            n = min(block, base.shape[0] - a, total - done)
            f.write(base[a:a + n])
            done += n
    return total / sc.fs


def run_localize(audio: Path, array: Path, out: Path, extra: list[str],
                 kill_after_parts: int | None = None) -> dict:
    """Run ``fusion localize`` as a subprocess; wall time and peak memory (or kill it)."""
    cmd = [sys.executable, "-m", "fusion", "localize", "--audio", str(audio), "--array",
           str(array), "--out", str(out), "--quiet", *extra]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    total_peak = 0
    stop = threading.Event()

    def sample() -> None:
        nonlocal total_peak
        parent = psutil.Process(proc.pid)
        while not stop.is_set():
            try:
                procs = [parent, *parent.children(recursive=True)]
                total_peak = max(total_peak, sum(p.memory_info().rss for p in procs))
            except psutil.Error:
                pass
            if kill_after_parts is not None:
                parts = list(Path(f"{out}.parts").glob("*/chunk-*.json"))
                if len(parts) >= kill_after_parts:
                    proc.send_signal(signal.SIGKILL)
                    return
            stop.wait(0.1)

    watcher = threading.Thread(target=sample, daemon=True)
    watcher.start()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    stop.set()
    watcher.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode() if proc.stderr else ""
    return {"returncode": proc.returncode, "wall_s": round(wall, 2),
            "cpu_s": round(usage.ru_utime + usage.ru_stime, 2),
            "peak_rss_mb": round(usage.ru_maxrss / 1024.0, 1),
            "peak_total_rss_mb": round(total_peak / 2**20, 1), "stderr": err.strip()[-300:]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[10.0, 60.0],
                    help="recording lengths, minutes (default 10 60)")
    ap.add_argument("--base-s", type=float, default=60.0, help="simulated scenario repeated, s")
    ap.add_argument("--seed", type=int, default=1000, help="scenario seed (report seed)")
    ap.add_argument("--workers", type=int, default=2, help="Dask workers of the parallel runs")
    ap.add_argument("--modes", nargs="+", choices=("serial", "workers"),
                    default=["serial", "workers"], help="runs per recording")
    ap.add_argument("--chunk", type=float, default=60.0, help="--chunk-s of fusion localize, s")
    ap.add_argument("--no-resume", action="store_true", help="skip the kill + rerun check")
    ap.add_argument("--localize-args", default="",
                    help="extra options of fusion localize, one string (e.g. '--no-refine')")
    ap.add_argument("--folder", type=Path, default=None,
                    help="work folder, kept (default: a temporary one, removed at the end); "
                         "recordings already in it are reused")
    args = ap.parse_args()
    work = args.folder or Path(tempfile.mkdtemp(prefix="bench-localize-scale-"))
    work.mkdir(parents=True, exist_ok=True)
    extra = [*args.localize_args.split(), "--chunk-s", str(args.chunk)]
    runs, identical = [], {}
    try:
        recordings = []
        for minutes in sorted(args.minutes):
            tag = f"seed{args.seed}_base{args.base_s:g}s"
            audio = work / f"rec_{minutes:g}min_{tag}.flac"
            array = work / f"array_{tag}.json"
            t0 = time.perf_counter()
            dur = write_long_recording(audio, array, minutes=minutes, base_s=args.base_s,
                                       seed=args.seed)
            recordings.append((minutes, audio, array, dur, time.perf_counter() - t0))
        for minutes, audio, array, dur, t_write in recordings:
            outs = {}
            for mode in args.modes:
                out = work / f"r_{minutes:g}min_{mode}.json"
                more = ["--workers", str(args.workers)] if mode == "workers" else []
                r = run_localize(audio, array, out, extra + more)
                r.update(minutes=minutes, mode=mode, workers=args.workers if more else 0,
                         x_real_time=round(dur / r["wall_s"], 2),
                         x_real_time_cpu=round(dur * max(1, args.workers if more else 1)
                                               / max(r["cpu_s"], 1e-9), 2),
                         write_s=round(t_write, 1),
                         flac_mb=round(audio.stat().st_size / 2**20, 1),
                         load_avg=[round(v, 2) for v in os.getloadavg()])
                if r["returncode"] == 0:
                    r.pop("stderr")
                    outs[mode] = out.read_bytes()
                runs.append(r)
                print(json.dumps(r), file=sys.stderr, flush=True)  # partial results survive
            if len(outs) == 2:
                identical[f"{minutes:g}min"] = outs["serial"] == outs["workers"]
        result: dict = {"benchmark": "localize_scale", "seed": args.seed, "fs_hz": 96000,
                        "channels": 5, "chunk_s": args.chunk, "localize_args": args.localize_args,
                        "cpu_count": os.cpu_count(), "runs": runs,
                        "serial_equals_workers": identical}
        serial = [r for r in runs if r["mode"] == "serial" and r["returncode"] == 0]
        if len(serial) >= 2:
            result["memory_ratio"] = round(serial[-1]["peak_rss_mb"] / serial[0]["peak_rss_mb"], 3)
        if not args.no_resume and serial:
            minutes, audio, array, dur, _ = recordings[0]
            out = work / "r_resume.json"
            n_chunks = max(1, int(round(dur / args.chunk)))
            killed = run_localize(audio, array, out, extra,
                                  kill_after_parts=max(1, n_chunks // 3))
            parts = len(list(Path(f"{out}.parts").glob("*/chunk-*.json")))
            again = run_localize(audio, array, out, extra)
            ref = (work / f"r_{minutes:g}min_serial.json").read_bytes()
            result["resume"] = {"minutes": minutes, "killed_returncode": killed["returncode"],
                                "parts_at_kill": parts, "chunks": n_chunks,
                                "rerun_wall_s": again["wall_s"],
                                "resume_identical": out.exists() and out.read_bytes() == ref}
        print(json.dumps(result))
    finally:
        if args.folder is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
