"""Autoferry recordings as the project's CSV files (``fusion import autoferry``).

One scenario of the Autoferry benchmark (:func:`fusion.datasets.autoferry.load_autoferry`) becomes
the inputs of the ``fusion`` commands, all on one clock and in one frame:

========================  ===================================================================
file                      columns (``docs/formats.md``)
========================  ===================================================================
``radar.csv``             ``event,time,x,y,own_x,own_y`` -- section 3 (``fusion track``)
``lidar.csv``             same, lidar scans
``eo_bearings.csv``       ``track_id,time,bearing_deg,own_x,own_y`` with ``track_id`` -1 --
                          sections 4 and 7 (``fusion smooth``), true bearings
``ir_bearings.csv``       same, infrared camera
``ownship.csv``           ``time,x,y`` -- section 8 (``fusion tma --ownship``)
``truth.csv``             ``track_id,time,x,y`` -- GNSS fixes of the target boats (each once)
``truth_bearings.csv``    ``track_id,time,bearing_deg,range_m`` -- GNSS bearing and range from
                          the ferry at every scan (what the camera bearings should follow)
``import.json``           time origin (Unix s), frame, row counts, source files, files not
                          written and why
========================  ===================================================================

A scenario without ground truth (no ``*_groundTruth.json``) is imported without ``truth.csv``
and ``truth_bearings.csv``, and a file that would have no rows is not written; one warning line
names each (see :func:`import_autoferry`). Everything read is checked first (finite, plausible:
:mod:`fusion.datasets._autoferry_json`), and all files of all scenarios are written together.

Frame: x east, y north, metres, the upstream "Piren" NED frame with its axes renamed (origin at
lat 63.4389029083, lon 10.39908278). Time: seconds from the earliest scan of the scenario, any
sensor (``t0_unix`` in ``import.json``); GNSS times are on the same clock (a fix slightly before
the first scan has a negative time). Radar/lidar positions are absolute (ferry position added);
camera bearings are degrees clockwise from north in [0, 360), as the ferry-fixed NED bearings of
the upstream files are.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fusion._output import outputs_together
from fusion.datasets.autoferry import AutoferryRecording, Sensor, load_autoferry
from fusion.io import MAX_ABS_VALUE, write_json, write_table
from fusion.types import Table

__all__ = ["AutoferryImport", "autoferry_tables", "find_scenarios", "import_autoferry"]

logger = logging.getLogger(__name__)

#: Output file names, in the order they are written.
FILES = ("radar.csv", "lidar.csv", "eo_bearings.csv", "ir_bearings.csv", "ownship.csv",
         "truth.csv", "truth_bearings.csv")
#: Origin of the Piren NED frame (lat, lon deg; height m), from the upstream description.
PIREN_LLA = (63.4389029083, 10.39908278, 39.923)


@dataclass(frozen=True)
class AutoferryImport:
    """What one scenario's import wrote.

    Attributes
    ----------
    scenario : str
        Scenario name (folder name).
    out_dir : pathlib.Path
        Folder of the files.
    t0_unix : float
        Time origin of every file, Unix s (the earliest scan).
    rows : dict of str to int
        Rows written per file name.
    """

    scenario: str
    out_dir: Path
    t0_unix: float
    rows: dict[str, int]


def _positions(rec: AutoferryRecording, sensor: Sensor) -> dict[str, np.ndarray]:
    p = rec.positions((sensor,))
    return {"event": p["event"], "time": p["time"], "x": p["x"], "y": p["y"],
            "own_x": p["own_x"], "own_y": p["own_y"]}


def _bearings(rec: AutoferryRecording, sensor: Sensor) -> dict[str, np.ndarray]:
    b = rec.bearings((sensor,))
    return {"track_id": np.full(len(b), -1, np.int64), "time": b["time"],
            "bearing_deg": b["bearing_deg"], "own_x": b["own_x"], "own_y": b["own_y"]}


def autoferry_tables(rec: AutoferryRecording) -> dict[str, dict[str, np.ndarray]]:
    """The CSV tables of one recording, by file name (see the module notes).

    Parameters
    ----------
    rec : AutoferryRecording
        A loaded scenario.

    Returns
    -------
    dict of str to dict of str to ndarray
        File name (:data:`FILES`) to its columns, each 1-D of the file's row count; times in s
        from the earliest scan, positions in m (x east, y north), bearings in deg.
    """
    own = rec.ownship()
    truth: Table = rec.truth
    # the upstream truth repeats each fix at every scan index: one row per (target, time)
    _, first = np.unique(np.column_stack([truth["track_id"], truth["time"]]), axis=0,
                         return_index=True)
    order = first[np.lexsort((truth["time"][first], truth["track_id"][first]))]
    tb = rec.true_bearings()
    return {
        "radar.csv": _positions(rec, Sensor.RADAR),
        "lidar.csv": _positions(rec, Sensor.LIDAR),
        "eo_bearings.csv": _bearings(rec, Sensor.EO),
        "ir_bearings.csv": _bearings(rec, Sensor.IR),
        "ownship.csv": {"time": own["time"], "x": own["x"], "y": own["y"]},
        "truth.csv": {k: truth[k][order] for k in ("track_id", "time", "x", "y")},
        "truth_bearings.csv": {k: tb[k] for k in ("track_id", "time", "bearing_deg", "range_m")},
    }


def find_scenarios(folder: str | Path) -> list[Path]:
    """Scenario folders under `folder`: `folder` itself if it holds a ``*_detections.json``,
    else its sub-folders that do (sorted by name).

    Raises
    ------
    FileNotFoundError
        If `folder` does not exist or holds no scenario.
    ValueError
        A sub-folder holds a ``*_groundTruth.json`` without its ``*_detections.json`` (it is
        not skipped silently).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such folder")

    def has(p: Path, pattern: str) -> bool:
        return any(p.glob(pattern))

    if has(folder, "*_detections.json"):
        return [folder]
    subs = sorted(p for p in folder.iterdir() if p.is_dir())
    for sub in subs:
        if has(sub, "*_groundTruth.json") and not has(sub, "*_detections.json"):
            raise ValueError(f"{sub}: holds a *_groundTruth.json but no *_detections.json; not "
                             "an Autoferry scenario (remove it or add its detections)")
    found = [p for p in subs if has(p, "*_detections.json")]
    if not found:
        raise FileNotFoundError(f"{folder}: no Autoferry scenario (needs *_detections.json and "
                                "*_groundTruth.json, here or in its sub-folders)")
    return found


