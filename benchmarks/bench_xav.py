"""Benchmark: localize the 34 XAV large-array detections against the authors' published intervals.

The recording (6 hydrophones on a 1.7 m frame, fish sounds 1-1.5 m from its centre; ``shared/
realdata/xav_large_array``) is read as the six mono files it ships as, and the 34 detections of
``reference_localizations_from_published_notebook.csv`` (their start/end times and frequency
boxes) go through ``fusion localize --events`` (:func:`fusion.commands.localize_events.
run_events`) with its defaults: no tuning option is set. Metrics:

* ``kept_inside``: of the 12 localizations the authors kept, how many of ours lie inside their
  3-D uncertainty box on all three axes (target >= 10); ``kept_inside_estimated_band`` the same
  with the frequency boxes withheld (each event's band estimated from the data);
* per kept event, the distance of our estimate from the box centre, and our 95 % half-widths
  against the authors' half-widths (medians);
* over all 34: observable fixes, fixes inside the search box, surface agreements, TDOA-fit RMS.

No randomness: the result is deterministic (no seeds). ``--table`` writes a markdown table of all
34 events (estimate, 95 % interval, covariance, fit, flags, reference box).

Usage::

    python benchmarks/bench_xav.py --table xav_events.md
"""

from __future__ import annotations

import argparse
import csv
import json
import logging
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _realdata import REALDATA  # noqa: E402

from fusion.commands.localize_events import add_event_options, run_events  # noqa: E402

REFERENCE = "reference_localizations_from_published_notebook.csv"


def _events_csv(rows: list[dict], path: Path, *, bands: bool) -> None:
    with path.open("w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["t_start", "t_end"] + (["f_low", "f_high"] if bands else []))
        for r in rows:
            out.writerow([r["time_min_offset_s"], r["time_max_offset_s"]]
                         + ([r["frequency_min_hz"], r["frequency_max_hz"]] if bands else []))


def _run(data: Path, rows: list[dict], work: Path, *, bands: bool) -> list[dict]:
    """The result events of ``fusion localize --events`` with default options."""
    events = work / ("events.csv" if bands else "events_noband.csv")
    out = work / ("result.json" if bands else "result_noband.json")
    _events_csv(rows, events, bands=bands)
    files = sorted((data / "data").glob("AMAR173.*.wav"), key=lambda p: int(p.name.split(".")[1]))
    parser = argparse.ArgumentParser()
    add_event_options(parser)
    args = parser.parse_args([])  # the defaults: no tuning
    args.audio, args.array, args.events, args.out = files, data / "array.json", events, out
    run_events(args)
    return json.loads(out.read_text())["events"]


def _box(r: dict) -> np.ndarray | None:
    """The authors' interval, shape (3, 2) m, or None."""
    if not r["x_err_low_m"]:
        return None
    return np.array([[float(r[f"{a}_err_low_m"]), float(r[f"{a}_err_high_m"])] for a in "xyz"])


def _inside(e: dict, box: np.ndarray) -> bool:
    p = [e["x"], e["y"], e["z"]]
    return all(v is not None and lo <= v <= hi for v, (lo, hi) in zip(p, box, strict=True))


def _fmt(v: float | None, digits: int = 2) -> str:
    if v is None:
        return "-"
    return f"{v:.{digits}f}" if abs(v) < 1e4 else f"{v:.2e}"  # diverged far-field solves


def _flag(v: bool | None) -> str:
    return "-" if v is None else ("yes" if v else "no")


def _table(rows: list[dict], events: list[dict], path: Path) -> None:
    lines = [
        "| # | t (s) | band (Hz) | x, y, z (m) | 95 % interval x; y; z (m) | "
        "cov xx, yy, zz, xy, xz, yz (m^2) | fit RMS (us) | used | obs | surf | kept | "
        "authors' box x; y; z (m) | inside |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r, e in zip(rows, events, strict=True):
        iv = "; ".join(f"{_fmt(e['interval_95'][a][0])}..{_fmt(e['interval_95'][a][1])}"
                       for a in "xyz")
        c = e["cov"]
        cov = ", ".join(_fmt(c[i][j], 4) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2),
                                                        (1, 2)))
        box = _box(r)
        ref = "-" if box is None else "; ".join(f"{lo:.2f}..{hi:.2f}" for lo, hi in box)
        inside = "-" if box is None else ("yes" if _inside(e, box) else "no")
        rms = e["residual_rms_s"]
        lines.append(
            f"| {r['detection_index']} | {e['t_start']:.2f}-{e['t_end']:.2f} | "
            f"{e['f_low']:.0f}-{e['f_high']:.0f} | "
            f"{_fmt(e['x'])}, {_fmt(e['y'])}, {_fmt(e['z'])} | {iv} | {cov} | "
            f"{_fmt(None if rms is None else rms * 1e6, 0)} | {e['tdoas_used']} | "
            f"{'yes' if e['observable'] else 'no'} | {_flag(e['surface_agrees'])} | "
            f"{'yes' if r['kept_by_notebook_filter'] == 'True' else 'no'} | {ref} | {inside} |")
    path.write_text("\n".join(lines) + "\n")


def main() -> None:
    """Run the benchmark; print one JSON line."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=REALDATA / "xav_large_array",
                    help="the xav_large_array folder (default: from FUSION_REALDATA or "
                         "../shared/realdata)")
    ap.add_argument("--table", type=Path, default=None,
                    help="write a markdown table of all 34 events here")
    opts = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    rows = list(csv.DictReader((opts.data / REFERENCE).open()))
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        events = _run(opts.data, rows, Path(tmp), bands=True)
        seconds = time.perf_counter() - t0
        noband = _run(opts.data, rows, Path(tmp), bands=False)
    kept = [k for k, r in enumerate(rows) if r["kept_by_notebook_filter"] == "True"]
    boxes = {k: _box(rows[k]) for k in kept}
    dist, ratio = [], []
    for k in kept:
        e, box = events[k], boxes[k]
        dist.append(float(np.linalg.norm(np.array([e["x"], e["y"], e["z"]]) - box.mean(axis=1))))
        ours = np.array([(e["interval_95"][a][1] - e["interval_95"][a][0]) / 2 for a in "xyz"])
        ratio.append(ours / ((box[:, 1] - box[:, 0]) / 2))
    rms = [e["residual_rms_s"] for e in events if e["residual_rms_s"] is not None]
    if opts.table is not None:
        _table(rows, events, opts.table)
    print(json.dumps({
        "events": len(events),
        "kept": len(kept),
        "kept_inside": sum(_inside(events[k], boxes[k]) for k in kept),
        "kept_inside_estimated_band": sum(_inside(noband[k], boxes[k]) for k in kept),
        "kept_distance_to_box_centre_m_median": round(float(np.median(dist)), 3),
        "kept_distance_to_box_centre_m_max": round(float(np.max(dist)), 3),
        "kept_halfwidth_ratio_xyz_median": np.round(np.median(ratio, axis=0), 2).tolist(),
        "observable": sum(e["observable"] for e in events),
        "in_search_box": sum(e["in_region"] for e in events),
        "surface_agrees": sum(bool(e["surface_agrees"]) for e in events),
        "kept_fit_rms_us_median": round(float(np.median(
            [events[k]["residual_rms_s"] for k in kept])) * 1e6, 1),
        "all_fit_rms_us_median": round(float(np.median(rms)) * 1e6, 1),
        "seconds_34_events": round(seconds, 2),
        "table": None if opts.table is None else str(opts.table),
    }))


if __name__ == "__main__":
    main()
