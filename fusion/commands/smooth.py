"""``fusion smooth --bearings B.csv --out S.csv``: bearing-rate smoothing on factor graphs.

Rows with ``track_id >= 0`` are smoothed track by track (batch Levenberg-Marquardt); rows with
``track_id`` -1 are detections of unknown origin, formed into tracks and smoothed jointly through
crossings (:class:`fusion.passive.smoothing.MultiTrackSmoother`). Rows out of time order are
sorted (one warning); two rows of one labelled track at the same time are an error. Output
(``docs/formats.md``, section 7):
``track_id,time,bearing_deg,bearing_rate_deg_per_min,sigma_bearing_deg``, bearings in [0, 360)
when every input bearing is >= 0, else in [-180, 180).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from fusion.cli import number
from fusion.geometry import wrap_angle
from fusion.io import read_bearings, write_table
from fusion.passive.smoothing import BearingSmoother, MultiTrackSmoother, smooth_bearings

logger = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``smooth`` subcommand."""
    p = sub.add_parser(
        "smooth",
        help="smooth bearing tracks (labelled, or detections of unknown origin)",
        description="Bearing-rate smoothing on factor graphs; track_id -1 rows are detections "
        "of unknown origin, tracked and smoothed jointly through crossings.",
    )
    p.add_argument("--bearings", type=Path, required=True, help="input CSV track_id,time,bearing_deg")
    p.add_argument("--out", type=Path, required=True, help="output CSV")
    p.add_argument("--sigma-bearing-deg", type=number(float, gt=0), default=0.5,
                   help="bearing measurement standard deviation, deg (default 0.5)")
    p.add_argument("--q-deg2-per-s3", type=number(float, gt=0), default=3e-6,
                   help="bearing acceleration PSD, deg^2/s^3 (default 3e-6)")
    p.add_argument("--robust", choices=("none", "huber", "cauchy"), default="huber",
                   help="loss on the bearing factors of labelled tracks (default huber)")
    p.add_argument("--clutter-density", type=number(float, gt=0), default=0.1,
                   help="false detections per scan per radian (default 0.1)")
    p.add_argument("--p-detect", type=number(float, gt=0, le=1), default=0.9,
                   help="probability that a track is detected in a scan, (0, 1] (default 0.9)")
    p.add_argument("--min-length", type=number(int, ge=2), default=5,
                   help="fewest detections of a track formed from unknown-origin rows, >= 2 "
                        "(default 5)")
    p.set_defaults(handler=run, inputs=("bearings",))


def run(args: argparse.Namespace) -> int:
    """Read, smooth, write."""
    table = read_bearings(args.bearings)
    ids, times = table["track_id"], table["time"]
    short = [int(k) for k in np.unique(ids[ids >= 0]) if np.unique(times[ids == k]).size < 2]
    if short:
        listed = ", ".join(map(str, short[:5])) + (", ..." if len(short) > 5 else "")
        raise ValueError(f"{args.bearings}: track(s) {listed} have fewer than 2 distinct times; "
                         "a bearing rate needs at least 2 samples per track")
    sigma = np.radians(args.sigma_bearing_deg)
    q = args.q_deg2_per_s3 * np.radians(1.0) ** 2
    single = BearingSmoother(sigma_bearing=sigma, q=q, robust=args.robust)
    multi = MultiTrackSmoother(sigma_bearing=sigma, q=q, clutter_density=args.clutter_density,
                               p_detect=args.p_detect, min_length=args.min_length)
    bearing_deg = table["bearing_deg"]
    tracks = smooth_bearings(table["track_id"], table["time"], np.radians(bearing_deg),
                             single=single, multi=multi)
    to_360 = bool(np.all(bearing_deg >= 0))
    cols: dict[str, list[np.ndarray]] = {k: [] for k in (
        "track_id", "time", "bearing_deg", "bearing_rate_deg_per_min", "sigma_bearing_deg")}
    for tr in tracks:
        b = np.degrees(tr.bearing)
        cols["track_id"].append(np.full(len(tr), tr.track_id, np.int64))
        cols["time"].append(tr.times)
        cols["bearing_deg"].append(np.mod(b, 360.0) if to_360 else b)
        cols["bearing_rate_deg_per_min"].append(np.degrees(tr.rate) * 60.0)
        cols["sigma_bearing_deg"].append(np.degrees(tr.sigma_bearing))
    out = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in cols.items()}
    write_table(args.out, out)
    logger.info("wrote %d tracks to %s", len(tracks), args.out)
    return 0