@dataclass(frozen=True)
class _Planned:
    """One scenario read and checked, its files not written yet."""

    scenario: Path
    rec: AutoferryRecording
    dest: Path
    tables: dict[str, dict[str, np.ndarray]]  # the files to write (those with rows)
    left_out: dict[str, str]  # file name -> why it is not written


def _plan(scen: Path, dest: Path) -> _Planned:
    """Read and check one scenario; decide its files (nothing written)."""
    rec = load_autoferry(scen)
    tables = autoferry_tables(rec)
    left_out: dict[str, str] = {}
    if rec.truth_file is None or len(rec.truth) == 0:
        why = (f"{scen} has no ground truth (*_groundTruth.json)" if rec.truth_file is None
               else f"{rec.truth_file} holds no GNSS fix")
        left_out |= {"truth.csv": why, "truth_bearings.csv": why}
    elif len(tables["truth_bearings.csv"]["time"]) == 0:
        t = rec.truth["time"]
        raise ValueError(f"{rec.truth_file}: the GNSS fixes ({t.min():.3g}..{t.max():.3g} s) "
                         f"cover no scan (0..{rec.scan_time[-1]:.3g} s); the ground truth of "
                         "another recording?")
    for name in FILES:
        if name not in left_out and len(next(iter(tables[name].values()))) == 0:
            left_out[name] = f"{scen} has no {name.removesuffix('.csv').replace('_', ' ')}"
    for name in left_out:
        tables.pop(name)
        if (dest / name).exists():
            raise ValueError(f"{dest / name}: exists (from an earlier import?), and this import "
                             f"writes no {name} ({left_out[name]}); remove it or choose another "
                             "--out")
    for name, cols in tables.items():  # what the readers of the next command accept
        for col, v in cols.items():
            if not np.all(np.abs(v) <= MAX_ABS_VALUE):
                k = int(np.flatnonzero(~(np.abs(v) <= MAX_ABS_VALUE))[0])
                raise ValueError(f"{scen}: {name} would hold {v[k]:g} in column {col!r} (row "
                                 f"{k + 1}): not a finite plausible value; check the recording")
    return _Planned(scen, rec, dest, tables, left_out)


