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
``import.json``           time origin (Unix s), frame, row counts, source files
========================  ===================================================================

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

from fusion.datasets.autoferry import AutoferryRecording, Sensor, load_autoferry
from fusion.io import write_json, write_table
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
    """Scenario folders under `folder`: `folder` itself if it holds the two JSON files, else its
    sub-folders that do (sorted by name).

    Raises
    ------
    FileNotFoundError
        If `folder` does not exist or holds no scenario.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such folder")

    def is_scenario(p: Path) -> bool:
        return any(p.glob("*_detections.json")) and any(p.glob("*_groundTruth.json"))

    if is_scenario(folder):
        return [folder]
    subs = sorted(p for p in folder.iterdir() if p.is_dir() and is_scenario(p))
    if not subs:
        raise FileNotFoundError(f"{folder}: no Autoferry scenario (needs *_detections.json and "
                                "*_groundTruth.json, here or in its sub-folders)")
    return subs


def import_autoferry(folder: str | Path, out_dir: str | Path) -> list[AutoferryImport]:
    """Convert Autoferry scenario(s) into the project's CSV files.

    Parameters
    ----------
    folder : path-like
        One scenario folder, or a folder of scenario folders.
    out_dir : path-like
        Output folder. One scenario: the files go into it; several: into ``out_dir/NAME/``.
        Each file is written atomically; existing files of these names are replaced.

    Returns
    -------
    list of AutoferryImport
        One per scenario, in the order written.

    Raises
    ------
    FileNotFoundError, ValueError
        No scenario, malformed upstream files (naming the file), or `out_dir` inside the input.
    """
    src = Path(folder)
    out = Path(out_dir)
    scenarios = find_scenarios(src)
    src_abs, out_abs = src.resolve(), out.resolve()
    if out_abs == src_abs or src_abs in out_abs.parents:
        raise ValueError(f"{out}: is inside the input folder {src}; refusing to write into the "
                         "recording")
    done = []
    for scen in scenarios:
        try:
            rec = load_autoferry(scen)
        except (KeyError, TypeError, IndexError) as e:  # ragged or missing fields
            raise ValueError(f"{scen}: malformed Autoferry scan ({type(e).__name__}: {e})") from None
        dest = out if len(scenarios) == 1 else out / scen.name
        tables = autoferry_tables(rec)
        rows = {}
        for name in FILES:
            write_table(dest / name, tables[name])
            rows[name] = int(len(next(iter(tables[name].values()))))
        write_json(dest / "import.json", {
            "scenario": rec.name,
            "source": str(scen),
            "t0_unix": rec.t0_unix,
            "time": "s from t0_unix, the earliest scan of any sensor",
            "frame": "x east, y north, m: the Piren NED frame of the data set with axes renamed",
            "frame_origin_lat_lon_h": list(PIREN_LLA),
            "bearings": "deg clockwise from north (true), from the ferry",
            "rows": rows,
        })
        logger.info("%s: %s", rec.name, ", ".join(f"{k} {v}" for k, v in rows.items()))
        done.append(AutoferryImport(rec.name, dest, rec.t0_unix, rows))
    return done
