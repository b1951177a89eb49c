"""The lines of the fans (program segments 46-54): two interchangeable strategies behind one base.

A fan is the set of candidate lines through one anchor beam at the latest update; the
acquisition searches the fans of the anchor beams around the click for the line with the largest
mean BTR value (segments 46-50), derives the band noise level off that line (segment 52) and
turns it into a bearing rate (segment 54). :class:`FanStrategy` is what differs between kinds of
line:

- :class:`StraightLineFans`: the method's literal straight lines in beam number
  (:func:`~fusion.passive.acquisition.lines.best_lines_in_fans`), the beam rate turned into a
  bearing rate by eq. 10 at the middle (or the latest end) of the line;
- :class:`ConstantRateFans` (the default of :class:`~fusion.passive.acquisition.Acquisition`):
  constant-bearing-rate traces in the cosine beam spacing the method assumes (eqs. 5-11,
  :func:`~fusion.passive.acquisition.traces.best_traces_in_fans`), refined to a sub-beam end
  position and rate (:func:`~fusion.passive.acquisition.refine.refine_trace`).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import bearing_rate_from_beam_rate
from fusion.passive.acquisition.lines import best_lines_in_fans, slope_grid
from fusion.passive.acquisition.refine import refine_trace
from fusion.passive.acquisition.traces import best_traces_in_fans, constant_rate_traces

__all__ = ["BestLine", "ConstantRateFans", "FanStrategy", "StraightLineFans"]


@dataclass(frozen=True)
class BestLine:
    """The overall best line on the IBW BTR (program segment 50), for plotting and checks.

    Attributes
    ----------
    anchor_beam : int
        Beam the best line's fan is anchored at, at the latest scan (the method's ``bestbeam``).
    beam_rate_per_scan : float
        Mean slope forward in time, beams per scan: for a straight line minus the method's
        ``brgratebpu`` (which runs backwards from the latest update); for a constant-bearing-rate
        trace ``(end_beam - start_beam) / (n_scans_used - 1)``.
    start_scan, end_scan : int
        Oldest and latest scans the line spans (chronological scan indices, ``end_scan`` the latest).
    start_beam, end_beam : float
        Beam positions of the line at `start_scan` and `end_scan` (unrounded; after refinement for
        a refined trace).
    n_scans_used : int
        Scans the line spans.
    signal_plus_noise : float
        Mean IBW BTR value along the fan search's best line (the method's ``signalplusnoise``).
    trace : {"beam", "bearing"}
        Straight line in beam number (the literal method) or constant-bearing-rate trace.
    bearing_rate_deg_per_min : float
        Bearing rate of a constant-bearing-rate trace, deg/min (NaN for a straight line).
    coarse_end_beam : float
        End beam found by the fan search, before refinement (the anchor beam).
    coarse_bearing_rate_deg_per_min : float
        Bearing rate of the fan search's best trace, before refinement (NaN for a straight line).
    refined : bool
        Whether the sub-beam refinement was applied.
    beams : ndarray, shape (n_scans_used,)
        Fractional beam of the line at scans ``start_scan .. end_scan`` (chronological).
    """

    anchor_beam: int
    beam_rate_per_scan: float
    start_scan: int
    end_scan: int
    start_beam: float
    end_beam: float
    n_scans_used: int
    signal_plus_noise: float
    trace: Literal["beam", "bearing"] = "beam"
    bearing_rate_deg_per_min: float = float("nan")
    coarse_end_beam: float = float("nan")
    coarse_bearing_rate_deg_per_min: float = float("nan")
    refined: bool = False
    beams: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))


def _positive_or_none(name: str, value: float | None) -> None:
    if value is not None and (not np.isfinite(value) or value <= 0):
        raise ValueError(f"{name} must be positive, got {value!r}")


class FanStrategy(ABC):
    """How the fans' lines are drawn, searched, refined and turned into a bearing rate.

    Subclasses are configured in their constructor; :class:`fusion.passive.acquisition.Acquisition`
    calls the four methods in the order of the method's program segments.
    """

    #: ``"beam"`` (straight in beam number) or ``"bearing"`` (constant bearing rate).
    trace: ClassVar[Literal["beam", "bearing"]]

    @abstractmethod
    def search(
        self, btr_latest_first: NDArray[np.float64], anchors: NDArray[np.int64], *,
        min_scans: int, scan_period: float,
    ) -> BestLine | None:
        """Segments 46-50: the best line of every fan, then the overall best.

        Parameters
        ----------
        btr_latest_first : ndarray, shape (n_scans, n_beams)
            IBW BTR, row 0 the latest update.
        anchors : ndarray of int, shape (n_fans,)
            Anchor beams.
        min_scans : int
            The method's ``minscan``.
        scan_period : float
            Time between scans, s.

        Returns
        -------
        BestLine or None
            None when no line of any fan qualified.
        """

    @abstractmethod
    def extend(self, line: BestLine, *, n_scans: int, n_beams: int,
               scan_period: float) -> NDArray[np.float64]:
        """Fractional beam of the line at every scan, latest first, also beyond where it leaves
        the BTR (the cells segment 52 leaves out of the band noise level), shape (n_scans,)."""

    def refine_line(
        self, line: BestLine, btr_latest_first: NDArray[np.float64], *, min_scans: int,
        scan_period: float, lobe_beams: float, noise_level: float,
    ) -> BestLine:
        """The line refined between segments 52 and 54 (default: unchanged).

        Parameters
        ----------
        line : BestLine
            The overall best line.
        btr_latest_first : ndarray, shape (n_scans, n_beams)
            IBW BTR, row 0 the latest update.
        min_scans : int
            The method's ``minscan``.
        scan_period : float
            Time between scans, s.
        lobe_beams : float
            Half-width of the main lobe to its first nulls, beams.
        noise_level : float
            Band noise level.
        """
        return line

    @abstractmethod
    def bearing_rate(self, line: BestLine, *, n_beams: int, scan_period: float) -> float:
        """Segment 54: the line's bearing rate, rad/s forward in time."""


