"""``fusion tma --bearings B.csv --ownship O.csv --out T.csv``: bearings-only target motion analysis.

Reads true bearings (``time,bearing_deg``) and own-ship positions (``time,x,y``), estimates the
target track on a factor graph and writes ``time,x,y,vx,vy,sigma_x,sigma_y,range``
(``docs/formats.md``, section 8) plus ``range_low,range_high`` (the range interval from the
noise-fitted covariance) and ``observable`` (1, or 0 when range is flagged unobservable). Rows out
of time order are sorted (one warning); repeated times are an error. When range is unobservable
(no own-ship manoeuvre, one too small for the range, or an ill-conditioned range) one warning
line goes to stderr and the estimate is still written, flagged. One line on stdout sums up.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from fusion.cli import emit, number
from fusion.io import read_ownship, read_tma_bearings, write_table
from fusion.passive.tma import BearingsOnlyTMA, OwnshipTrack


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``tma`` subcommand."""
    p = sub.add_parser(
        "tma",
        help="bearings-only target motion analysis",
        description="Estimate a target's track from true bearings taken by a manoeuvring own-ship.",
    )
    p.add_argument("--bearings", type=Path, required=True, help="CSV time,bearing_deg")
    p.add_argument("--ownship", type=Path, required=True, help="CSV time,x,y")
    p.add_argument("--out", type=Path, required=True, help="output CSV")
    p.add_argument("--bearing-sigma-deg", type=number(float, gt=0), default=1.0,
                   help="bearing noise standard deviation, deg (default 1.0)")
    p.add_argument("--motion", choices=("single", "chain"), default="single",
                   help="one constant-velocity state, or a state per time with CV factors "
                        "(default single)")
    p.add_argument("--accel-psd-m2-per-s3", dest="q", type=number(float, gt=0), default=1e-6,
                   help="acceleration PSD of the target for --motion chain, m^2/s^3 (default 1e-6)")
    p.add_argument("--robust", choices=("huber", "cauchy", "tukey"), default=None,
                   help="robust loss on the bearings (default none)")
    p.add_argument("--robust-k", type=number(float, gt=0), default=2.0,
                   help="robust threshold in bearing sigmas (default 2.0)")
    p.add_argument("--noise", choices=("fit", "given"), default="fit",
                   help="fit: covariance scaled to the residuals seen (their variance and "
                        "correlation, never below --bearing-sigma-deg); given: as the graph "
                        "gives it (default fit)")
    p.add_argument("--max-range-rel-sigma", type=number(float, gt=0), default=0.15,
                   help="flag range unobservable above this relative range sigma (default 0.15)")
    p.add_argument("--min-manoeuvre-m", type=number(float, ge=0), default=5.0,
                   help="flag range unobservable when the own-ship departs less than this "
                        "from a straight constant-speed track, m (default 5)")
    p.add_argument("--min-manoeuvre-sigmas", type=number(float, ge=0), default=1.0,
                   help="flag range unobservable when that departure, seen from the target, "
                        "subtends fewer bearing sigmas (default 1)")
    p.add_argument("--level", type=number(float, gt=0, le=0.9999), default=0.95,
                   help="coverage of the range interval range_low..range_high (default 0.95)")
    p.set_defaults(handler=run, inputs=("bearings", "ownship"))


def run(args: argparse.Namespace) -> int:
    """Run TMA on the files named in `args`; write the output CSV."""
    bearings = read_tma_bearings(args.bearings)
    ownship = read_ownship(args.ownship)
    try:
        track = OwnshipTrack(ownship["time"], np.column_stack([ownship["x"], ownship["y"]]))
    except ValueError as e:
        raise ValueError(f"{args.ownship}: {e}") from None
    tma = BearingsOnlyTMA(
        bearing_sigma_deg=args.bearing_sigma_deg, motion=args.motion, q=args.q,
        robust=args.robust, robust_k=args.robust_k, noise=args.noise,
        max_range_rel_sigma=args.max_range_rel_sigma, min_manoeuvre_m=args.min_manoeuvre_m,
        min_manoeuvre_sigmas=args.min_manoeuvre_sigmas, interval_level=args.level,
    )
    t, t_own = bearings["time"], ownship["time"]
    tol = 1e-9 * max(1.0, float(t_own[-1] - t_own[0]), float(np.max(np.abs(t_own))))
    if t.min() < t_own[0] - tol or t.max() > t_own[-1] + tol:
        raise ValueError(
            f"{args.bearings}: bearing times [{t.min():g}, {t.max():g}] s reach outside the "
            f"own-ship track [{t_own[0]:g}, {t_own[-1]:g}] s of {args.ownship}"
        )
    try:
        res = tma.estimate(bearings["time"], np.radians(bearings["bearing_deg"]), track)
    except ValueError as e:
        raise ValueError(f"{args.bearings}: {e}") from None
    write_table(
        args.out,
        {"time": res.times, "x": res.x, "y": res.y, "vx": res.vx, "vy": res.vy,
         "sigma_x": res.sigma_x, "sigma_y": res.sigma_y, "range": res.range,
         "range_low": res.range_low, "range_high": res.range_high,
         "observable": np.full(res.times.size, int(res.observable), np.int64)},
    )
    flag = "range observable" if res.observable else f"RANGE UNOBSERVABLE ({res.reason})"
    emit(f"fusion tma: {flag}; final range {res.range[-1]:.4g} m, "
         f"{100 * args.level:g} % interval {res.range_low[-1]:.4g}-{res.range_high[-1]:.4g} m; "
         f"bearing residual RMS {res.bearing_rms_deg:.3g} deg, covariance x "
         f"{res.covariance_scale:.3g} -> {args.out}")
    return 0
