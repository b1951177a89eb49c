"""Crossing-detector settings in seconds, read from a bearing table.

The method (*Target Track Crossing Prediction/Detection*) counts its window in samples J of
period K. Recorded tables come at any rate: :func:`crossing_settings` takes the window and the
horizon in seconds, reads the period from the data and turns them into the detector's J and K
(:class:`CrossingSettings`, one line of which says what was chosen).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from fusion.passive.bearing_grid import estimate_period

__all__ = [
    "DEFAULT_CALIBRATE",
    "DEFAULT_CURVATURE",
    "DEFAULT_EXTRAPOLATION",
    "DEFAULT_CONFIRM",
    "DEFAULT_CONFIRM_LEAD",
    "DEFAULT_CONFIRM_OVERLAP",
    "DEFAULT_CURVE_ALPHA",
    "DEFAULT_HORIZON_S",
    "DEFAULT_LADDER_ALPHA",
    "DEFAULT_LEAD_WINDOWS",
    "DEFAULT_LEVEL",
    "DEFAULT_MANOEUVRE_SCALE",
    "DEFAULT_FAR_SIDE",
    "DEFAULT_ALLOWANCE_GATE_LEVEL",
    "DEFAULT_MANOEUVRE_MEMORY_WINDOWS",
    "DEFAULT_N_WINDOWS",
    "DEFAULT_REVISE",
    "DEFAULT_WINDOW_FILL",
    "DEFAULT_WINDOW_S",
    "MAX_SAMPLES_PER_WINDOW",
    "MIN_SAMPLES_PER_WINDOW",
    "CrossingSettings",
    "crossing_settings",
    "crossing_settings_from_steps",
]


@dataclass(frozen=True)
class CrossingSettings:
    """Detector settings for one bearing table, in seconds and in samples.

    Attributes
    ----------
    period_s : float
        Grid period K, s.
    data_step_s : float
        Median time step of the data within tracks, s.
    window_s : float
        Span of the shortest least-squares window, s (``J K``).
    J : int
        Samples in the shortest window.
    n_windows : int
        Windows in the ladder (``J, 2 J, ...``).
    horizon_s : float
        Prediction horizon and widest interval (the fits' own; the allowances may widen an
        alert's interval beyond it on windows they do not gate) that resolves a pair, s.
    lead_windows : float
        Predictions reach this many spans of the window used ahead (never beyond the horizon).
    confirm : int
        Samples in a row a pair must satisfy an inequality before it alerts.
    level : float
        Nominal level of the Fieller intervals.
    curve_alpha : float or None
        Level of the F-test that replaces a window's line by a constant-velocity bearing curve
        (None: lines only).
    ladder_alpha : float or None
        Level of the variance-ratio test that admits a track to a longer window (None: all).
    revise : bool
        A pair's prediction is raised again when its interval no longer overlaps that of the
        prediction raised (False: one prediction per crossing).
    confirm_overlap : bool
        A confirming sample's interval must overlap the one before (False: any hit confirms).
    confirm_lead_windows : float or None
        Confirming samples may predict up to this many window spans ahead (None: as
        `lead_windows`); alerts only within `lead_windows`.
    curvature : bool
        Predictions from lines carry the variance of the curvature the window's line leaves
        out (False: the lines' covariance only).
    manoeuvre_scale : float
        Predictions carry the variance of a bearing rate that wanders with the intensity the
        tracks' own rate changes show, times this (0: off).
    far_side : bool
        The lead-dependent variances are evaluated again at an interval's upper end.
    allowance_gate_level : int or None
        Ladder level from which the widened intervals also decide which pairs alert (None:
        never; they only widen the alerts' intervals).
    curve_manoeuvre : bool
        Pairs judged on curves carry the manoeuvre allowance too (it only widens their
        intervals).
    window_fill : float
        A longer window of the ladder takes part once it holds more than this fraction of its
        samples (1: only full windows).
    manoeuvre_memory_s : float or None
        Time constant over which a track's rate changes are forgotten, s (None: the
        detector's default).
    calibrate : bool
        Predictions' variances grown by the factor the held-out check of each track's earlier
        window asks for (False: the fits' own covariance).
    adjusted : tuple of str
        What was asked and changed, one phrase each (printed by :meth:`describe`).
    """

    period_s: float
    data_step_s: float
    window_s: float
    J: int
    n_windows: int
    horizon_s: float
    lead_windows: float
    confirm: int
    level: float
    curve_alpha: float | None = None
    ladder_alpha: float | None = None
    revise: bool = False
    confirm_overlap: bool = False
    calibrate: bool = False
    curvature: bool = False
    confirm_lead_windows: float | None = None
    manoeuvre_scale: float = 0.0
    far_side: bool = False
    allowance_gate_level: int | None = 0
    manoeuvre_memory_s: float | None = None
    curve_manoeuvre: bool = False
    window_fill: float = 1.0
    adjusted: tuple[str, ...] = ()

    def detector_options(self) -> dict[str, Any]:
        """Keyword arguments of the detector and of :func:`~fusion.passive.crossing.detect_crossings`."""
        return {"J": self.J, "K": self.period_s, "horizon_s": self.horizon_s,
                "n_windows": self.n_windows, "lead_windows": self.lead_windows,
                "confirm": self.confirm, "level": self.level, "curve_alpha": self.curve_alpha,
                "ladder_alpha": self.ladder_alpha, "revise": self.revise,
                "confirm_overlap": self.confirm_overlap, "calibrate": self.calibrate,
                "curvature": self.curvature, "confirm_lead_windows": self.confirm_lead_windows,
                "manoeuvre_scale": self.manoeuvre_scale, "far_side": self.far_side,
                "allowance_gate_level": self.allowance_gate_level,
                "manoeuvre_memory_s": self.manoeuvre_memory_s,
                "curve_manoeuvre": self.curve_manoeuvre, "window_fill": self.window_fill}

    def describe(self) -> str:
        """One line saying what was chosen."""
        longest = self.J * 2 ** (self.n_windows - 1) * self.period_s
        return (f"K={self.period_s:.4g} s (data step {self.data_step_s:.4g} s), windows "
                f"{self.window_s:.4g}-{longest:.4g} s (J={self.J}, {self.n_windows} windows"
                + ("" if self.window_fill >= 1.0 or self.n_windows == 1 else
                   f", longer ones used once more than {self.window_fill:g} full")
                + "), "
                f"predictions up to {self.lead_windows:g} window ahead, horizon "
                f"{self.horizon_s:.4g} s, {self.confirm} sample(s) to confirm"
                + (" (intervals overlapping)" if self.confirm_overlap else "")
                + ("" if self.confirm_lead_windows is None else
                   f" (counted from {self.confirm_lead_windows:g} window ahead)")
                + f", level {self.level:g}"
                + (" (predictions calibrated on held-out samples)" if self.calibrate else "")
                + (" (predictions with the curvature lines leave out)" if self.curvature else "")
                + (f" (predictions with the rate wander the tracks show, x{self.manoeuvre_scale:g})"
                   if self.manoeuvre_scale > 0 else "")
                + (" (curves too)" if self.curve_manoeuvre and self.manoeuvre_scale > 0
                   and self.curve_alpha is not None else "")
                + (" (evaluated at the interval's far end)" if self.far_side else "")
                + ("" if self.allowance_gate_level is None or not (
                    self.far_side or self.manoeuvre_scale > 0) else
                   f" (gating from window {self.allowance_gate_level + 1} of the ladder)")
                + ", "
                + ("straight lines only" if self.curve_alpha is None else
                   f"curves kept at F-test level {self.curve_alpha:g}")
                + (", predictions revised" if self.revise else "")
                + ("" if self.ladder_alpha is None else
                   f", longer windows only where they fit (F-test level {self.ladder_alpha:g})")
                + "".join(f"; ADJUSTED {a}" for a in self.adjusted))


#: Default shortest window, s (chosen on varied scenarios, see benchmarks/RESULTS.md).
DEFAULT_WINDOW_S = 40.0
#: Default prediction horizon and widest interval, s.
DEFAULT_HORIZON_S = 600.0
#: Default number of windows in the ladder (40 s to 1280 s).
DEFAULT_N_WINDOWS = 6
#: Default reach of predictions, in spans of the window used.
DEFAULT_LEAD_WINDOWS = 0.5
#: Default level of the F-test that replaces the shortest window's line by a constant-velocity
#: curve (chosen on tuning seeds, benchmarks/RESULTS.md, issue 19).
DEFAULT_CURVE_ALPHA = 0.001
#: Default level of the variance-ratio test that admits a track to a longer window (issue 19).
DEFAULT_LADDER_ALPHA = 0.01
#: Default: a prediction whose interval moved off the one raised is raised again (issue 19,
#: evening, benchmarks/RESULTS.md).
DEFAULT_REVISE = True
#: Default: a confirming sample's interval must overlap the one before (issue 19, evening).
DEFAULT_CONFIRM_OVERLAP = True
#: Default: predictions' variances calibrated on held-out samples (issue 19, evening).
DEFAULT_CALIBRATE = False
#: Default: line predictions' variance includes the curvature the window leaves out (issue 19,
#: 2026-12-03).
DEFAULT_CURVATURE = True
#: The ``--extrapolation`` default of the command line.
DEFAULT_EXTRAPOLATION = "curvature" if DEFAULT_CURVATURE else "model"
#: Default factor on the estimated rate-wander intensity of predictions (0: off; issue 19,
#: 2026-12-03 afternoon).
DEFAULT_MANOEUVRE_SCALE = 2.0
#: Default: lead-dependent variances evaluated again at the interval's upper end (issue 19,
#: 2026-12-03 afternoon).
DEFAULT_FAR_SIDE = True
#: Default ladder level from which the widened intervals also gate the alerts (2: the windows
#: from the third on; issue 19, 2026-12-03 afternoon).
DEFAULT_ALLOWANCE_GATE_LEVEL = 2
#: Default memory of a track's rate-wander intensity, in shortest windows.
DEFAULT_MANOEUVRE_MEMORY_WINDOWS = 10.0
#: Default: curved pairs' predictions carry the manoeuvre allowance too (issue 19, 2026-12-03
#: late afternoon).
DEFAULT_CURVE_MANOEUVRE = True
#: Default fill beyond which a longer window of the ladder takes part (issue 19, 2026-12-03
#: evening: slow crossings; 1.0 before).
DEFAULT_WINDOW_FILL = 0.5
#: Default: confirming samples counted within the prediction reach only (None).
DEFAULT_CONFIRM_LEAD = None
#: Default number of samples in a row that confirm an alert.
DEFAULT_CONFIRM = 2
#: Default nominal level of the Fieller intervals (see :func:`crossing_settings`).
DEFAULT_LEVEL = 0.99
#: Fewest samples in the shortest window when the window is given in seconds.
MIN_SAMPLES_PER_WINDOW = 10
#: Largest number of samples in the shortest window; denser data is averaged onto a coarser grid.
MAX_SAMPLES_PER_WINDOW = 30


def crossing_settings(
    track_id: ArrayLike,
    time: ArrayLike,
    **options: Any,
) -> CrossingSettings:
    """Window, horizon and grid period of a bearing table, in seconds, from the data.

    Parameters
    ----------
    track_id, time : array_like, shape (m,)
        Track of each sample (negative ids are ignored) and sample times, s.
    **options
        ``window_s``, ``horizon_s``, ``period_s``, ``J`` and the detector's options, as in
        :func:`crossing_settings_from_steps` (with its defaults).

    Returns
    -------
    CrossingSettings

    Notes
    -----
    The defaults were chosen on varied scenarios (``benchmarks/bench_crossings.py --tune``):
    a short first window (40 s, at least ten samples) keeps the lines close to curving tracks,
    the ladder doubles it up to 32 times for pairs it cannot resolve, predictions reach half a
    window ahead and need two samples in a row. The tracks' curvature and the selection of the
    first resolved sample make the fits' nominal 95 % interval too narrow; the nominal level
    0.999 gives intervals that hold the crossing about as often as a 95 % interval should
    (measured coverage in benchmarks/RESULTS.md). Short records get a window of an eighth of
    their median track span if that is shorter. Dense data get a grid period of
    window / :data:`MAX_SAMPLES_PER_WINDOW` (their samples are averaged onto it), so the
    window, not the sampling rate, sets the warning time.
    """
    tid = np.asarray(track_id)
    tt = np.asarray(time, dtype=float)
    step = estimate_period(tid[tid >= 0], tt[tid >= 0])
    ids = np.unique(tid[tid >= 0])
    track_span = float(np.median([np.ptp(tt[tid == k]) for k in ids]))
    return crossing_settings_from_steps(step, track_span, **options)


def crossing_settings_from_steps(
    step_s: float,
    track_span_s: float,
    *,
    window_s: float | None = None,
    horizon_s: float | None = None,
    period_s: float | None = None,
    J: int | None = None,
    n_windows: int = DEFAULT_N_WINDOWS,
    lead_windows: float = DEFAULT_LEAD_WINDOWS,
    confirm: int = DEFAULT_CONFIRM,
    level: float = DEFAULT_LEVEL,
    curve_alpha: float | None = DEFAULT_CURVE_ALPHA,
    ladder_alpha: float | None = DEFAULT_LADDER_ALPHA,
    revise: bool = DEFAULT_REVISE,
    confirm_overlap: bool = DEFAULT_CONFIRM_OVERLAP,
    calibrate: bool = DEFAULT_CALIBRATE,
    curvature: bool = DEFAULT_CURVATURE,
    confirm_lead_windows: float | None = DEFAULT_CONFIRM_LEAD,
    manoeuvre_scale: float = DEFAULT_MANOEUVRE_SCALE,
    far_side: bool = DEFAULT_FAR_SIDE,
    allowance_gate_level: int | None = DEFAULT_ALLOWANCE_GATE_LEVEL,
    manoeuvre_memory_windows: float = DEFAULT_MANOEUVRE_MEMORY_WINDOWS,
    curve_manoeuvre: bool = DEFAULT_CURVE_MANOEUVRE,
    window_fill: float = DEFAULT_WINDOW_FILL,
) -> CrossingSettings:
    """:func:`crossing_settings` from the two numbers it takes of the data.

    Parameters
    ----------
    step_s : float
        Median positive time step within tracks, s
        (:func:`~fusion.passive.bearing_grid.estimate_period`).
    track_span_s : float
        Median time span of the tracks, s.
    window_s : float, optional
        Span of the shortest window, s (default :data:`DEFAULT_WINDOW_S`, or ``J K`` when `J`
        is given).
    horizon_s : float, optional
        Prediction horizon, s (default :data:`DEFAULT_HORIZON_S`, at least the window).
    period_s : float, optional
        Grid period K, s (default: the median time step within tracks, made coarser when the
        window would hold more than :data:`MAX_SAMPLES_PER_WINDOW` samples).
    J : int, optional
        Samples in the shortest window (default ``round(window_s / K)``, at least
        :data:`MIN_SAMPLES_PER_WINDOW`).
    n_windows, lead_windows, confirm, level, curve_alpha, \
ladder_alpha, revise, confirm_overlap, calibrate, curvature, confirm_lead_windows, \
manoeuvre_scale, far_side, allowance_gate_level, curve_manoeuvre, window_fill
        As in :class:`fusion.passive.crossing.CrossingDetector`.
    manoeuvre_memory_windows : float, optional
        Memory of a track's rate-wander intensity, in spans of the shortest window.

    Returns
    -------
    CrossingSettings

    Notes
    -----
    For data read in chunks, where the table is never held at once
    (:class:`~fusion.passive.crossing.summary.BearingStats` gives both numbers exactly).
    """
    step = float(step_s)
    track_span = float(track_span_s)
    if not (np.isfinite(window_fill) and 0.0 < window_fill <= 1.0):
        raise ValueError(f"window_fill must lie in (0, 1], got {window_fill!r}")
    if not (np.isfinite(manoeuvre_memory_windows) and manoeuvre_memory_windows > 0):
        raise ValueError(f"manoeuvre_memory_windows must be > 0, got {manoeuvre_memory_windows!r}")
    for name, v in (("window_s", window_s), ("horizon_s", horizon_s), ("period_s", period_s)):
        if v is not None and not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be > 0, got {v!r}")
    if J is not None and (int(J) != J or J < 3):
        raise ValueError(f"J must be an integer > 2, got {J!r}")
    span = min(DEFAULT_WINDOW_S, max(3.0 * step, track_span / 8.0)) if window_s is None \
        else float(window_s)
    if period_s is not None:
        K = float(period_s)
    elif J is not None and window_s is None:
        K = step
    else:
        K = max(step, span / MAX_SAMPLES_PER_WINDOW)
    adjusted = []
    if J is None:
        J = max(MIN_SAMPLES_PER_WINDOW, int(round(span / K)))
        if window_s is not None and abs(J * K - span) > 0.5 * K:
            why = (f"at least {MIN_SAMPLES_PER_WINDOW} samples of K={K:.4g} s"
                   if J == MIN_SAMPLES_PER_WINDOW else f"whole samples of K={K:.4g} s")
            adjusted.append(f"window {span:.4g} s -> {J * K:.4g} s ({why})")
    elif window_s is not None:
        adjusted.append(f"window {float(window_s):.4g} s -> {J * K:.4g} s (J={J} samples given)")
    window = J * K
    horizon = max(DEFAULT_HORIZON_S, window) if horizon_s is None else float(horizon_s)
    return CrossingSettings(period_s=K, data_step_s=step, window_s=window, J=int(J),
                            n_windows=int(n_windows), horizon_s=horizon,
                            lead_windows=float(lead_windows), confirm=int(confirm),
                            level=float(level),
                            curve_alpha=None if curve_alpha is None else float(curve_alpha),
                            ladder_alpha=None if ladder_alpha is None else float(ladder_alpha),
                            revise=bool(revise), confirm_overlap=bool(confirm_overlap),
                            calibrate=bool(calibrate), curvature=bool(curvature),
                            confirm_lead_windows=None if confirm_lead_windows is None
                            else float(confirm_lead_windows),
                            manoeuvre_scale=float(manoeuvre_scale), far_side=bool(far_side),
                            allowance_gate_level=None if allowance_gate_level is None
                            else int(allowance_gate_level),
                            manoeuvre_memory_s=float(manoeuvre_memory_windows) * window,
                            curve_manoeuvre=bool(curve_manoeuvre),
                            window_fill=float(window_fill),
                            adjusted=tuple(adjusted))
