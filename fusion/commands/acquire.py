"""``fusion acquire --cube C.npz --beam B --freq-hz F``: initial bearing, bearing rate and SNR."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fusion.cli import MAX_SCANS_OPTION, emit, number, summary
from fusion.io import read_cube
from fusion.passive.acquisition import Acquisition


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``acquire`` subcommand."""
    p = sub.add_parser(
        "acquire",
        help="bearing, bearing rate and SNR of a clicked narrowband target",
        description=(
            "Find the best line through the initialisation-band BTR of a beam/frequency/time cube "
            "around an operator's click and print the target's bearing, bearing rate and SNR as "
            "JSON (high bearing-rate acquisition)."
        ),
    )
    p.add_argument("--cube", type=Path, required=True, help="cube .npz (power, freqs, ...)")
    p.add_argument("--beam", type=number(int, ge=0), required=True,
                   help="clicked beam (0 = forward endfire)")
    p.add_argument("--freq-hz", dest="freq",
                   type=number(float, gt=0), required=True, help="clicked frequency, Hz")
    p.add_argument("--display-lag-s", dest="lag", type=number(float, ge=0), default=0.0,
                   help="spectral integration / display lag to correct, s (default 0)")
    p.add_argument("--ibw-hz", dest="ibw", type=number(float, gt=0), default=None,
                   help="initialisation bandwidth, Hz (default: the clicked bin)")
    p.add_argument("--no-normalize", action="store_true",
                   help="the cube is already normalised to unit noise mean")
    p.add_argument("--min-scans", type=number(int, ge=2, le=MAX_SCANS_OPTION), default=None,
                   help="fewest scans a line may span before leaving the BTR, at most the "
                        "cube's scans (default: all)")
    p.add_argument("--noise-dof", type=number(float, gt=0), default=None,
                   help="degrees of freedom of the noise per cell (2: one periodogram look; "
                        "default: estimated from the cube)")
    p.add_argument("--freq-tolerance-bins", dest="freq_tolerance",
                   type=number(int, ge=0, le=MAX_SCANS_OPTION), default=1, metavar="BINS",
                   help="bins the clicked frequency may be off the line: the initialisation band "
                        "is also tried shifted by up to this many bins (default 1; 0: the "
                        "clicked band only)")
    p.add_argument("--pool-scans", type=number(int, ge=1, le=MAX_SCANS_OPTION), default=None,
                   help="scans pooled into each noise estimate of the normaliser (default: the "
                        "whole history; 1: every scan on its own, the method's literal normaliser)")
    p.add_argument("--trace", choices=("bearing", "beam"), default="bearing",
                   help="lines of the fans: constant-bearing-rate traces in cosine-spaced beams, "
                        "refined to sub-beam accuracy (default), or the method's literal straight "
                        "lines in beam number")
    p.add_argument("--rate-at", choices=("midpoint", "latest"), default=None,
                   help="--trace beam: beam where the line's beam rate becomes a bearing rate, "
                        "the middle of the line (default) or its latest end")
    p.set_defaults(handler=run, inputs=("cube",))


def run(args: argparse.Namespace) -> int:
    """Read the cube, acquire, print the JSON result."""
    cube = read_cube(args.cube)
    if args.beam >= cube.n_beams:
        raise ValueError(f"--beam {args.beam} is outside the beams 0..{cube.n_beams - 1} of "
                         f"{args.cube}")
    if cube.n_bins < 2:
        raise ValueError(f"{args.cube}: the cube needs at least 2 frequency bins "
                         "(bin spacing unknown)")
    df = float(np.median(np.diff(cube.freqs)))
    lo, hi = cube.freqs[0] - 0.5 * df, cube.freqs[-1] + 0.5 * df
    if not lo <= args.freq <= hi:
        raise ValueError(f"--freq-hz {args.freq:g} Hz is outside the band {lo:g}..{hi:g} Hz of "
                         f"{args.cube}")
    if args.min_scans is not None and args.min_scans > cube.n_scans:
        raise ValueError(f"--min-scans {args.min_scans} exceeds the {cube.n_scans} scans of "
                         f"{args.cube}")
    if args.rate_at is not None and args.trace != "beam":
        raise ValueError("--rate-at applies to --trace beam")
    acq = Acquisition(lag_s=args.lag, ibw_hz=args.ibw, normalize=not args.no_normalize,
                      min_scans=args.min_scans, noise_dof=args.noise_dof,
                      pool_scans=args.pool_scans, trace=args.trace,
                      rate_at=args.rate_at or "midpoint",
                      freq_tolerance_bins=args.freq_tolerance)
    try:
        res = acq.acquire(cube, beam=args.beam, freq_hz=args.freq)
    except ValueError as e:
        raise ValueError(f"{args.cube}: {e}") from None
    emit(json.dumps(res.to_json()))
    summary("acquire", f"bearing {res.bearing_deg:.2f} deg, rate {res.bearing_rate_deg_per_min:.3g} "
            f"deg/min, SNR {res.snr_db:.1f} dB" + (" (defaults used)" if res.default_used else ""),
            err=True)
    return 0