def run_demo(out_dir: Path, *, seed: int) -> dict:
    """Demo part: tracks from unlabeled detections through crossings, bearing-time figure.

    Writes ``smoothed.csv`` and ``smoothing.png`` (raw detections, smoothed tracks with 1-sigma
    bands, true crossings, and the crossing alerts of :mod:`fusion.passive.crossing` when
    present) into `out_dir`; returns tracks, swaps, lost tracks and RMSE.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fusion.passive.smoothing import crossing_outcomes
    from fusion.simulate.bearings import simulate_bearings

    out_dir = Path(out_dir)
    sc = simulate_bearings(seed=seed, n_tracks=4, duration_s=1200.0, n_crossing_pairs=2,
                           n_wrap_crossings=0, n_near_miss_pairs=0, p_detect=0.9,
                           clutter_rate=0.2)
    sigma = np.radians(sc.noise_deg)
    res = MultiTrackSmoother(sigma_bearing=sigma, q=1e-9,
                             clutter_density=0.2 / (2 * np.pi)).run(
        sc.time, np.radians(sc.bearing_deg))
    cr = [(c.track_a, c.track_b, c.t_cross) for c in sc.crossings]
    outcomes = crossing_outcomes(sc.track_id, res.labels, sc.time, cr,
                                 guard_s=15 * sc.sample_period_s,
                                 window_s=20 * sc.sample_period_s)
    cols = {
        "track_id": np.concatenate([np.full(len(tr), tr.track_id) for tr in res.tracks]),
        "time": np.concatenate([tr.times for tr in res.tracks]),
        "bearing_deg": np.concatenate([np.mod(np.degrees(tr.bearing), 360) for tr in res.tracks]),
        "bearing_rate_deg_per_min": np.concatenate([np.degrees(tr.rate) * 60 for tr in res.tracks]),
        "sigma_bearing_deg": np.concatenate([np.degrees(tr.sigma_bearing) for tr in res.tracks]),
    }
    write_table(out_dir / "smoothed.csv", cols)
    fig, ax = plt.subplots(figsize=(7, 8))
    ax.plot(sc.bearing_deg, sc.time, ".", color="0.6", ms=2, label="detections (unlabeled)")
    for tr in res.tracks:
        b = np.mod(np.degrees(tr.bearing), 360)
        s = np.degrees(tr.sigma_bearing)
        br = np.where(np.abs(np.diff(b, prepend=b[0])) > 180, np.nan, b)  # no line across 0/360
        line, = ax.plot(br, tr.times, lw=1.2, label=f"track {tr.track_id}")
        ax.fill_betweenx(tr.times, br - s, br + s, color=line.get_color(), alpha=0.3)
    for a, _b, tc in cr:
        k = int(np.argmin(np.abs(sc.truth_time - tc)))
        ax.plot(sc.truth_bearing_deg[a, k], tc, "kx", ms=8)
    n_alerts = 0
    try:
        from fusion.passive.crossing import detect_crossings

        alerts = detect_crossings(cols)
        det = [al for al in alerts if str(al.kind) == "detected"]
        n_alerts = len(alerts)
        for al in det:
            sel = (cols["track_id"] == al.track_a)
            if sel.any():
                ax.axhline(al.t_cross, color="r", lw=0.5, alpha=0.4)
    except ImportError:  # the crossing module is optional for this figure
        logger.info("fusion.passive.crossing not available; no alerts drawn")
    ax.set_xlabel("bearing (deg)")
    ax.set_ylabel("time (s)")
    ax.invert_yaxis()
    ax.set_title("Smoothed tracks (1-sigma bands); x: true crossings; red: crossing alerts")
    ax.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "smoothing.png", dpi=110)
    plt.close(fig)
    rmse = []
    for tr in res.tracks:
        k = np.searchsorted(sc.truth_time, tr.times)
        rmse.append(min(float(np.degrees(np.sqrt(np.mean(wrap_angle(
            tr.bearing - np.radians(sc.truth_bearing_deg[m, k])) ** 2))))
            for m in range(sc.n_tracks)))
    return {"tracks": len(res.tracks), "true_tracks": sc.n_tracks, "crossings": len(cr),
            "swaps": int(np.sum(outcomes == "swap")), "lost": int(np.sum(outcomes == "lost")),
            "crossing_alerts": n_alerts,
            "median_track_rmse_deg": round(float(np.median(rmse)), 4),
            "raw_noise_deg": sc.noise_deg}