def import_autoferry(folder: str | Path, out_dir: str | Path) -> list[AutoferryImport]:
    """Convert Autoferry scenario(s) into the project's CSV files.

    Parameters
    ----------
    folder : path-like
        One scenario folder, or a folder of scenario folders.
    out_dir : path-like
        Output folder. One scenario: the files go into it; several: into ``out_dir/NAME/``.
        Every scenario is read and checked before anything is written; then all files are
        committed together (:func:`fusion._output.outputs_together`): a failure leaves no file
        and no folder of the import. Existing files of these names are replaced.

    Returns
    -------
    list of AutoferryImport
        One per scenario, in the order written.

    Raises
    ------
    FileNotFoundError, ValueError
        No scenario, malformed or implausible upstream content (naming the file and the scan or
        entry), or `out_dir` inside the input.

    Notes
    -----
    A scenario without ground truth (no ``*_groundTruth.json``, or one without fixes) is
    imported without ``truth.csv`` and ``truth_bearings.csv``; a file that would have no rows
    (no lidar scans, say) is not written either. A warning names each file left out, and
    ``import.json`` lists them; an existing file of that name in the destination is refused
    rather than left beside files of another recording.
    """
    src = Path(folder)
    out = Path(out_dir)
    scenarios = find_scenarios(src)
    src_abs, out_abs = src.resolve(), out.resolve()
    if out_abs == src_abs or src_abs in out_abs.parents:
        raise ValueError(f"{out}: is inside the input folder {src}; refusing to write into the "
                         "recording")
    plans = [_plan(scen, out if len(scenarios) == 1 else out / scen.name) for scen in scenarios]
    done = []
    with outputs_together(out):
        for plan in plans:
            done.append(_write(plan))
    for plan in plans:
        for why in dict.fromkeys(plan.left_out.values()):
            names = ", ".join(n for n, w in plan.left_out.items() if w == why)
            logger.warning("%s: %s; %s not written", plan.rec.name, why, names)
    return done


def _write(plan: _Planned) -> AutoferryImport:
    rec, dest = plan.rec, plan.dest
    rows = {name: int(len(next(iter(cols.values())))) for name, cols in plan.tables.items()}
    for name, cols in plan.tables.items():
        write_table(dest / name, cols, max_abs=MAX_ABS_VALUE)
    write_json(dest / "import.json", {
        "scenario": rec.name,
        "source": str(plan.scenario),
        "t0_unix": rec.t0_unix,
        "time": "s from t0_unix, the earliest scan of any sensor",
        "frame": "x east, y north, m: the Piren NED frame of the data set with axes renamed",
        "frame_origin_lat_lon_h": list(PIREN_LLA),
        "bearings": "deg clockwise from north (true), from the ferry",
        "rows": rows,
        "not_written": plan.left_out,
    })
    logger.info("%s: %s", rec.name, ", ".join(f"{k} {v}" for k, v in rows.items()))
    return AutoferryImport(rec.name, dest, rec.t0_unix, rows)
