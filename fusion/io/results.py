"""Localization results of ``fusion localize`` (JSON): typed records, read and write."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fusion.io._files import PathLike
from fusion.io.json_files import read_json, write_json

__all__ = [
    "LocalizationResult",
    "LocalizationWindow",
    "SourceEstimate",
    "TdoaRecord",
    "read_localization",
    "write_localization",
]


@dataclass(frozen=True)
class TdoaRecord:
    """One measured TDOA of a processing window.

    Attributes
    ----------
    pair : tuple of int
        0-based sensor indices ``(i, j)``.
    tau : float
        Arrival time at sensor i minus at sensor j, s.
    valid : bool
        Whether validation accepted it.
    llr : float
        Validation log-likelihood ratio.
    t : float
        Arrival time at sensor i at which `tau` holds, s from the start of the audio (NaN in a
        file written before the field existed).
    rate : float
        ``d tau / dt`` at `t`, s/s (NaN when the file has none).
    """

    pair: tuple[int, int]
    tau: float
    valid: bool
    llr: float
    t: float = math.nan
    rate: float = math.nan

    def tau_at(self, t_s: float) -> float:
        """The delay at another arrival time ``t_s`` on sensor i, to first order, s."""
        return self.tau + self.rate * (t_s - self.t)


@dataclass(frozen=True)
class SourceEstimate:
    """One localized source of a processing window (position in m, covariance in m^2)."""

    x: float
    y: float
    z: float
    cov: tuple[tuple[float, float, float], ...]
    tdoas_used: int


@dataclass(frozen=True)
class LocalizationWindow:
    """TDOAs and sources of one processing window (``t_start``/``t_end`` in s from the audio start)."""

    t_start: float
    t_end: float
    tdoas: tuple[TdoaRecord, ...]
    sources: tuple[SourceEstimate, ...]


@dataclass(frozen=True)
class LocalizationResult:
    """Result of ``fusion localize``: windows and tracks (``tracks``: id -> points (t, x, y, z))."""

    windows: tuple[LocalizationWindow, ...]
    tracks: tuple[tuple[int, tuple[tuple[float, float, float, float], ...]], ...] = ()


def write_localization(path: PathLike, result: LocalizationResult) -> Path:
    """Write a localization result as JSON (atomic)."""
    doc = {
        "windows": [
            {
                "t_start": w.t_start,
                "t_end": w.t_end,
                "tdoas": [
                    {"pair": list(d.pair), "tau": d.tau,
                     **({"t": d.t, "rate": d.rate} if math.isfinite(d.t) else {}),
                     "valid": d.valid, "llr": d.llr}
                    for d in w.tdoas
                ],
                "sources": [
                    {"x": s.x, "y": s.y, "z": s.z, "cov": [list(r) for r in s.cov],
                     "tdoas_used": s.tdoas_used}
                    for s in w.sources
                ],
            }
            for w in result.windows
        ],
        "tracks": [
            {"id": tid, "points": [{"t": t, "x": x, "y": y, "z": z} for t, x, y, z in pts]}
            for tid, pts in result.tracks
        ],
    }
    return write_json(path, doc)


def _num(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ValueError(f"{where}: {v!r} is not a finite number")
    return float(v)


def _int(v: Any, where: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise ValueError(f"{where}: {v!r} is not a whole number")
    return v


def _cov3(v: Any, where: str) -> tuple[tuple[float, float, float], ...]:
    try:
        cov = np.asarray(v, dtype=float)
    except (ValueError, TypeError):
        cov = np.zeros(0)
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise ValueError(f"{where}: 'cov' must be a finite 3x3 matrix")
    return tuple(tuple(float(x) for x in r) for r in cov)


def read_localization(path: PathLike) -> LocalizationResult:
    """Read and validate a localization result JSON."""
    p = Path(path)
    doc = read_json(p)
    if not isinstance(doc, dict) or not isinstance(doc.get("windows"), list):
        raise ValueError(f"{p}: expected an object with a 'windows' list")
    try:
        windows = []
        for k, w in enumerate(doc["windows"]):
            where = f"{p}: window {k}"
            tdoas = []
            for d in w["tdoas"]:
                if not isinstance(d["valid"], bool) or len(d["pair"]) != 2:
                    raise ValueError(f"{where}: a TDOA needs a 2-element 'pair' and a true/false "
                                     "'valid'")
                timing = ((_num(d["t"], where), _num(d["rate"], where)) if "t" in d
                          else (math.nan, math.nan))
                tdoas.append(TdoaRecord((_int(d["pair"][0], where), _int(d["pair"][1], where)),
                                        _num(d["tau"], where), d["valid"], _num(d["llr"], where),
                                        *timing))
            sources = tuple(
                SourceEstimate(_num(s["x"], where), _num(s["y"], where), _num(s["z"], where),
                               _cov3(s["cov"], where), _int(s["tdoas_used"], where))
                for s in w["sources"]
            )
            windows.append(LocalizationWindow(_num(w["t_start"], where), _num(w["t_end"], where),
                                              tuple(tdoas), sources))
        tracks = tuple(
            (_int(t["id"], str(p)),
             tuple((_num(q["t"], str(p)), _num(q["x"], str(p)), _num(q["y"], str(p)),
                    _num(q["z"], str(p))) for q in t["points"]))
            for t in doc.get("tracks", [])
        )
    except (KeyError, TypeError, IndexError) as e:
        raise ValueError(f"{p}: malformed localization result (missing or bad {e})") from None
    return LocalizationResult(tuple(windows), tracks)
