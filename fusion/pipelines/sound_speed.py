"""A recording's sound speed from its localized windows, and the windows re-solved at it.

``fusion localize`` localizes every window at the array file's sound speed, then (by default)
reads the fixes it wrote back, estimates the one speed they share on a factor graph
(:func:`fusion.localization.sound_speed.estimate_sound_speed`) and re-solves every fix at that
speed from the TDOAs it owns (``owned_tdoas`` and ``paths`` of the ``fusion localize`` JSON). It
works on the written windows (the JSON entries of :func:`fusion.pipelines.localization.
result_document`), so it runs after the chunks of a long recording are done, in one pass to
collect the fixes and one to rewrite them.

Which fixes teach the speed: those observable and not mirror-ambiguous that own more TDOAs
than their three coordinates (a fix with exactly three has nothing to say about the speed).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.localization.retime import emission_shift
from fusion.localization.sound_speed import (
    MIN_CALIBRATION_FIXES,
    FixTdoas,
    SoundSpeedEstimate,
    estimate_sound_speed,
    path_sensors,
    refit_fix,
)
from fusion.localization.surface_paths import PATHS
from fusion.pipelines.localization import SEA_SURFACE_Z, UNBOUNDED_M2

__all__ = ["SpeedCalibration", "calibrate_speed", "fix_tdoas"]

#: Added in quadrature to every TDOA sigma, s, as the window's own solve does
#: (:class:`fusion.pipelines.localization.ClickLocalization`'s ``sigma_floor_s``).
SIGMA_FLOOR_S = 1e-6


def fix_tdoas(window: dict, source: dict, sensors: ArrayLike, c: float,
              sigma_floor_s: float = SIGMA_FLOOR_S) -> FixTdoas | None:
    """The TDOAs a written source owns, moved to its emission and read along their paths.

    Returns None for a source without ``owned_tdoas`` (a file of an older version).
    """
    owned = source.get("owned_tdoas")
    if not owned:
        return None
    s = np.asarray(sensors, dtype=float)
    d = [window["tdoas"][k] for k in owned]
    pairs = np.array([t["pair"] for t in d], dtype=np.intp)
    taus = np.array([t["tau"] for t in d], dtype=float)
    rates = np.nan_to_num(np.array([t.get("rate", 0.0) for t in d], dtype=float))
    sig = np.hypot(np.array([t["sigma"] for t in d], dtype=float), sigma_floor_s)
    paths = np.array([PATHS.index(p) for p in source.get("paths", ["direct"] * len(d))])
    pos = np.array([source["x"], source["y"], source["z"]], dtype=float)
    moved = taus + emission_shift(rates, pairs[:, 0], np.isin(paths, (1, 3)), pos, s, c,
                                  SEA_SURFACE_Z)
    s2, q2 = path_sensors(s, pairs, paths, SEA_SURFACE_Z)
    return FixTdoas(s2, q2, moved, sig, np.ones(len(d)), pos)


def _teaches(source: dict, fix: FixTdoas | None) -> bool:
    return (fix is not None and fix.m > 3 and bool(source.get("observable", True))
            and not source.get("mirror_ambiguous", False))


@dataclass(frozen=True)
class SpeedCalibration:
    """The speed a recording's fixes share, and how to rewrite its windows at it.

    Attributes
    ----------
    nominal_mps : float
        The array file's speed, m/s.
    estimate : SoundSpeedEstimate or None
        The estimate; None when the recording had too few fixes to teach it (the windows are
        then left as written).
    note : str
        One line for the user: the speed used and where it came from.
    """

    nominal_mps: float
    estimate: SoundSpeedEstimate | None
    note: str
    sensors: NDArray[np.float64]

    @property
    def speed_mps(self) -> float:
        """The speed the written fixes stand on, m/s."""
        return self.nominal_mps if self.estimate is None else self.estimate.speed_mps

    def record(self) -> dict:
        """What is written beside the output."""
        out = {"source": "array file" if self.estimate is None else "estimated",
               "speed_mps": self.speed_mps, "nominal_mps": self.nominal_mps}
        if self.estimate is not None:
            out.update(self.estimate.to_dict())
        return out

    def apply(self, window: dict) -> dict:
        """The window with each source re-solved at the estimated speed (a new dict)."""
        if self.estimate is None or not window.get("sources"):
            return window
        sources = []
        for src in window["sources"]:
            fix = fix_tdoas(window, src, self.sensors, self.nominal_mps)
            if fix is None:
                sources.append(src)
                continue
            p, cov = refit_fix(fix, self.estimate.speed_mps,
                               variance_factor=self.estimate.variance_factor)
            s2 = fix.sensors
            d = (np.linalg.norm(p - s2[fix.pairs[:, 0]], axis=1)
                 - np.linalg.norm(p - s2[fix.pairs[:, 1]], axis=1)) / self.estimate.speed_mps
            finite = bool(np.all(np.isfinite(cov)))
            sources.append({**src, "x": float(p[0]), "y": float(p[1]), "z": float(p[2]),
                            "cov": np.where(np.isfinite(cov), cov, UNBOUNDED_M2).tolist(),
                            "observable": bool(src.get("observable", True)) and finite,
                            "residual_rms_s": float(np.sqrt(np.mean((d - fix.taus) ** 2)))})
        return {**window, "sources": sources}


def calibrate_speed(windows: Iterable[dict], sensors: ArrayLike, nominal_mps: float
                    ) -> SpeedCalibration:
    """Estimate the speed shared by the fixes of written windows (see the module docstring).

    Parameters
    ----------
    windows : iterable of dict
        The ``fusion localize`` JSON entries of one recording's windows.
    sensors : array_like, shape (n, 3)
        Sensor positions, m.
    nominal_mps : float
        The array file's speed, m/s.
    """
    s = np.asarray(sensors, dtype=float)
    fixes = []
    for w in windows:
        for src in w.get("sources", []):
            fix = fix_tdoas(w, src, s, nominal_mps)
            if _teaches(src, fix):
                fixes.append(fix)
    if len(fixes) < MIN_CALIBRATION_FIXES:
        return SpeedCalibration(nominal_mps, None, (
            f"sound speed: the array file's {nominal_mps:g} m/s ({len(fixes)} fixes with more "
            f"than 3 TDOAs; {MIN_CALIBRATION_FIXES} are needed to estimate it)"), s)
    try:
        est = estimate_sound_speed(fixes, nominal_mps=nominal_mps, n_real_sensors=len(s))
    except (ValueError, RuntimeError) as e:
        return SpeedCalibration(nominal_mps, None, (
            f"sound speed: the array file's {nominal_mps:g} m/s (not estimated: {e})"), s)
    return SpeedCalibration(nominal_mps, est, (
        f"sound speed: {est.speed_mps:.1f} +- {est.sigma_mps:.2g} m/s estimated from "
        f"{est.n_tdoas} TDOAs of {est.n_fixes} fixes (array file {nominal_mps:g} m/s); every "
        "fix re-solved at it (--sound-speed array keeps the file's)"), s)
