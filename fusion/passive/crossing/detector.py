"""The streaming crossing detector: window ladder, confirmation and alert de-duplication.

:class:`CrossingDetector` is the streaming component of *Target Track Crossing
Prediction/Detection* (blocks 104A-104E, output 106): each :meth:`CrossingDetector.step` updates
the tracks' sliding window fits, evaluates equation (2) and inequalities (3)/(4) for the pairs
within reach and raises the alerts. Importable from :mod:`fusion.passive.crossing` too, which
holds the batch entry point :func:`~fusion.passive.crossing.detect_crossings`.
"""

from __future__ import annotations

import logging

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.passive.crossing.calibration import ExtrapolationScale, holdout_errors
from fusion.passive.crossing.curvature import CurvatureStats, curvature_stats
from fusion.passive.crossing.curve import (
    CurveStats,
    curve_fits,
)
from fusion.passive.crossing.events import _Events, _Hits, raise_alerts
from fusion.passive.crossing.judge import ladder_hits
from fusion.passive.crossing.manoeuvre import ManoeuvreIntensity, half_window_slopes
from fusion.passive.crossing.types import CrossingAlert
from fusion.passive.line_fit import LineStats, SlidingLineFit

__all__ = ["CrossingDetector"]

#: Most samples in the longest window of the ladder (``J * 2**(n_windows - 1)``): each track
#: slot holds that many samples per window (16 slots to begin with: 272 MB at this limit;
#: ``--period-s 1.2e-7`` made windows of 33 million samples, 4-36 GiB).
MAX_WINDOW_SAMPLES = 1_000_000

logger = logging.getLogger(__name__)


