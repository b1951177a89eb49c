"""Localize events found by any detector: waveform TDOAs, a factor-graph solve, a surface check.

An :class:`Event` is a time span on the audio, optionally with a frequency box (a detector's
output, e.g. a spectrogram blob). :class:`EventLocalizer` turns each into an :class:`EventFix`:

1. cut the event with a margin of the array's largest delay (a little more) on each side, and
   band-pass every channel to the event's band (given, or estimated from the event against the
   noise before it, :func:`fusion.localization.event_tdoa.estimate_band`);
2. cross-correlate every sensor pair within its physically possible lags, to a fraction of a
   sample, with a standard deviation from the data (:func:`fusion.localization.event_tdoa.pair_tdoas`);
3. set aside TDOAs that break their triangle closures (:func:`~fusion.localization.event_tdoa.
   closure_screen`);
4. start from the best points of a TDOA-misfit grid over a box a few array apertures wide,
   solve on a factor graph (:func:`factors.tdoa.solve_source`, least squares, then Huber with the
   sigmas scaled by the fit's variance factor) and keep the marginal covariance;
5. sample the hyperbolic intensity of eq. (17) over the same box, refine its peak, and report
   whether it agrees with the solve.

Every length scale comes from the array (its aperture, its sensor distances), none from an
assumed range: a 1.7 m frame with sources a metre away works as a kilometre array does.

Notes
-----
Steps 2 and 4 follow eq. (14)-(15) of *Localization of Short Duration Periodic Signals*
(Baggenstoss, NUWC 102089); step 5 is its eq. (16)-(17). The covariance: the ``m`` all-pair TDOAs
of ``n`` channels hold only ``rank = n - 1`` independent delays, and noise on one channel moves
all its pairs together, so the factor's covariance (which takes the TDOAs as independent) is
multiplied by ``m / rank`` -- exact when the errors are per-channel arrival errors, conservative
when they are independent per pair -- and by the variance factor ``max(1, chi^2 rank / (m (rank
- 3)))`` (the reduced chi-square of the fit counted in independent delays) so that misfit beyond
the data sigmas (array-position or sound-speed error, multipath) widens the interval.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from factors.tdoa import solve_source
from factors.tdoa.model import predicted_tdoas
from fusion._validation import check_positive
from fusion.geometry import SensorArray
from fusion.localization.event_tdoa import (
    MAX_EDGE_FRACTION,
    PairTdoas,
    bandpass,
    closure_screen,
    estimate_band,
    pair_tdoas,
)
from fusion.localization.surfaces import (
    SearchRegion,
    WindowTdoas,
    array_aperture,
    intensity_volume,
    refine_peak,
    sensor_distances,
)
from fusion.types import frozen_array

__all__ = ["Event", "EventFix", "EventLocalizer"]

logger = logging.getLogger(__name__)
_TDOA_LOG = logging.getLogger("factors.tdoa")


@contextmanager
def _quiet(log: logging.Logger) -> Iterator[None]:
    """Hold back `log`'s records below ERROR (each start of a solve would warn on its own)."""

    def keep(record: logging.LogRecord) -> bool:
        return record.levelno >= logging.ERROR

    log.addFilter(keep)
    try:
        yield
    finally:
        log.removeFilter(keep)

#: Two-sided 95 % quantile of the standard normal (per-axis intervals).
Z95 = float(stats.norm.ppf(0.975))


@dataclass(frozen=True)
class Event:
    """A detection to localize: a time span and an optional frequency box.

    Attributes
    ----------
    t_start, t_end : float
        Span, s from the start of the audio (``0 <= t_start < t_end``).
    f_low, f_high : float or None
        Frequency box, Hz; None (either) lets the localizer estimate the band. A zero
        ``f_low`` means "from the lowest frequency" and is raised to the band floor.
    """

    t_start: float
    t_end: float
    f_low: float | None = None
    f_high: float | None = None

    def __post_init__(self) -> None:
        t0, t1 = float(self.t_start), float(self.t_end)
        if not (np.isfinite(t0) and np.isfinite(t1) and 0 <= t0 < t1):
            raise ValueError(f"event times must satisfy 0 <= t_start < t_end, got {t0}, {t1}")
        for name in ("f_low", "f_high"):
            v = getattr(self, name)
            if v is not None and not (np.isfinite(v) and v >= 0):
                raise ValueError(f"event {name} must be a finite frequency >= 0, got {v!r}")
        if self.f_low is not None and self.f_high is not None and not self.f_low < self.f_high:
            raise ValueError(f"event f_low {self.f_low} must be below f_high {self.f_high}")
        object.__setattr__(self, "t_start", t0)
        object.__setattr__(self, "t_end", t1)