class StraightLineFans(FanStrategy):
    """The method's literal fans: straight lines ``fbeam = a * iscan + anchor`` in beam number.

    Parameters
    ----------
    max_slope : float, optional
        Largest slope magnitude searched, beams per update; None: the slope that crosses all
        beams in ``min_scans`` scans, ``(n_beams - 1) / (min_scans - 1)``.
    slope_step : float, optional
        Slope increment, beams per update; None: a quarter of a beam over the history,
        ``0.25 / (n_scans - 1)``.
    rate_at : {"midpoint", "latest"}
        Beam at which the beam rate is turned into a bearing rate (eq. 10): the middle of the
        line (default) or its latest end.

    Notes
    -----
    At constant bearing rate the chord of the curved trace has beam rate
    ``(N - 1) / 2 sin(theta) theta_dot`` at the *mean* bearing to within ``sinc(delta_theta / 2)``,
    hence the midpoint default for eq. 10.
    """

    trace: ClassVar[Literal["beam"]] = "beam"

    def __init__(self, *, max_slope: float | None = None, slope_step: float | None = None,
                 rate_at: Literal["midpoint", "latest"] = "midpoint") -> None:
        _positive_or_none("max_slope", max_slope)
        _positive_or_none("slope_step", slope_step)
        if rate_at not in ("midpoint", "latest"):
            raise ValueError(f"rate_at must be 'midpoint' or 'latest', got {rate_at!r}")
        self.max_slope = max_slope
        self.slope_step = slope_step
        self.rate_at = rate_at

    def search(
        self, btr_latest_first: NDArray[np.float64], anchors: NDArray[np.int64], *,
        min_scans: int, scan_period: float,
    ) -> BestLine | None:
        n_scans, n_beams = btr_latest_first.shape
        max_slope = ((n_beams - 1) / (min_scans - 1) if self.max_slope is None
                     else float(self.max_slope))
        step = 0.25 / (n_scans - 1) if self.slope_step is None else float(self.slope_step)
        fans = best_lines_in_fans(btr_latest_first, anchors,
                                  slope_grid(-max_slope, max_slope, step), min_scans=min_scans)
        if not fans.found.any():
            return None
        i = int(np.argmax(np.where(fans.found, fans.signal_plus_noise, -np.inf)))
        bestbeam, a, n_used = int(fans.anchors[i]), float(fans.slope[i]), int(fans.n_used[i])
        return BestLine(
            anchor_beam=bestbeam,
            beam_rate_per_scan=-a,
            start_scan=n_scans - n_used,
            end_scan=n_scans - 1,
            start_beam=bestbeam + a * (n_used - 1),
            end_beam=float(bestbeam),
            n_scans_used=n_used,
            signal_plus_noise=float(fans.signal_plus_noise[i]),
            trace="beam",
            coarse_end_beam=float(bestbeam),
            beams=bestbeam + a * np.arange(n_used)[::-1].astype(float),
        )

    def extend(self, line: BestLine, *, n_scans: int, n_beams: int,
               scan_period: float) -> NDArray[np.float64]:
        return line.end_beam - line.beam_rate_per_scan * np.arange(n_scans)

    def bearing_rate(self, line: BestLine, *, n_beams: int, scan_period: float) -> float:
        beam_rate = line.beam_rate_per_scan / scan_period  # beams/s, forward in time
        ref_beam = (0.5 * (line.start_beam + line.end_beam)
                    if self.rate_at == "midpoint" else line.end_beam)
        return float(bearing_rate_from_beam_rate(ref_beam, beam_rate, n_beams))  # eq. 10


