"""Reader of the Autoferry maritime sensor-fusion benchmark (real detections, GNSS truth).

The recordings come from the autonomous ferry milliAmpere in Trondheim harbour (May 2021): radar
and lidar detections (positions, with much clutter), EO and IR camera detections (bearings, with
false alarms and misses), the ferry's own position, and GNSS truth of two target boats. Per
scenario the upstream files are ``scenarioN_detections.json`` and ``scenarioN_groundTruth.json``;
the detection at index ``k`` pairs with the ground-truth entry at index ``k``.

Upstream frames and what this reader makes of them:

- positions are north/east metres in the "Piren" NED frame; here they become the project's local
  frame, ``x`` = east, ``y`` = north (metres);
- radar/lidar measurements are ``[[n_1..n_M], [e_1..e_M]]`` relative to the ferry (axes parallel to
  NED); here they are returned in the absolute local frame (ferry position added);
- EO/IR measurements are bearings ``atan2(east, north)`` in radians from the ferry; here they are
  compass bearings in degrees clockwise from north, in ``[0, 360)``;
- times are returned in seconds from the scenario's first scan (``t0_unix`` keeps the origin).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from fusion.datasets._autoferry_json import parse_ground_truth, parse_scans
from fusion.io import Table, read_json

__all__ = ["AutoferryRecording", "Sensor", "load_autoferry"]


class Sensor(IntEnum):
    """Sensor ids of the Autoferry data set."""

    LIDAR = 1
    RADAR = 2
    IR = 3
    EO = 4


@dataclass(frozen=True)
class AutoferryRecording:
    """One Autoferry scenario, scans in time order.

    Attributes
    ----------
    name : str
        Scenario name (folder name).
    t0_unix : float
        Unix time of the first scan, s.
    scan_time : ndarray, shape (n_scans,)
        Scan times, s from ``t0_unix``.
    scan_sensor : ndarray of int, shape (n_scans,)
        Sensor id of each scan (:class:`Sensor`).
    ownship_xy : ndarray, shape (n_scans, 2)
        Ferry position at each scan, m (x east, y north).
    measurements : tuple of ndarray
        Per scan: bearings, deg (EO/IR, shape (M,)) or absolute positions, m (radar/lidar,
        shape (M, 2) as x, y).
    truth : Table
        GNSS truth: ``track_id, time, x, y`` (time in s from ``t0_unix``); no rows when the
        scenario has no ground truth.
    truth_file : pathlib.Path or None
        The ground-truth file read (None: the folder holds none).
    """

    name: str
    t0_unix: float
    scan_time: NDArray[np.float64]
    scan_sensor: NDArray[np.int64]
    ownship_xy: NDArray[np.float64]
    measurements: tuple[NDArray[np.float64], ...]
    truth: Table
    truth_file: Path | None = None

    def bearings(self, sensors: Iterable[int] = (Sensor.IR, Sensor.EO)) -> Table:
        """Camera bearings as a table.

        Returns
        -------
        Table
            ``scan, time, bearing_deg, sensor_id, own_x, own_y``; one row per bearing.
        """
        wanted = set(int(s) for s in sensors)
        rows = [
            (k, b)
            for k, (sid, m) in enumerate(zip(self.scan_sensor, self.measurements, strict=True))
            if sid in wanted and sid in (Sensor.IR, Sensor.EO)
            for b in m
        ]
        k = np.array([r[0] for r in rows], dtype=np.int64)
        return Table(
            {
                "scan": k,
                "time": self.scan_time[k],
                "bearing_deg": np.array([r[1] for r in rows], dtype=float),
                "sensor_id": self.scan_sensor[k],
                "own_x": self.ownship_xy[k, 0],
                "own_y": self.ownship_xy[k, 1],
            },
            f"{self.name}:bearings",
        )

    def positions(self, sensors: Iterable[int] = (Sensor.RADAR,)) -> Table:
        """Radar/lidar detections as a table in the absolute local frame.

        Returns
        -------
        Table
            ``event, time, x, y, sensor_id, own_x, own_y``; ``event`` numbers the scans of the
            chosen sensors consecutively from 0 (empty scans keep their number).
        """
        wanted = set(int(s) for s in sensors)
        scans = [
            k for k, sid in enumerate(self.scan_sensor)
            if sid in wanted and sid in (Sensor.RADAR, Sensor.LIDAR)
        ]
        ev, ks, xy = [], [], []
        for e, k in enumerate(scans):
            m = self.measurements[k]
            ev.extend([e] * len(m))
            ks.extend([k] * len(m))
            xy.extend(m.tolist())
        ks_a = np.array(ks, dtype=np.int64)
        xy_a = np.array(xy, dtype=float).reshape(-1, 2)
        return Table(
            {
                "event": np.array(ev, dtype=np.int64),
                "time": self.scan_time[ks_a],
                "x": xy_a[:, 0],
                "y": xy_a[:, 1],
                "sensor_id": self.scan_sensor[ks_a],
                "own_x": self.ownship_xy[ks_a, 0],
                "own_y": self.ownship_xy[ks_a, 1],
            },
            f"{self.name}:positions",
        )

    def ownship(self) -> Table:
        """Ferry track ``time, x, y`` at strictly increasing times (duplicate times dropped)."""
        t, idx = np.unique(self.scan_time, return_index=True)
        return Table(
            {"time": t, "x": self.ownship_xy[idx, 0], "y": self.ownship_xy[idx, 1]},
            f"{self.name}:ownship",
        )

    def true_bearings(self) -> Table:
        """GNSS bearings from the ferry: ``track_id, time, bearing_deg, range_m`` at each scan.

        Target positions are interpolated in time to each scan; the ferry position is the scan's.
        """
        out: dict[str, list[NDArray[np.float64]]] = {
            "track_id": [], "time": [], "bearing_deg": [], "range_m": []
        }
        tr = self.truth
        for tid in np.unique(tr["track_id"]):
            m = tr["track_id"] == tid
            tt, order = np.unique(tr["time"][m], return_index=True)
            x = np.interp(self.scan_time, tt, tr["x"][m][order])
            y = np.interp(self.scan_time, tt, tr["y"][m][order])
            inside = (self.scan_time >= tt[0]) & (self.scan_time <= tt[-1])
            dx = x - self.ownship_xy[:, 0]
            dy = y - self.ownship_xy[:, 1]
            out["track_id"].append(np.full(int(inside.sum()), tid))
            out["time"].append(self.scan_time[inside])
            out["bearing_deg"].append(np.mod(np.degrees(np.arctan2(dx, dy)), 360.0)[inside])
            out["range_m"].append(np.hypot(dx, dy)[inside])
        cols = {k: np.concatenate(v) if v else np.zeros(0) for k, v in out.items()}
        cols["track_id"] = cols["track_id"].astype(np.int64)
        return Table(cols, f"{self.name}:true_bearings")


def load_autoferry(folder: str | Path) -> AutoferryRecording:
    """Load one scenario folder (``scenarioN_detections.json`` + ``scenarioN_groundTruth.json``).

    Parameters
    ----------
    folder : path-like
        The scenario folder; the two JSON files are found by their name endings. Without a
        ``*_groundTruth.json`` the recording has no truth (a table without rows).

    Returns
    -------
    AutoferryRecording

    Raises
    ------
    FileNotFoundError, ValueError
        Missing files, malformed content, numbers that are not finite or not plausible
        (:mod:`fusion.datasets._autoferry_json`): one line naming the file and the scan or
        entry.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such folder")
    det_file = _one_file(folder, "*_detections.json")
    if det_file is None:
        raise FileNotFoundError(f"{folder}: needs *_detections.json (and *_groundTruth.json)")
    gt_file = _one_file(folder, "*_groundTruth.json")
    times, sensors, own_ne, raw = parse_scans(det_file, read_json(det_file))
    order = np.argsort(times, kind="stable")
    t0 = float(times[order[0]])
    meas: list[NDArray[np.float64]] = []
    for k in order:
        if sensors[k] in (Sensor.IR, Sensor.EO):
            meas.append(np.mod(np.degrees(raw[k]), 360.0))
        else:  # (north, east) offsets -> absolute (x east, y north)
            meas.append(raw[k][:, ::-1] + own_ne[k, ::-1])
    tid: list[int] = []
    tt: list[float] = []
    tx: list[float] = []
    ty: list[float] = []
    if gt_file is not None:
        tid, tt, tx, ty = parse_ground_truth(gt_file, read_json(gt_file), n_scans=len(times),
                                             t0=t0, detections=det_file)
    truth = Table(
        {
            "track_id": np.array(tid, dtype=np.int64),
            "time": np.array(tt, dtype=float),
            "x": np.array(tx, dtype=float),
            "y": np.array(ty, dtype=float),
        },
        str(gt_file if gt_file is not None else folder),
    )
    return AutoferryRecording(
        name=folder.name,
        t0_unix=t0,
        scan_time=times[order] - t0,
        scan_sensor=sensors[order],
        ownship_xy=own_ne[order][:, ::-1].copy(),
        measurements=tuple(meas),
        truth=truth,
        truth_file=gt_file,
    )


def _one_file(folder: Path, pattern: str) -> Path | None:
    """The one file of `folder` matching `pattern` (None if none; two are refused)."""
    found = sorted(folder.glob(pattern))
    if len(found) > 1:
        names = ", ".join(p.name for p in found)
        raise ValueError(f"{folder}: holds {len(found)} {pattern} files ({names}); expected one "
                         "scenario per folder")
    return found[0] if found else None
