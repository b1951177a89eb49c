"""``fusion tma --bearings B.csv --ownship O.csv --out T.csv``: bearings-only target motion analysis.

Reads true bearings (``time,bearing_deg``) and own-ship positions (``time,x,y``), estimates the
target track on a factor graph and writes ``time,x,y,vx,vy,sigma_x,sigma_y,range``
(``docs/formats.md``, section 8). Rows out of time order are sorted (one warning); repeated times
are an error. When range is unobservable (no own-ship manoeuvre), one warning line goes to
stderr and the estimate is still written.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from fusion.cli import number
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
                   help="one constant-velocity state, or a state per time with CV factors")
    p.add_argument("--q", type=number(float, gt=0), default=1e-6,
                   help="acceleration PSD of the target for --motion chain, m^2/s^3 (default 1e-6)")
    p.add_argument("--robust", choices=("huber", "cauchy", "tukey"), default=None,
                   help="robust loss on the bearings (default none)")
    p.add_argument("--robust-k", type=number(float, gt=0), default=2.0,
                   help="robust threshold in bearing sigmas (default 2.0)")
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
        robust=args.robust, robust_k=args.robust_k,
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
         "sigma_x": res.sigma_x, "sigma_y": res.sigma_y, "range": res.range},
    )
    return 0