@dataclass(frozen=True)
class EventFix:
    """The localization of one event.

    Attributes
    ----------
    event : Event
        The event.
    band_hz : (float, float)
        Pass band used, Hz.
    band_source : str
        ``"given"`` (the event's box), ``"estimated"`` (from the data) or ``"default"``.
    tdoas : PairTdoas
        All pairs' delays, s, and their data sigmas (before the variance factor), s.
    used : ndarray of bool, shape (m,)
        TDOAs that entered the solve (usable and closure-consistent).
    position : ndarray, shape (3,)
        Source position, m; NaN when not observable (the solver's iterate then runs off along
        the weakest direction, to 1e7-1e11 m on the XAV recording, and is no position).
    covariance : ndarray, shape (3, 3)
        Its covariance, m^2 (NaN when not observable); see the module Notes.
    interval_95 : ndarray, shape (3, 2)
        Per-axis 95 % interval ``position -+ 1.96 sqrt(diag(covariance))``, m (NaN likewise).
    residual_rms_s : float
        RMS TDOA residual of the used TDOAs at the solution, s.
    closure_rms_s : float
        RMS triangle closure of the usable TDOAs, s.
    variance_factor : float
        Factor (>= 1) the sigmas and covariance were widened by to match the misfit.
    observable : bool
        The solve's observability (:class:`factors.tdoa.TdoaSolveInfo`) and a finite position.
    in_region : bool
        Position inside the search box.
    surface_peak : ndarray, shape (3,)
        Refined peak of the eq. (17) intensity over the box, m (NaN when not computed).
    surface_agrees : bool or None
        The peak lies within the 99 % ellipsoid of the solve (or within two of the surface's
        final grid cells); None when the check was not run.
    """

    event: Event
    band_hz: tuple[float, float]
    band_source: str
    tdoas: PairTdoas
    used: NDArray[np.bool_]
    position: NDArray[np.float64]
    covariance: NDArray[np.float64]
    interval_95: NDArray[np.float64]
    residual_rms_s: float
    closure_rms_s: float
    variance_factor: float
    observable: bool
    in_region: bool
    surface_peak: NDArray[np.float64] = field(default_factory=lambda: frozen_array([np.nan] * 3))
    surface_agrees: bool | None = None

    def __post_init__(self) -> None:
        for name in ("position", "covariance", "interval_95", "surface_peak"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        object.__setattr__(self, "used", frozen_array(self.used, bool))

    @property
    def n_used(self) -> int:
        """Number of TDOAs in the solve."""
        return int(self.used.sum())


def _as_event(e: Event | Sequence[float | None]) -> Event:
    if isinstance(e, Event):
        return e
    vals = list(e)
    if len(vals) not in (2, 4):
        raise ValueError(f"an event is (t_start, t_end[, f_low, f_high]), got {e!r}")
    return Event(*vals)


def _rank(pairs: NDArray[np.intp], n: int) -> int:
    if pairs.shape[0] == 0:
        return 0
    inc = np.zeros((pairs.shape[0], n))
    inc[np.arange(pairs.shape[0]), pairs[:, 0]] = 1.0
    inc[np.arange(pairs.shape[0]), pairs[:, 1]] = -1.0
    return int(np.linalg.matrix_rank(inc))


class EventLocalizer:
    """Localize detected events from multichannel audio (see the module docstring).

    Parameters
    ----------
    band_floor_hz : float, keyword-only
        Lowest band edge, Hz (a zero ``f_low`` is raised to it; also the floor of estimated
        bands). Default 10 Hz: below it hydrophone records carry flow noise and drift.
    default_band_hz : (float, float), optional, keyword-only
        Band for events without a frequency box whose band cannot be estimated; default from
        `band_floor_hz` to 0.45 of the sample rate.
    band_snr_db : float, keyword-only
        Event-to-noise power ratio that marks the estimated band, dB.
    noise_s : float, keyword-only
        Background taken before an event (after it when the audio starts too soon) to estimate
        its band, s (at least the event's length).
    filter_order : int, keyword-only
        Butterworth order (zero-phase, so twice this in effect).
    delay_margin : float, keyword-only
        The cut extends ``delay_margin`` times the largest possible delay (aperture / c) on each
        side of the event.
    upsample : int, keyword-only
        Fine-lag factor of the correlation peak search.
    closure_sigmas : float, keyword-only
        Triangle-closure threshold in standard deviations.
    huber_k : float, keyword-only
        Huber threshold of the robust solve, in (scaled) sigmas; 0 disables the robust stage.
    region_apertures : float, keyword-only
        Half-width of the search box (start grid and surface) in array apertures.
    grid_points : int, keyword-only
        Points of the coarse grid over the box.
    n_starts : int, keyword-only
        Grid minima the solve starts from (the lowest final cost wins).
    surface : bool, keyword-only
        Compute the eq. (17) surface check.

    Examples
    --------
    >>> loc = EventLocalizer()
    >>> loc.region_apertures
    3.0
    """

    def __init__(
        self,
        *,
        band_floor_hz: float = 10.0,
        default_band_hz: tuple[float, float] | None = None,
        band_snr_db: float = 6.0,
        noise_s: float = 1.0,
        filter_order: int = 4,
        delay_margin: float = 1.5,
        upsample: int = 16,
        closure_sigmas: float = 3.0,
        huber_k: float = 1.345,
        region_apertures: float = 3.0,
        grid_points: int = 32_768,
        n_starts: int = 3,
        surface: bool = True,
    ) -> None:
        self.band_floor_hz = check_positive("band_floor_hz", band_floor_hz)
        if default_band_hz is not None:
            lo, hi = (float(v) for v in default_band_hz)
            if not (0 < lo < hi and np.isfinite(hi)):
                raise ValueError(f"default_band_hz must be (low, high) with 0 < low < high, got "
                                 f"{default_band_hz!r}")
            default_band_hz = (lo, hi)
        self.default_band_hz = default_band_hz
        self.band_snr_db = float(band_snr_db)
        self.noise_s = check_positive("noise_s", noise_s)
        if int(filter_order) != filter_order or not 1 <= filter_order <= 12:
            raise ValueError(f"filter_order must be an integer in 1..12, got {filter_order!r}")
        self.filter_order = int(filter_order)
        self.delay_margin = check_positive("delay_margin", delay_margin)
        if self.delay_margin < 1.0:
            raise ValueError(f"delay_margin must be >= 1 (the cut must hold every possible "
                             f"delay), got {delay_margin!r}")
        if int(upsample) != upsample or upsample < 1:
            raise ValueError(f"upsample must be a positive integer, got {upsample!r}")
        self.upsample = int(upsample)
        self.closure_sigmas = check_positive("closure_sigmas", closure_sigmas)
        self.huber_k = check_positive("huber_k", huber_k, allow_zero=True)
        self.region_apertures = check_positive("region_apertures", region_apertures)
        if int(grid_points) != grid_points or grid_points < 27:
            raise ValueError(f"grid_points must be an integer >= 27, got {grid_points!r}")
        self.grid_points = int(grid_points)
        if int(n_starts) != n_starts or n_starts < 1:
            raise ValueError(f"n_starts must be a positive integer, got {n_starts!r}")
        self.n_starts = int(n_starts)
        self.surface = bool(surface)

    # ------------------------------------------------------------------ the verb
    def localize(
        self,
        audio: ArrayLike,
        fs: float,
        sensors: SensorArray,
        events: Iterable[Event | Sequence[float | None]],
    ) -> list[EventFix]:
        """Localize each event.

        Parameters
        ----------
        audio : array_like, shape (n_samples, n_sensors)
            Synchronous samples, column ``i`` = ``sensors.positions[i]``.
        fs : float
            Sample rate, Hz.
        sensors : SensorArray
            Sensor positions (m) and sound speed (m/s).
        events : iterable of Event or (t_start, t_end[, f_low, f_high])
            Events, s and Hz (None for a missing band edge).

        Returns
        -------
        list of EventFix
            One per event, in order.

        Raises
        ------
        ValueError
            Audio of the wrong shape or non-finite, a bad sample rate, an event outside the
            audio or whose band is empty at this sample rate.
        """
        x = np.asarray(audio, dtype=float)
        if x.ndim != 2 or x.shape[1] != sensors.n_sensors:
            raise ValueError(f"audio must have shape (n_samples, {sensors.n_sensors}), got "
                             f"{x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError("audio contains NaN or infinite samples")
        fs = check_positive("fs", fs)
        evs = [_as_event(e) for e in events]
        duration = x.shape[0] / fs
        for k, e in enumerate(evs):
            if e.t_start >= duration:
                raise ValueError(f"event {k} starts at {e.t_start:g} s, after the end of the "
                                 f"audio ({duration:g} s)")
        s = sensors.positions
        region = SearchRegion(extent_factor=self.region_apertures, max_points=self.grid_points)
        grid = region.volume(s)
        lo, hi = region.bounds(s)
        dist = sensor_distances(grid, s)
        return [self._one(x, fs, sensors, e, k, grid, dist, (lo, hi)) for k, e in enumerate(evs)]

    # ------------------------------------------------------------------ steps
    def _band(self, x: NDArray, fs: float, e: Event, a: int, b: int
              ) -> tuple[tuple[float, float], str]:
        top = MAX_EDGE_FRACTION * fs
        if e.f_low is not None and e.f_high is not None:
            band, source = (max(e.f_low, self.band_floor_hz), min(e.f_high, top)), "given"
        else:
            noise_n = max(int(round(self.noise_s * fs)), b - a)
            noise = x[max(0, a - noise_n):a] if a >= noise_n // 2 else x[b:b + noise_n]
            est = estimate_band(x[a:b], noise, fs, snr_db=self.band_snr_db,
                                floor_hz=self.band_floor_hz)
            if est is None:
                band = self.default_band_hz or (self.band_floor_hz, top)
                band, source = (max(band[0], self.band_floor_hz), min(band[1], top)), "default"
            else:
                band, source = est, "estimated"
                if e.f_low is not None:
                    band = (max(e.f_low, self.band_floor_hz), band[1])
                if e.f_high is not None:
                    band = (band[0], min(e.f_high, top))
        if not band[0] < band[1]:
            raise ValueError(f"event at {e.t_start:g}-{e.t_end:g} s: band {band[0]:g}-{band[1]:g} "
                             f"Hz is empty (sample rate {fs:g} Hz, band floor "
                             f"{self.band_floor_hz:g} Hz)")
        return band, source

    def _starts(self, tdoas: WindowTdoas, grid, dist: NDArray) -> list[NDArray[np.float64]]:
        """The `n_starts` best separated points of the TDOA misfit on the grid."""
        first, second = tdoas.pairs[:, 0], tdoas.pairs[:, 1]
        sig = np.sqrt(tdoas.sigmas**2 + (grid.step / tdoas.c) ** 2)  # a cell's delay span
        r = ((dist[:, first] - dist[:, second]) / tdoas.c - tdoas.taus) / sig
        cost = np.log1p(0.5 * r * r).sum(axis=1)  # Cauchy misfit: a wrong TDOA cannot dominate
        order = np.argsort(cost)
        starts: list[NDArray[np.float64]] = []
        for k in order[:2000]:
            p = grid.points(int(k), int(k) + 1)[0]
            if all(np.linalg.norm(p - q) > 2.5 * grid.step for q in starts):
                starts.append(p)
            if len(starts) == self.n_starts:
                break
        return starts

    def _solve(self, s: NDArray, tdoas: WindowTdoas, starts: list[NDArray], c: float) -> tuple:
        """Least-squares solve from each start; the finite one of lowest cost (or None)."""
        best = None
        for p0 in starts:  # an unobservable start is reported once per event, not per start
            try:
                out = solve_source(s, tdoas.pairs, tdoas.taus, tdoas.sigmas, c=c, initial=p0)
            except (RuntimeError, ValueError) as err:  # a failed start; others may succeed
                logger.debug("solve from %s failed: %s", p0, err)
                continue
            if np.all(np.isfinite(out[0])) and (best is None or out[2].cost < best[2].cost):
                best = out
        return best

    def _one(self, x: NDArray, fs: float, sensors: SensorArray, e: Event, index: int, grid,
             dist: NDArray, box: tuple[NDArray, NDArray]) -> EventFix:
        s, c = sensors.positions, sensors.sound_speed
        n_sens = sensors.n_sensors
        margin_s = self.delay_margin * array_aperture(s) / c + 2.0 / fs
        a = max(0, int(np.floor((e.t_start - margin_s) * fs)))
        b = min(x.shape[0], int(np.ceil((e.t_end + margin_s) * fs)))
        band, source = self._band(x, fs, e, a, b)
        pad = int(np.ceil(4.0 / band[0] * fs))  # four periods of the low edge: the filter settles
        pa, pb = max(0, a - pad), min(x.shape[0], b + pad)
        y = bandpass(x[pa:pb], fs, band, order=self.filter_order)[a - pa:a - pa + (b - a)]
        meas = pair_tdoas(y, fs, s, c, band_hz=band, upsample=self.upsample)
        usable = meas.usable
        keep, closure_rms = closure_screen(meas.pairs, meas.taus, meas.sigmas, usable,
                                           n_sigma=self.closure_sigmas)
        nan3 = np.full(3, np.nan)
        fail = dict(event=e, band_hz=band, band_source=source, tdoas=meas, used=keep,
                    position=nan3, covariance=np.full((3, 3), np.nan),
                    interval_95=np.full((3, 2), np.nan), residual_rms_s=float("nan"),
                    closure_rms_s=closure_rms, variance_factor=float("nan"), observable=False,
                    in_region=False)
        rank = _rank(meas.pairs[keep], n_sens)
        if rank < 3:
            logger.warning("event %d (%.3f-%.3f s): %d independent usable TDOAs, need 3",
                           index, e.t_start, e.t_end, rank)
            return EventFix(**fail)
        used = WindowTdoas(s, meas.pairs[keep], meas.taus[keep], meas.sigmas[keep], c=c)
        with _quiet(_TDOA_LOG):
            best = self._solve(s, used, self._starts(used, grid, dist), c)
        if best is None:
            logger.warning("event %d (%.3f-%.3f s): no solve converged", index, e.t_start, e.t_end)
            return EventFix(**fail)
        pos, cov, info = best
        m = used.m
        resid = (predicted_tdoas(pos, s, used.pairs, c=c) - used.taus) / used.sigmas
        chi2 = float(np.sum(resid**2))
        dof = m * (rank - 3) / rank  # residual dof counted in independent delays
        factor = max(1.0, chi2 / dof) if dof > 0 else 1.0
        scaled = WindowTdoas(s, used.pairs, used.taus, used.sigmas * np.sqrt(factor), c=c)
        if self.huber_k > 0:
            with _quiet(_TDOA_LOG):
                robust = solve_source(s, scaled.pairs, scaled.taus, scaled.sigmas, c=c, initial=pos,
                                      robust=gtsam.noiseModel.mEstimator.Huber.Create(self.huber_k))
            if np.all(np.isfinite(robust[0])):
                pos, cov, info = robust
        else:
            cov = cov * factor
        cov = cov * (m / rank)  # all-pair TDOAs are not independent (module Notes)
        observable = bool(info.observable and np.all(np.isfinite(pos)))
        if not observable:
            logger.warning("event %d (%.3f-%.3f s): position not observable from its TDOAs "
                           "(condition number %.3g, weakest direction %s)", index, e.t_start,
                           e.t_end, info.condition_number, np.round(info.weakest_direction, 3))
        half = Z95 * np.sqrt(np.diag(cov)) if observable else nan3
        interval = np.column_stack([pos - half, pos + half])
        resid_s = predicted_tdoas(pos, s, used.pairs, c=c) - used.taus
        in_region = bool(np.all(pos >= box[0]) and np.all(pos <= box[1]))
        peak, agrees = nan3, None
        if self.surface:
            peak, agrees = self._surface(scaled, grid, dist, box, pos, cov, observable)
        return EventFix(
            event=e, band_hz=band, band_source=source, tdoas=meas, used=keep,
            position=pos if observable else nan3,
            covariance=cov if observable else np.full((3, 3), np.nan), interval_95=interval,
            residual_rms_s=float(np.sqrt(np.mean(resid_s**2))), closure_rms_s=closure_rms,
            variance_factor=factor, observable=observable, in_region=in_region,
            surface_peak=peak, surface_agrees=agrees)

    def _surface(self, tdoas: WindowTdoas, grid, dist: NDArray, box: tuple, pos: NDArray,
                 cov: NDArray, observable: bool) -> tuple[NDArray[np.float64], bool]:
        """Refined eq. (17) peak over the box and whether it agrees with the solve."""
        vol = intensity_volume(tdoas, grid, equation=17, distances=dist)
        start, _ = vol.peak()
        peak, _, step = refine_peak(tdoas, start, grid.step, equation=17, lo=box[0], hi=box[1])
        d = peak - pos
        if np.linalg.norm(d) <= 2.0 * step:
            return peak, True
        if not observable:
            return peak, False
        maha2 = float(d @ np.linalg.solve(cov, d))
        return peak, bool(maha2 <= stats.chi2.ppf(0.99, 3))