class ConstantRateFans(FanStrategy):
    """Fans of constant-bearing-rate traces in cosine-spaced beams, refined to sub-beam accuracy.

    Parameters
    ----------
    max_rate_deg_per_min : float, optional
        Largest bearing-rate magnitude searched, deg/min; None: 180 deg over ``min_scans - 1``
        scans (the analogue of a line crossing all beams).
    rate_step_deg_per_min : float, optional
        Bearing-rate increment, deg/min; None: the increment that moves a broadside trace's oldest
        scan by a quarter of a beam, ``0.25 / ((N - 1) / 2 * history)`` rad/s (the straight
        lines' quarter beam over the history).
    sampling : {"nearest", "linear"}
        How a trace reads the BTR: the nearest beam (the method's rounding, default) or linear
        interpolation across beams.
    refine : bool
        Refine the overall best trace to a sub-beam end position and rate
        (:func:`~fusion.passive.acquisition.refine.refine_trace`; default True).
    refine_span_beams : float
        Half-size of the refinement's search box, beams (default 2).

    Notes
    -----
    Segment 54 for a trace: the bearing of its (refined) end beam (eq. 6) and its bearing rate,
    which is already in rad/s (the trace is the integral of eq. 11).
    """

    trace: ClassVar[Literal["bearing"]] = "bearing"

    def __init__(
        self, *, max_rate_deg_per_min: float | None = None,
        rate_step_deg_per_min: float | None = None,
        sampling: Literal["nearest", "linear"] = "nearest", refine: bool = True,
        refine_span_beams: float = 2.0,
    ) -> None:
        _positive_or_none("max_rate_deg_per_min", max_rate_deg_per_min)
        _positive_or_none("rate_step_deg_per_min", rate_step_deg_per_min)
        _positive_or_none("refine_span_beams", refine_span_beams)
        if sampling not in ("nearest", "linear"):
            raise ValueError(f"sampling must be 'nearest' or 'linear', got {sampling!r}")
        self.max_rate_deg_per_min = max_rate_deg_per_min
        self.rate_step_deg_per_min = rate_step_deg_per_min
        self.sampling = sampling
        self.refine = bool(refine)
        self.refine_span_beams = float(refine_span_beams)

    def search(
        self, btr_latest_first: NDArray[np.float64], anchors: NDArray[np.int64], *,
        min_scans: int, scan_period: float,
    ) -> BestLine | None:
        n_scans, n_beams = btr_latest_first.shape
        max_rate = (math.pi / ((min_scans - 1) * scan_period) if self.max_rate_deg_per_min is None
                    else math.radians(self.max_rate_deg_per_min) / 60.0)
        step = (0.25 / ((n_beams - 1) / 2.0 * (n_scans - 1) * scan_period)
                if self.rate_step_deg_per_min is None
                else math.radians(self.rate_step_deg_per_min) / 60.0)
        k = int(math.floor(max_rate / step + 1e-9))
        rates = step * np.arange(-k, k + 1)  # symmetric, 0 included
        fans = best_traces_in_fans(btr_latest_first, anchors, rates, scan_period=scan_period,
                                   min_scans=min_scans, sampling=self.sampling)
        if not fans.found.any():
            return None
        i = int(np.argmax(np.where(fans.found, fans.signal_plus_noise, -np.inf)))
        rate = float(fans.rate_rad_s[i])
        return self._trace_line(n_scans, n_beams, scan_period, anchor=int(fans.anchors[i]),
                                end=float(fans.anchors[i]), rate=rate, coarse_rate=rate,
                                spn=float(fans.signal_plus_noise[i]), refined=False)

    def extend(self, line: BestLine, *, n_scans: int, n_beams: int,
               scan_period: float) -> NDArray[np.float64]:
        return constant_rate_traces(
            line.end_beam, math.radians(line.bearing_rate_deg_per_min) / 60.0,
            n_scans=n_scans, n_beams=n_beams, scan_period=scan_period)[0]

    def refine_line(
        self, line: BestLine, btr_latest_first: NDArray[np.float64], *, min_scans: int,
        scan_period: float, lobe_beams: float, noise_level: float,
    ) -> BestLine:
        if not self.refine:
            return line
        n_scans, n_beams = btr_latest_first.shape
        coarse_rate = math.radians(line.bearing_rate_deg_per_min) / 60.0
        ref = refine_trace(btr_latest_first, line.end_beam, coarse_rate, scan_period=scan_period,
                           min_scans=min_scans, lobe_beams=lobe_beams, noise_level=noise_level,
                           span_beams=self.refine_span_beams)
        return self._trace_line(n_scans, n_beams, scan_period, anchor=line.anchor_beam,
                                end=ref.end_beam, rate=ref.rate_rad_s, coarse_rate=coarse_rate,
                                spn=line.signal_plus_noise, refined=True)

    def bearing_rate(self, line: BestLine, *, n_beams: int, scan_period: float) -> float:
        return math.radians(line.bearing_rate_deg_per_min) / 60.0

    @staticmethod
    def _trace_line(
        n_scans: int, n_beams: int, scan_period: float, *, anchor: int, end: float,
        rate: float, coarse_rate: float, spn: float, refined: bool,
    ) -> BestLine:
        pos, n_used = constant_rate_traces(end, rate, n_scans=n_scans, n_beams=n_beams,
                                           scan_period=scan_period)
        n_used = int(n_used)
        beams = pos[:n_used][::-1].copy()  # chronological
        return BestLine(
            anchor_beam=anchor,
            beam_rate_per_scan=float((beams[-1] - beams[0]) / max(n_used - 1, 1)),
            start_scan=n_scans - n_used,
            end_scan=n_scans - 1,
            start_beam=float(beams[0]),
            end_beam=float(end),
            n_scans_used=n_used,
            signal_plus_noise=spn,
            trace="bearing",
            bearing_rate_deg_per_min=math.degrees(rate) * 60.0,
            coarse_end_beam=float(anchor),
            coarse_bearing_rate_deg_per_min=math.degrees(coarse_rate) * 60.0,
            refined=refined,
            beams=beams,
        )
