"""``fusion report RESULT --out DIR``: PNG figures of any ``fusion`` command's output.

RESULT is a result file or a command's output folder; its kind is told from its columns, keys or
files (:mod:`fusion.report.kinds`): the BTR with the acquired line (``acquire``, with
``--cube``), bearing-time tracks with TQI states, crossing alerts and sigma bands (``passive``,
``crossings``, ``tqi``, ``smooth``), multistatic tracks over the clutter map (``track``, with
``--detections``; sigma bands for ``--smooth`` output), the TMA solution (``tma``), sources and
whale tracks in plan view and depth, and the intensity surface with ``--array`` (``localize``).
An unknown result is one error line and exit code 2. matplotlib is imported only here (Agg
canvas, no window).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fusion.cli import emit, number


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``report`` subcommand."""
    p = sub.add_parser(
        "report",
        help="PNG figures of any command's output, with axis labels and units",
        description="Draw the figures of a fusion result (a file or an output folder) as PNG "
                    "files, with axis labels and units. The kind of result is told from its "
                    "columns or keys.",
        epilog="Kinds: acquire (JSON saved from stdout; needs --cube), passive (output folder "
               "or its tracks.csv), smooth, tqi, crossings, track, tma, localize (JSON, "
               "--events JSON, or an output folder of JSONs).",
    )
    p.add_argument("result", type=Path, metavar="RESULT",
                   help="a result file (CSV or JSON) or a command's output folder")
    p.add_argument("--out", type=Path, required=True, help="folder for the PNG files")
    extra = p.add_argument_group("extra inputs (where a figure needs them)")
    extra.add_argument("--cube", type=Path, default=None,
                       help="acquire: the cube .npz it read (required for its BTR)")
    extra.add_argument("--freq-hz", dest="freq", type=number(float, gt=0), default=None,
                       help="acquire: the clicked frequency, Hz (default: the bin with the "
                            "strongest line)")
    extra.add_argument("--display-lag-s", dest="lag", type=number(float, ge=0), default=0.0,
                       help="acquire: the --display-lag-s it was given, s (default 0)")
    extra.add_argument("--bearings", type=Path, default=None,
                       help="crossings/smooth/tqi: bearings CSV track_id,time,bearing_deg (the "
                            "tracks the alerts or states belong to, or the raw input)")
    extra.add_argument("--alerts", type=Path, default=None,
                       help="smooth, passive tracks.csv: crossing alerts CSV to draw on the tracks")
    extra.add_argument("--detections", type=Path, default=None,
                       help="track: the detections CSV it read (clutter map behind the tracks)")
    extra.add_argument("--ownship", type=Path, default=None,
                       help="tma: own-ship CSV time,x,y")
    extra.add_argument("--array", type=Path, default=None,
                       help="localize: the array JSON (sensors and intensity surface)")
    p.set_defaults(handler=run, out_is_dir=True,
                   inputs=("result", "cube", "bearings", "alerts", "detections", "ownship",
                           "array"))


def run(args: argparse.Namespace) -> int:
    """Detect the result's kind, draw its figures, print one line per file written."""
    from fusion.report.build import ReportInputs, make_report

    extra = ReportInputs(cube=args.cube, freq_hz=args.freq, lag_s=args.lag,
                         bearings=args.bearings, alerts=args.alerts, detections=args.detections,
                         ownship=args.ownship, array=args.array)
    kind, written = make_report(args.result, args.out, inputs=extra)
    for path in written:
        emit(str(path))
    n = sum(path.suffix == ".png" for path in written)
    emit(f"fusion report: {n} figure(s) of the {kind} result and summary.md -> {args.out}",
         err=True)
    return 0
