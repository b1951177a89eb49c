"""Click front end end to end: TDOA accuracy vs the CRB, validation, association, throughput.

Runs :class:`fusion.pipelines.clicks.ClickFrontEnd` (defaults, shipped validator) on varied
simulated recordings (:func:`fusion.pipelines.clicks.training.varied_scenario`: 1-3 whales, 3-8
sensors, SNR 12-36 dB, ICI 0.25-0.6 s with 0-20 % jitter, surface echo 0 to -0.95, 0-20
transients). Truth is used only to score.

Seeds: the shipped validator was trained on seeds 0-39 (``fusion train-validator --simulated
40``) and every setting was chosen on them; the report seeds (default 5000-5019) were never looked
at before the reported run.

Metrics (one JSON line):

* ``tdoa_rms_us`` / ``tdoa_rms_over_crb``: valid, refined TDOAs that match a true TDOA within 1 ms,
  whose measured click SNR is >= 10 dB: RMS error against the truth at the window centre, and
  the RMS of error / CRB (1 = at the bound);
* ``auc``: ROC AUC of the validation LLR over every candidate (labels: SCM delay within 3 ms of
  a true TDOA); ``alias_accept``: fraction of inter-click-interval aliases (SCM delay within 3 ms
  of a true TDOA plus or minus one or two mean ICIs, and not a true TDOA) that pass validation;
* ``precision`` / ``pairs_found``: fraction of valid TDOAs that are true; mean fraction of (window,
  pair, whale) with a valid true TDOA;
* ``cross_pair_correct``: over pairs of valid true TDOAs sharing exactly one sensor in 3-whale
  scenarios, fraction whose association decision (alpha >= 3) agrees with same-whale;
* ``x_realtime``: audio seconds per processing second for 5 channels at 96 kHz, one core,
  reading a FLAC file included, with the time of each stage.

Usage: ``python benchmarks/bench_click_frontend.py [--seeds 5000-5019] [--duration 30]``
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from sklearn.metrics import roc_auc_score
from threadpoolctl import threadpool_limits

from fusion.pipelines.clicks import ClickFrontEnd
from fusion.pipelines.clicks.training import (
    label_windows,
    scenario_labels,
    varied_scenario,
)


def seeds_arg(text: str) -> list[int]:
    """``A-B`` (inclusive) or a comma list."""
    if "-" in text:
        a, b = (int(v) for v in text.split("-"))
        return list(range(a, b + 1))
    return [int(v) for v in text.split(",")]


def score(sc, windows) -> dict:
    """Per-scenario scores against the truth."""
    labels = scenario_labels(sc)
    true = label_windows(windows, labels, tol_s=3e-3, coarse=True)
    out = {"err": [], "crb": [], "llr": [], "y": [], "alias_pass": [], "valid_true": [],
           "found": [], "cross": []}
    icis = np.array([s.ici_mean_s for s in sc.sources])
    n_src = len(sc.sources)
    for w, y in zip(windows, true, strict=True):
        mid = 0.5 * (w.t_start + w.t_end)
        found = set()
        src_of = {}
        for k, d in enumerate(w.tdoas):
            out["llr"].append(d.llr)
            out["y"].append(bool(y[k]))
            per_src = []
            for s in range(n_src):
                sel = labels.source == s
                sub = type(labels)(labels.time_s[sel], labels.i[sel], labels.j[sel],
                                   labels.tau_s[sel], labels.source[sel])
                ref = sub.tau_at(d.pair, mid, w.t_start, w.t_end)
                per_src.append(ref[0] if ref.size else np.nan)
            per_src = np.asarray(per_src)
            err = np.abs(per_src - d.tau_s)
            if not y[k]:
                alias = np.isfinite(per_src) & np.any(np.abs(
                    np.abs(d.tau_coarse_s - per_src)[:, None] - icis[:, None] * [1, 2]) < 3e-3,
                    axis=1)
                if np.any(alias):
                    out["alias_pass"].append(d.passes)
            if d.valid:
                out["valid_true"].append(bool(y[k]))
            if d.valid and y[k]:
                s = int(np.nanargmin(err))
                found.add((d.pair, s))
                src_of[k] = s
                if np.isfinite(d.crb_s) and d.snr_db >= 10.0 and err[s] < 1e-3:
                    out["err"].append(d.tau_s - per_src[s])
                    out["crb"].append(d.crb_s)
        n_possible = len(sc.pairs()) * n_src
        out["found"].append(len(found) / n_possible)
        if n_src == 3:
            for a in src_of:
                for b in src_of:
                    if a < b and len(set(w.tdoas[a].pair) & set(w.tdoas[b].pair)) == 1:
                        out["cross"].append((w.alpha[a, b] >= 3.0) == (src_of[a] == src_of[b]))
    return out


def throughput(duration_s: float, seed: int) -> dict:
    """x real time of read + front end on a 5-channel 96 kHz FLAC, one core, stage times."""
    import soundfile as sf

    from fusion.simulate.clicks import simulate_clicks, write_click_scenario

    sc = simulate_clicks(seed=seed, n_sensors=5, n_sources=3, duration_s=duration_s,
                         snr_db=25.0)
    with tempfile.TemporaryDirectory() as tmp:
        write_click_scenario(tmp, sc)
        path = str(Path(tmp) / "audio.flac")
        fe = ClickFrontEnd()
        with threadpool_limits(1):
            t0 = time.process_time()
            blocks = list(sf.blocks(path, blocksize=int(2 * sc.fs), dtype="float32",
                                    always_2d=True))
            t_read = time.process_time() - t0
            t0 = time.process_time()
            fe.detector.detect(np.concatenate(blocks), sc.fs)
            t_detect = time.process_time() - t0
            t0 = time.process_time()
            stream = ((k * 2.0, b) for k, b in enumerate(
                sf.blocks(path, blocksize=int(2 * sc.fs), dtype="float32", always_2d=True)))
            n = len(list(fe.iter_windows(stream, fs=sc.fs, sensors=sc.sensors,
                                         duration_s=duration_s)))
            t_all = time.process_time() - t0
    return {"x_realtime": round(duration_s / t_all, 1), "windows": n,
            "seconds_total": round(t_all, 2), "seconds_flac_read": round(t_read, 2),
            "seconds_detect": round(t_detect, 2),
            "seconds_scm_validate_refine_associate": round(t_all - t_read - t_detect, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=seeds_arg, default=seeds_arg("5000-5019"))
    ap.add_argument("--duration", type=float, default=30.0, help="s per scenario")
    ap.add_argument("--speed-duration", type=float, default=60.0, help="s of the speed run")
    args = ap.parse_args()
    fe = ClickFrontEnd()
    agg: dict[str, list] = {}
    for seed in args.seeds:
        sc = varied_scenario(seed, duration_s=args.duration)
        windows = fe.run_array(sc.audio, sc.fs, sc.sensors)
        for k, v in score(sc, windows).items():
            agg.setdefault(k, []).extend(v)
    err, crb = np.asarray(agg["err"]), np.asarray(agg["crb"])
    y, llr = np.asarray(agg["y"]), np.asarray(agg["llr"])
    res = {
        "scenarios": len(args.seeds), "seeds": f"{args.seeds[0]}-{args.seeds[-1]}",
        "candidates": int(y.size), "tdoas_scored": int(err.size),
        "tdoa_rms_us": round(float(np.sqrt(np.mean(err**2))) * 1e6, 3),
        "tdoa_rms_crb_us": round(float(np.sqrt(np.mean(crb**2))) * 1e6, 3),
        "tdoa_rms_over_crb": round(float(np.sqrt(np.mean((err / crb) ** 2))), 3),
        "tdoa_median_abs_us": round(float(np.median(np.abs(err))) * 1e6, 3),
        "auc": round(float(roc_auc_score(y, np.nan_to_num(llr, nan=-1e9))), 4),
        "alias_candidates": len(agg["alias_pass"]),
        "alias_accept": round(float(np.mean(agg["alias_pass"])), 4) if agg["alias_pass"] else None,
        "precision": round(float(np.mean(agg["valid_true"])), 4),
        "pairs_found": round(float(np.mean(agg["found"])), 4),
        "cross_pair_tested": len(agg["cross"]),
        "cross_pair_correct": round(float(np.mean(agg["cross"])), 4) if agg["cross"] else None,
    }
    res.update(throughput(args.speed_duration, seed=args.seeds[0]))
    print(json.dumps(res))


if __name__ == "__main__":
    main()
