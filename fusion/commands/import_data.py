"""``fusion import autoferry DIR --out OUT``: recorded data sets as the project's CSV files.

``autoferry``: one scenario folder of the Autoferry benchmark (``scenarioN_detections.json`` and
``scenarioN_groundTruth.json``), or a folder of such folders, becomes ``radar.csv``,
``lidar.csv`` (detections, x east / y north), ``eo_bearings.csv``, ``ir_bearings.csv`` (true
bearings, track_id -1), ``ownship.csv``, ``truth.csv`` (GNSS), ``truth_bearings.csv`` and
``import.json``, all timed in seconds from the earliest scan
(:mod:`fusion.datasets.autoferry_files`). One line per scenario says what was written.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fusion.cli import emit, summary


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``import`` subcommand."""
    p = sub.add_parser(
        "import",
        help="convert a recorded data set into the project's CSV files",
        description="Convert a recorded data set into the project's CSV files (docs/formats.md). "
        "autoferry: radar/lidar positions -> detections (x east, y north), EO/IR -> true "
        "bearings (track_id -1), ferry -> own-ship, GNSS -> truth; time in s from the "
        "earliest scan (t0_unix in import.json).",
    )
    p.add_argument("kind", choices=("autoferry",), help="data set")
    p.add_argument("source", type=Path, metavar="DIR",
                   help="a scenario folder, or a folder of scenario folders")
    p.add_argument("--out", type=Path, required=True,
                   help="output folder (several scenarios: one sub-folder each)")
    p.set_defaults(handler=run, inputs=("source",), out_is_dir=True)


def run(args: argparse.Namespace) -> int:
    """Import; one line per scenario."""
    from fusion.datasets.autoferry_files import import_autoferry

    n = 0
    for imp in import_autoferry(args.source, args.out):
        counts = ", ".join(f"{k.removesuffix('.csv')} {v}" for k, v in imp.rows.items())
        emit(f"{imp.scenario}: t0 {imp.t0_unix:.3f} (Unix s) -> {imp.out_dir}: {counts} rows")
        n += 1
    summary("import", f"{n} scenario(s) -> {args.out}")
    return 0
