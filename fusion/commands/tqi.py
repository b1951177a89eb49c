"""``fusion tqi --amplitudes A.csv --out Q.csv``: track quality indicator of tracker outputs.

Reads ``track_id,time,amplitude,residual`` (amplitude: cell power, linear, normalised so that
noise alone has mean 1; residual: bearing error, deg), runs the track quality indicator with
hysteresis on every track (all tracks at once, vectorised), and writes the input columns plus
``tqi`` (``lost``, ``uncertain``, ``low_snr``, ``strong``) in the input's row order -- after
:func:`fusion.io.read_amplitudes` has put rows that were out of time order within a track in time
order (one warning says so); two updates of one track at the same time are an error.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from fusion.cli import number
from fusion.io import read_amplitudes, write_table
from fusion.passive.quality import TrackQualityIndicator

logger = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``tqi`` subcommand."""
    p = sub.add_parser(
        "tqi",
        help="track quality (lost/uncertain/low_snr/strong) of tracker outputs",
        description="Track quality indicator with hysteresis of narrowband tracker outputs "
        "(amplitude and bearing residual per update).",
    )
    p.add_argument("--amplitudes", type=Path, required=True,
                   help="CSV track_id,time,amplitude,residual")
    p.add_argument("--out", type=Path, required=True, help="output CSV (input columns + tqi)")
    g = p.add_argument_group("design SNRs (per cell)")
    g.add_argument("--snr0-db", type=number(float), default=3.0, help="tracker threshold SNR_0 (3 dB)")
    g.add_argument("--snr1-db", type=number(float), default=10.0, help="strong-track SNR_1 (10 dB)")
    g.add_argument("--n-looks", type=number(int, ge=1), default=1,
                   help="periodogram looks averaged per cell of the spectra (1)")
    t = p.add_argument_group("thresholds (method defaults)")
    t.add_argument("--tl", type=number(float), default=-3.5, help="lost threshold TL (-3.5)")
    t.add_argument("--tu", type=number(float), default=1.75, help="uncertain threshold TU (1.75)")
    t.add_argument("--ts", type=number(float), default=7.0, help="strong threshold TS (7.0)")
    t.add_argument("--lh", type=number(float, ge=0), default=1.5, help="low-SNR hysteresis LH (1.5)")
    t.add_argument("--sh", type=number(float, ge=0), default=2.0, help="strong-SNR hysteresis SH (2.0)")
    t.add_argument("--sllr0-max", type=number(float), default=None, metavar="TM0",
                   help="ceiling TM_0 of SLLR_0: how much evidence a loss must undo before "
                        "'lost' (default TU + LH + 0.25; above TU + LH so a track can leave "
                        "'uncertain'); lower: earlier 'lost', more state changes")
    t.add_argument("--no-hysteresis", action="store_true",
                   help="single thresholds (LH = SH = 0 in the decision flow)")
    r = p.add_argument_group("residual test")
    r.add_argument("--omega", type=number(float, gt=0), default=0.25,
                   help="error-detector angular centre frequency Omega, 1/deg (0.25)")
    r.add_argument("--t-err", type=number(float, ge=0), default=3.0, help="residual threshold constant (3.0)")
    r.add_argument("--residual-smoothing", type=number(float, gt=0, le=1), default=0.1,
                   help="gain of the recursive residual smoother, (0, 1] (0.1)")
    p.add_argument("--diagnostics", action="store_true",
                   help="also write sllr0, sllr1, smoothed_residual, err_max columns")
    p.set_defaults(handler=run, inputs=("amplitudes",))


def run(args: argparse.Namespace) -> int:
    """Compute the TQI of every track and write the output CSV."""
    if not args.snr1_db > args.snr0_db:
        raise ValueError(f"--snr1-db ({args.snr1_db:g}) must exceed --snr0-db ({args.snr0_db:g})")
    if not args.tl < args.tu:
        raise ValueError(f"--tl ({args.tl:g}) must be below --tu ({args.tu:g})")
    if args.sllr0_max is not None and not args.sllr0_max > args.tl - args.lh:
        raise ValueError(f"--sllr0-max ({args.sllr0_max:g}) must exceed the SLLR_0 floor "
                         f"TL - LH ({args.tl - args.lh:g})")
    table = read_amplitudes(args.amplitudes)
    limits = None if args.sllr0_max is None else (args.tl - args.lh, args.sllr0_max)
    tqi = TrackQualityIndicator(
        snr0_db=args.snr0_db, snr1_db=args.snr1_db, n_looks=args.n_looks, tl=args.tl,
        tu=args.tu, ts=args.ts, lh=args.lh, sh=args.sh, hysteresis=not args.no_hysteresis,
        omega=args.omega, t_err=args.t_err, residual_smoothing=args.residual_smoothing,
        sllr0_limits=limits,
    )
    ids = table["track_id"]
    tracks, col = np.unique(ids, return_inverse=True)
    # update index of each row within its track (rows of a track are in time order)
    order = np.argsort(col, kind="stable")
    counts = np.bincount(col, minlength=tracks.size)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    row_k = np.empty(len(table), dtype=np.int64)
    row_k[order] = np.arange(len(table)) - np.repeat(starts, counts)
    shape = (int(counts.max()), tracks.size)
    amp = np.full(shape, np.nan)
    res = np.full(shape, np.nan)
    valid = np.zeros(shape, dtype=bool)
    amp[row_k, col] = table["amplitude"]
    res[row_k, col] = table["residual"]
    valid[row_k, col] = True
    hist = tqi.run(amp, res, valid=valid)
    columns = {name: table[name] for name in ("track_id", "time", "amplitude", "residual")}
    columns["tqi"] = hist.labels()[row_k, col]
    if args.diagnostics:
        columns["sllr0"] = hist.sllr0[row_k, col]
        columns["sllr1"] = hist.sllr1[row_k, col]
        columns["smoothed_residual"] = hist.residual_deg[row_k, col]
        columns["err_max"] = hist.err_max_deg[row_k, col]
    write_table(args.out, columns)
    logger.info("TQI of %d tracks, %d updates written to %s", tracks.size, len(table), args.out)
    return 0