class CrossingDetector:
    """Streaming crossing prediction and detection for many bearing tracks.

    Parameters
    ----------
    J : int, optional
        Samples in each track's least-squares window (> 2; the method text suggests at
        least 10).
    K : float
        Sample period, s: `step` is called every K seconds.
    horizon_s : float, optional
        Prediction horizon: inequality (3) becomes ``t_i < t_c <= t_i + horizon_s`` (default
        ``J K``, the method's form).
    min_rate_diff_deg_per_s : float, optional
        In-range check: pairs whose bearing rates differ by this much or less are treated as
        parallel and never alert (default 1e-9 deg/s: only numerically equal rates).
    merge_window_s : float, optional
        De-duplication window, s (default ``J K``; see Notes).
    max_gap_s : float, optional
        A track silent for longer than this restarts its windows (default ``3 K``).
    n_windows : int, optional
        Length of the window ladder: windows of ``J, 2 J, ..., 2^(n_windows - 1) J`` samples
        (default 1, the method's single window).
    level : float or None, optional
        Confidence level of the crossing-time intervals (default 0.95); None computes no
        interval and raises every alert the inequalities give (the method text alone; the
        ladder is then not used).
    max_interval_s : float, optional
        An alert needs an interval no wider than this, s (default `horizon_s`).
    lead_windows : float, optional
        Predictions from a window reach at most this many window spans ahead (default 1, the
        method's ``t_c <= t_i + J K`` for each window; never beyond `horizon_s`).
    confirm : int, optional
        An alert needs its pair to satisfy an inequality (resolved) at this many samples in a
        row (default 1, the method's rule).
    curve_alpha : float or None, optional
        Level of the F-test that adds a quadratic term to a track's window fit
        (:func:`~fusion.passive.crossing.curve.curve_fits`); pairs with a curved track cross at
        the root of the difference polynomial, with the interval from the polynomials'
        covariance. None (default): straight lines only, the method's regression.
    curve_windows : int, optional
        Curves are fitted on this many of the shortest windows of the ladder (default 1: the
        shortest only; a constant-velocity curve over a long window of a manoeuvring vessel
        mimics a turn and extrapolates it, benchmarks/RESULTS.md).
    revise : bool, optional
        A crossing event whose interval, at a later sample, no longer overlaps the interval of
        the ``predicted`` alert it raised raises a new ``predicted`` alert (a revised
        prediction; default False: at most one per event, the rule below).
    confirm_overlap : bool, optional
        A sample confirms a pair's hit of the sample before only if their two crossing-time
        intervals overlap (default False: any hit confirms): two honest intervals of one
        crossing from windows sharing all but one sample overlap, and a prediction that jumps
        from sample to sample is not yet one.
    calibrate : bool, optional
        Grow the variance of predictions (crossings ahead of the sample) by the factor the data
        ask for (default False): each track's J-sample line of ``lead_windows J`` samples ago
        is checked on the samples since, and the factor is the smallest that makes those
        held-out errors fall within their intervals as often as the level says (pooled over
        tracks and the recent past, :class:`~fusion.passive.crossing.calibration.ExtrapolationScale`,
        :attr:`extrapolation_scale`). Needs a ladder window of ``J + lead_windows J`` samples.
    confirm_lead_windows : float, optional
        Samples that confirm a prediction may predict up to this many window spans ahead
        (default `lead_windows`); alerts are still raised only within `lead_windows`, so a pair
        watched from further out alerts as soon as its crossing comes within reach.
    curvature : bool, optional
        Predictions from lines also carry the variance of the curvature each window's line
        leaves out, at the predicted crossing (default False;
        :mod:`fusion.passive.crossing.curvature`).
    manoeuvre_scale, manoeuvre_memory_s : float, optional
        Predictions also carry the variance of a wandering bearing rate, each track's
        intensity estimated from its own rate changes (forgotten over `manoeuvre_memory_s`,
        default 10 shortest windows) times `manoeuvre_scale` (default 0: off;
        :mod:`fusion.passive.crossing.manoeuvre`).
    allowance_gate_level : int or None, optional
        From this ladder level on (0: the shortest; default), intervals widened by the
        manoeuvre term and `far_side` also decide which pairs are resolved; below it (None:
        everywhere) they only widen the alerts' intervals.
    far_side : bool, optional
        Lead-dependent variances (curvature, manoeuvre) taken again at a prediction's upper
        bound, which is recomputed (default False; :func:`~.pairs.pair_intervals`).
    curve_manoeuvre : bool, optional
        Pairs on curves carry the manoeuvre allowance too, widening only (default False).
    window_fill : float, optional
        A window of the ladder beyond the shortest takes part once it holds more than this
        fraction of its samples (default 1: only full windows; 0.5: as soon as it holds more
        than the window below it, e.g. a track younger than the window or restarted by a gap).
        The shortest window is always used full.
    split_repeats : bool, optional
        A crossing whose bearing difference changes sign the other way from the pair's
        current event is the pair's next crossing, however close in time (default True;
        False merges by time and interval overlap only).
    ladder_alpha : float or None, optional
        Level of the variance-ratio test that admits a track to a longer window of the
        ladder: its residual variance there must not exceed the shortest window's by more than
        the upper `ladder_alpha` quantile of F (a track that turned or sped up within the
        longer window is judged on the shorter ones only). None (default): every track.

    Notes
    -----
    Per sample (*Target Track Crossing Prediction/Detection*, FIG. 2): each reported track's
    window lines are updated (104A, :class:`SlidingLineFit`); equation (2), the in-range check
    (104C) and inequalities (3) and (4) (104D, 104E) are evaluated for the pairs of tracks with
    full windows, with the current sample time ``t_i`` in place of ``i K``.

    Intervals and the window ladder (not in the method text): the crossing time gets Fieller's
    interval from the two fits' covariance (:func:`~fusion.passive.crossing.pairs.pair_intervals`;
    the noise is each window's residual variance, so nothing about the noise needs to be
    known). A pair is *resolved* on a window when its interval is bounded (the bearing-rate
    difference exceeds its uncertainty) and no wider than `max_interval_s`. Each pair is judged
    on the shortest window that resolves it; pairs resolved on none raise no alert. Inequality
    (4) then reads ``t_i - W <= t_c <= t_i`` with ``W`` the span of the window used.

    De-duplication (the method text raises an alert whenever an inequality holds, which would
    repeat it at up to J consecutive samples): each pair keeps its current crossing *event*,
    identified by the latest ``t_c`` and interval seen for it. A satisfied inequality whose
    ``t_c`` lies within `merge_window_s` of the event's, or whose interval overlaps the
    event's, belongs to that event (and updates it) -- unless the two cross in opposite
    directions (the sign of the bearing difference's rate at the crossing): successive
    crossings of one pair alternate direction, so a repeated pass opens a new event however
    soon it comes; otherwise it opens a new event. Per event
    at most one ``predicted`` alert (only before any ``detected`` alert of the event) and at
    most one ``detected`` alert are issued.

    Examples
    --------
    >>> det = CrossingDetector(J=5, K=1.0)
    >>> alerts = []
    >>> for i in range(12):
    ...     alerts += det.step(float(i), [1, 2], [0.5 * i, 8.0 - 0.5 * i])
    >>> [(a.kind.value, a.t_cross) for a in alerts]
    [('predicted', 8.0), ('detected', 8.0)]
    """

    def __init__(
        self,
        *,
        J: int = 10,
        K: float,
        horizon_s: float | None = None,
        min_rate_diff_deg_per_s: float = 1e-9,
        merge_window_s: float | None = None,
        max_gap_s: float | None = None,
        n_windows: int = 1,
        level: float | None = 0.95,
        max_interval_s: float | None = None,
        lead_windows: float = 1.0,
        confirm: int = 1,
        curve_alpha: float | None = None,
        split_repeats: bool = True,
        ladder_alpha: float | None = None,
        curve_windows: int = 1,
        revise: bool = False,
        confirm_overlap: bool = False,
        calibrate: bool = False,
        curvature: bool = False,
        manoeuvre_scale: float = 0.0,
        far_side: bool = False,
        manoeuvre_memory_s: float | None = None,
        allowance_gate_level: int | None = 0,
        confirm_lead_windows: float | None = None,
        curve_manoeuvre: bool = False,
        window_fill: float = 1.0,
    ) -> None:
        if int(J) != J or J < 3:
            raise ValueError(f"J (samples per window) must be an integer > 2, got {J!r}")
        if not (np.isfinite(K) and K > 0):
            raise ValueError(f"K (sample period) must be > 0 s, got {K!r}")
        for name, v in (("horizon_s", horizon_s), ("merge_window_s", merge_window_s),
                        ("max_gap_s", max_gap_s), ("max_interval_s", max_interval_s)):
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be > 0, got {v!r}")
        if not (np.isfinite(min_rate_diff_deg_per_s) and min_rate_diff_deg_per_s >= 0):
            raise ValueError(f"min_rate_diff_deg_per_s must be >= 0, got {min_rate_diff_deg_per_s!r}")
        if int(n_windows) != n_windows or n_windows < 1:
            raise ValueError(f"n_windows must be a positive integer, got {n_windows!r}")
        if not (np.isfinite(lead_windows) and lead_windows > 0):
            raise ValueError(f"lead_windows must be > 0, got {lead_windows!r}")
        if level is not None and not 0.0 < level < 1.0:
            raise ValueError(f"level must lie in (0, 1), got {level!r}")
        self.J = int(J)
        self.K = float(K)
        self.horizon_s = self.J * self.K if horizon_s is None else float(horizon_s)
        self.min_rate_diff_rad_per_s = float(np.radians(min_rate_diff_deg_per_s))
        self.merge_window_s = self.J * self.K if merge_window_s is None else float(merge_window_s)
        self.max_gap_s = 3.0 * self.K if max_gap_s is None else float(max_gap_s)
        self.level = None if level is None else float(level)
        self.n_windows = int(n_windows) if self.level is not None else 1
        longest = self.J * 2 ** (self.n_windows - 1)
        if longest > MAX_WINDOW_SAMPLES:
            raise ValueError(
                f"the longest window, J = {self.J} samples of K = {self.K:g} s doubled "
                f"{self.n_windows - 1} times, has {longest:,} samples, more than "
                f"{MAX_WINDOW_SAMPLES:,}: use a longer --period-s, a shorter --window-s or "
                "fewer --window-samples or --windows")
        self.max_interval_s = self.horizon_s if max_interval_s is None else float(max_interval_s)
        self.lead_windows = float(lead_windows)
        self.confirm_lead = self.lead_windows if confirm_lead_windows is None else max(
            self.lead_windows, float(confirm_lead_windows))
        if int(confirm) != confirm or confirm < 1:
            raise ValueError(f"confirm must be a positive integer, got {confirm!r}")
        self.confirm = int(confirm)
        if curve_alpha is not None and not 0.0 < curve_alpha < 1.0:
            raise ValueError(f"curve_alpha must lie in (0, 1), got {curve_alpha!r}")
        self.curve_alpha = None if curve_alpha is None else float(curve_alpha)
        self.split_repeats = bool(split_repeats)
        if ladder_alpha is not None and not 0.0 < ladder_alpha < 1.0:
            raise ValueError(f"ladder_alpha must lie in (0, 1), got {ladder_alpha!r}")
        self.ladder_alpha = None if ladder_alpha is None else float(ladder_alpha)
        if int(curve_windows) != curve_windows or curve_windows < 1:
            raise ValueError(f"curve_windows must be a positive integer, got {curve_windows!r}")
        self.curve_windows = int(curve_windows)
        self.revise = bool(revise)
        self.confirm_overlap = bool(confirm_overlap)
        self.calibrate = bool(calibrate)
        self.curvature = bool(curvature) and self.level is not None
        if not (np.isfinite(manoeuvre_scale) and manoeuvre_scale >= 0):
            raise ValueError(f"manoeuvre_scale must be >= 0, got {manoeuvre_scale!r}")
        self.manoeuvre_scale = float(manoeuvre_scale) if self.level is not None else 0.0
        self.far_side = bool(far_side)
        self.curve_manoeuvre = bool(curve_manoeuvre)
        if not (np.isfinite(window_fill) and 0.0 < window_fill <= 1.0):
            raise ValueError(f"window_fill must lie in (0, 1], got {window_fill!r}")
        self.window_fill = float(window_fill)
        g = allowance_gate_level
        if g is not None and (int(g) != g or g < 0):
            raise ValueError(f"allowance_gate_level must be an integer >= 0 or None, got {g!r}")
        self.allowance_gate_level = None if g is None else int(g)
        m = self.manoeuvre_memory_s = 10.0 * self.J * self.K if manoeuvre_memory_s is None \
            else float(manoeuvre_memory_s)
        if not (np.isfinite(m) and m > 0):
            raise ValueError(f"manoeuvre_memory_s must be > 0, got {manoeuvre_memory_s!r}")
        self.reset()

    @property
    def windows(self) -> tuple[int, ...]:
        """Samples in each window of the ladder, shortest first."""
        return tuple(self.J * 2**k for k in range(self.n_windows))

    def reset(self) -> None:
        """Forget every track and event."""
        self._fits = tuple(SlidingLineFit(window=w, max_gap_s=self.max_gap_s)
                           for w in self.windows)
        self._events = _Events()
        self._last_time = -np.inf
        self._streak_key = np.zeros(0, np.int64)  # pairs hit at the previous sample ...
        self._streak_count = np.zeros(0, np.int64)  # ... and for how many samples in a row
        self._streak_low = np.zeros(0)  # ... with the interval of that sample
        self._streak_high = np.zeros(0)
        self._scale = ExtrapolationScale(self.level) if self._holdout() is not None else None
        self.extrapolation_scale = 1.0  # the factor on predictions' variances (calibrate)
        self._manoeuvre = ManoeuvreIntensity(self.manoeuvre_scale, self.manoeuvre_memory_s,
                                             self.K) if self.manoeuvre_scale > 0 else None
        self.manoeuvre_q = None  # the tracks' rate-wander intensities of this step, rad^2/s^3

    @property
    def window_need(self) -> tuple[int, ...]:
        """Samples each window of the ladder must hold to take part (`window_fill`)."""
        return tuple(w if (k == 0 or self.window_fill >= 1.0)
                     else max(self.J, int(np.floor(self.window_fill * w)) + 1)
                     for k, w in enumerate(self.windows))

    @property
    def fit(self) -> SlidingLineFit:
        """The per-track fits of the J-sample window (read them, do not update them)."""
        return self._fits[0]

    @property
    def fits(self) -> tuple[SlidingLineFit, ...]:
        """The per-track fits of every window of the ladder, shortest first."""
        return self._fits

    def step(
        self, time: float, track_ids: ArrayLike, bearings_deg: ArrayLike
    ) -> list[CrossingAlert]:
        """Process the bearings of one sample and return the new alerts.

        Parameters
        ----------
        time : float
            Sample time, s; strictly increasing from call to call (every K s).
        track_ids : array_like of int, shape (n,)
            Distinct ids of the tracks reported at this sample (negative ids, detections of
            unknown origin, are ignored).
        bearings_deg : array_like, shape (n,)
            Their bearings, deg (any wrap).

        Returns
        -------
        list of CrossingAlert
            Alerts raised at this sample, sorted by track pair.
        """
        t = float(time)
        if not np.isfinite(t):
            raise ValueError(f"time must be finite, got {time!r}")
        if t <= self._last_time:
            raise ValueError(f"time {t} is not after the previous step ({self._last_time})")
        ids = np.asarray(track_ids)
        bdeg = np.asarray(bearings_deg, dtype=float)
        if ids.ndim != 1 or ids.shape != bdeg.shape:
            raise ValueError("track_ids and bearings_deg must be 1-D arrays of one length")
        if ids.size and not np.issubdtype(ids.dtype, np.integer):
            if not np.all(np.isfinite(ids.astype(float))) or np.any(ids != np.round(ids)):
                raise ValueError("track_ids must be integers")
            ids = ids.astype(np.int64)
        if not np.all(np.isfinite(bdeg)):
            raise ValueError("bearings_deg must be finite")
        keep = ids >= 0
        ids, bdeg = ids[keep], bdeg[keep]
        if np.unique(ids).size != ids.size:
            raise ValueError(f"duplicate track ids at time {t}")
        self._last_time = t
        order = np.argsort(ids, kind="stable")
        ids, bdeg = ids[order], bdeg[order]
        for fit in self._fits:
            fit.update(ids, t, np.radians(bdeg))
        self._prune(t)
        self._calibrate(ids, t)
        self._estimate_manoeuvre(ids, t)
        hits = self._confirmed(self._hits(t, ids))
        if self.confirm_lead > self.lead_windows:  # watched further out, raised within reach
            with np.errstate(invalid="ignore"):
                keep = ~hits.predicted | (hits.t_cross - t <= (1.0 + 1e-12) * np.minimum(
                    self.horizon_s, self.lead_windows * hits.window_s))
            hits = _Hits(*(getattr(hits, f)[keep] for f in hits._FIELDS))
        return self._alerts(t, hits)

    def _confirmed(self, h: _Hits) -> _Hits:
        """Hits of pairs that satisfied an inequality at `confirm` samples in a row."""
        fit = self._fits[0]
        key = fit.slots(h.a) * (1 << 32) + fit.slots(h.b)
        pos = np.searchsorted(self._streak_key, key)
        pos_ok = np.minimum(pos, max(self._streak_key.size - 1, 0))
        seen = (pos < self._streak_key.size) & (self._streak_key[pos_ok] == key) \
            if self._streak_key.size else np.zeros(key.size, bool)
        if self.confirm_overlap and self._streak_key.size:  # the same crossing, consistently
            with np.errstate(invalid="ignore"):
                seen &= ((h.conf_low <= self._streak_high[pos_ok])
                         & (h.conf_high >= self._streak_low[pos_ok]) | np.isnan(h.conf_low))
        count = np.where(seen, self._streak_count[pos_ok] + 1 if self._streak_key.size else 1, 1)
        order = np.argsort(key, kind="stable")
        self._streak_key, self._streak_count = key[order], count[order]
        self._streak_low, self._streak_high = h.conf_low[order], h.conf_high[order]
        if self.confirm <= 1:
            return h
        keep = count >= self.confirm
        return _Hits(*(getattr(h, f)[keep] for f in h._FIELDS))

    # -- pairs -------------------------------------------------------------------------------
    def _models(self, fit: SlidingLineFit, ids: NDArray[np.int64], t: float, *, curves: bool
                ) -> tuple[LineStats, CurveStats | None, CurvatureStats | None]:
        """The windows' lines and, on the shortest windows (`curves`), their F-tested curves and
        (`curvature`) quadratic terms."""
        st = fit.stats(ids, t)
        quad = self.curvature
        curves = curves and self.curve_alpha is not None and self.level is not None
        if not curves and not quad:
            return st, None, None
        tau, val, ok = fit.windows(ids, t)
        cs = curve_fits(tau, val, ok, st, alpha=self.curve_alpha) if curves else None
        return st, cs, curvature_stats(tau, val, ok, st) if quad else None

    def _holdout(self) -> tuple[int, int] | None:
        """(ladder level, samples ahead) of the held-out check of `calibrate`, or None."""
        if not self.calibrate or self.level is None:
            return None
        ahead = max(1, int(round(self.lead_windows * self.J)))
        for level, w in enumerate(self.windows):
            if w >= self.J + ahead:
                return level, ahead
        return None

    def _calibrate(self, ids: NDArray[np.int64], t: float) -> None:
        """Add this sample's held-out errors and update the extrapolation factor."""
        hold = self._holdout()
        if self._scale is None or hold is None or ids.size == 0:
            return
        tau, val, ok = self._fits[hold[0]].windows(ids, t)
        self.extrapolation_scale = self._scale.add(
            *holdout_errors(tau, val, ok, J=self.J, K=self.K, ahead=hold[1]))

    def _estimate_manoeuvre(self, ids: NDArray[np.int64], t: float) -> None:
        """Add this sample's half-window rate changes to the rate-wander intensity."""
        if self._manoeuvre is None or ids.size == 0:
            return
        level = 1 if len(self._fits) > 1 else 0
        half = self.windows[level] // 2
        tau, val, ok = self._fits[level].windows(ids, t)
        self.manoeuvre_q = self._manoeuvre.add(ids, *half_window_slopes(
            tau, val, ok, (half - 0.5) * self.K, half), half * self.K)

    def _hits(self, t: float, ids: NDArray[np.int64]) -> _Hits:
        """Pairs satisfying an inequality on the shortest window that resolves them
        (:func:`~fusion.passive.crossing.judge.ladder_hits`)."""
        return ladder_hits(self, t, ids)

    # -- events ------------------------------------------------------------------------------
    def _prune(self, t: float) -> None:
        """Drop events no later ``t_c`` can join (older than the longest window + merge window)."""
        limit = t - self.windows[-1] * self.K - self.merge_window_s
        ev = self._events
        if ev.key.size:
            latest = np.fmax(ev.t_cross, ev.high)
            if latest.min() < limit:
                ev.keep(latest >= limit)

    def _alerts(self, t: float, h: _Hits) -> list[CrossingAlert]:
        """Apply the de-duplication rule to the pairs that satisfied an inequality."""
        if h.a.size == 0:
            return []
        fit = self._fits[0]
        out = raise_alerts(self._events, fit.slots(h.a) * (1 << 32) + fit.slots(h.b), h, t,
                           merge_window_s=self.merge_window_s,
                           split_repeats=self.split_repeats, revise=self.revise)
        if out:
            logger.debug("t=%.3f: %d crossing alert(s)", t, len(out))
        return out

