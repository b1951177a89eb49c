"""The passive narrowband chain as one pipeline: acquisition, fixed-lag graphs, TQI, crossings.

Per scan (:meth:`PassivePipeline.step`; :meth:`PassivePipeline.run` steps through whole cubes):

1. **Measure** every live track: predict its state to the scan time from its graph; in the
   track's frequency band read the cell at the predicted beam (amplitude ``A(k)``) and the peak
   near it (bearing, residual) -- :class:`~fusion.passive.measurement.PeakMeasurer`.
2. **Track quality**: one update of the TQI with hysteresis for all live tracks from their
   amplitudes and residuals (:class:`~fusion.passive.quality.TrackQualityIndicator`). ``lost``
   ends the track (after this scan's state); ``uncertain`` widens its process noise for this
   step by ``uncertain_q_factor``.
3. **Graphs**: each track's (bearing, bearing rate) lives on its own GTSAM fixed-lag smoother of
   linear factors (:class:`~fusion.passive.smoothing.fixed_lag.FixedLagBearingTrack`): a motion
   factor to the new state, and the measured bearing if it passes the innovation gate and the
   track is not in a crossing episode.
4. **Crossings**: every ``K`` s the crossing detector (*Target Track Crossing
   Prediction/Detection*, :class:`~fusion.passive.crossing.CrossingDetector`) sees the live
   tracks' bearings. A predicted crossing of two tracks whose bands overlap schedules an episode
   (:class:`~fusion.pipelines.passive.crossing.EpisodeBook`): around the crossing the pair
   coasts and its peaks are collected without labels; when the episode closes they go through
   the association-weighted multi-track graph (EM,
   :class:`~fusion.pipelines.passive.crossing.CrossingResolver`) and each track receives the
   bearings assigned to it on the states of their scans.
5. **Starts**: an operator click (beam, frequency) -- or, with a :class:`~fusion.passive.
   acquisition.starts.LineStarter`, a line found automatically -- is acquired over the last
   ``acquisition_scans`` scans (:class:`~fusion.passive.acquisition.Acquisition`) and starts a
   track whose first state carries the acquisition's estimate as a prior with its uncertainty
   (:class:`~fusion.passive.acquisition.prior.AcquisitionPrior`).

The pipeline chains these parts and holds no algorithm of its own.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import beam_from_bearing, beam_tolerance, beamwidth_cos, beamwidth_deg
from fusion.passive.acquisition import (
    Acquisition,
    AcquisitionPrior,
    AcquisitionResult,
    LineStarter,
)
from fusion.passive.crossing import AlertKind, CrossingAlert, CrossingDetector
from fusion.passive.measurement import BearingMeasurement, PeakMeasurer
from fusion.passive.quality import LABELS, TQIMemory, TrackQuality, TrackQualityIndicator
from fusion.passive.smoothing.fixed_lag import FixedLagBearingTrack
from fusion.pipelines.passive.crossing import (
    CrossingResolution,
    CrossingResolver,
    EpisodeBook,
)
from fusion.pipelines.passive.types import (
    Click,
    PassiveResult,
    PassiveTrack,
    Scan,
    ScanResult,
    SmootherSettings,
    TrackEnd,
    TrackStart,
    TrackUpdate,
    scans_of,
)
from fusion.types import Cube

__all__ = ["PassivePipeline", "SmootherSettings"]

logger = logging.getLogger(__name__)


@dataclass
class _Track:
    """A live track (internal, mutable)."""

    start: TrackStart
    graph: FixedLagBearingTrack
    bins: tuple[int, ...]
    search: int
    wavelength: float
    lobe_beams: float
    labels: list[str]
    recent: deque
    end: TrackEnd | None = None
    last: TrackUpdate | None = None

    @property
    def track_id(self) -> int:
        return self.start.track_id


def _memory_take(memory: TQIMemory, index: NDArray[np.int64]) -> TQIMemory:
    """The TQI memory of the trackers at `index` (in that order)."""
    return TQIMemory(**{k: getattr(memory, k)[index] for k in memory.__dataclass_fields__})


def _memory_join(a: TQIMemory, b: TQIMemory) -> TQIMemory:
    """The TQI memory of the trackers of `a` followed by those of `b`."""
    return TQIMemory(**{k: np.concatenate([getattr(a, k), getattr(b, k)])
                        for k in a.__dataclass_fields__})


class PassivePipeline:
    """Passive narrowband tracking from beam/frequency/time scans, one scan at a time.

    Parameters
    ----------
    acquisition : Acquisition
        Acquisition of a clicked (or proposed) line over the recent scans.
    tqi : TrackQualityIndicator
        Track quality indicator (only its pure :meth:`~TrackQualityIndicator.step` is used).
    crossing : CrossingDetector
        Crossing prediction/detection; the pipeline feeds it every ``crossing.K`` s and resets it
        with the pipeline.
    smoother : SmootherSettings, optional
        Graph and episode settings (default :class:`SmootherSettings()`).
    starter : LineStarter, optional
        Automatic starts; None (default): tracks start from clicks only.
    measurer : PeakMeasurer, optional
        Bearing measurement; default ``PeakMeasurer(beam_sigma=smoother.beam_sigma)``.
    prior : AcquisitionPrior, optional
        Acquisition-to-prior model; default ``AcquisitionPrior()``.
    resolver : CrossingResolver, optional
        Association of crossing episodes; default ``CrossingResolver()``.
    acquisition_scans : int
        Scans the acquisition looks back over (the history a click needs).

    Examples
    --------
    >>> from fusion.simulate.passive import simulate_passive
    >>> sc = simulate_passive(seed=1, n_scans=90)
    >>> pipe = PassivePipeline(acquisition=Acquisition(), tqi=TrackQualityIndicator(),
    ...                        crossing=CrossingDetector(J=12, K=5.0))
    >>> res = pipe.run(sc.cube, [Click(b, f) for b, f, _ in sc.clicks])
    >>> len(res.tracks) == sc.n_targets
    True
    """

    def __init__(
        self,
        *,
        acquisition: Acquisition,
        tqi: TrackQualityIndicator,
        crossing: CrossingDetector,
        smoother: SmootherSettings | None = None,
        starter: LineStarter | None = None,
        measurer: PeakMeasurer | None = None,
        prior: AcquisitionPrior | None = None,
        resolver: CrossingResolver | None = None,
        acquisition_scans: int = 60,
    ) -> None:
        if int(acquisition_scans) != acquisition_scans or acquisition_scans < 3:
            raise ValueError(f"acquisition_scans must be an integer >= 3, got {acquisition_scans!r}")
        self.acquisition = acquisition
        self.tqi = tqi
        self.crossing = crossing
        self.smoother = SmootherSettings() if smoother is None else smoother
        self.starter = starter
        self.measurer = (PeakMeasurer(beam_sigma=self.smoother.beam_sigma) if measurer is None
                         else measurer)
        self.prior = AcquisitionPrior() if prior is None else prior
        self.resolver = CrossingResolver() if resolver is None else resolver
        self.acquisition_scans = int(acquisition_scans)
        self.reset()

    # -- state ----------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget every scan, track, click and alert."""
        self.crossing.reset()
        self._geometry: Scan | None = None
        self._q = 0.0
        hold = max(self.acquisition_scans, self.starter.window_scans if self.starter else 0)
        self._history: deque = deque(maxlen=hold)
        self._pending: list[Click] = []
        self._live: list[_Track] = []
        self._done: list[_Track] = []
        self._memory: TQIMemory | None = None
        self._episodes: EpisodeBook | None = None
        self._alerts: list[CrossingAlert] = []
        self._resolutions: list[CrossingResolution] = []
        self._next_id = 0
        self._n_scans = 0
        self._last_time = -math.inf
        self._next_feed = -math.inf

    def _setup(self, scan: Scan) -> None:
        """Take the array geometry and scan period from the first scan."""
        self._geometry = scan
        sa = math.radians(self.smoother.accel_sigma_deg_per_min2) / 3600.0  # rad/s^2
        self._q = sa * sa * scan.scan_period
        margin = (self.smoother.context_scans + self.smoother.block + 2) * scan.scan_period
        max_half = 0.5 * (self.smoother.lag_s - margin)
        if max_half < 3.0 * scan.scan_period:
            raise ValueError(f"lag_s {self.smoother.lag_s:g} s is too short for crossing "
                             f"episodes: need > {margin + 6.0 * scan.scan_period:g} s")
        self._episodes = EpisodeBook(separation_lobes=self.smoother.separation_lobes,
                                     min_half_s=3.0 * scan.scan_period, max_span_s=2.0 * max_half)
        self._next_feed = scan.time

    def _check_scan(self, scan: Scan) -> None:
        g = self._geometry
        if (scan.power.shape != g.power.shape or not np.allclose(scan.freqs, g.freqs)
                or scan.aperture != g.aperture or scan.sound_speed != g.sound_speed):
            raise ValueError("scan geometry differs from the first scan's (beams, bins, "
                             "frequencies, aperture, sound speed)")
        if not scan.time > self._last_time:
            raise ValueError(f"scan time {scan.time} is not after the previous ({self._last_time})")

    def _check_click(self, click: Click) -> None:
        g = self._geometry
        if click.beam >= g.n_beams:
            raise ValueError(f"click beam {click.beam} is outside the beams 0..{g.n_beams - 1}")
        df = float(np.median(np.diff(g.freqs))) if g.freqs.size > 1 else 1.0
        if not g.freqs[0] - 0.5 * df <= click.freq_hz <= g.freqs[-1] + 0.5 * df:
            raise ValueError(f"click frequency {click.freq_hz:g} Hz is outside the band "
                             f"{g.freqs[0] - 0.5 * df:g}..{g.freqs[-1] + 0.5 * df:g} Hz")

    # -- the chain ------------------------------------------------------------------------------
    def step(self, scan: Scan, *, clicks: Sequence[Click] = ()) -> ScanResult:
        """Process one scan.

        Parameters
        ----------
        scan : Scan
            The next scan (time after the previous one; same geometry as the first).
        clicks : sequence of Click
            Clicks made now; each waits until its time and a full acquisition window.

        Returns
        -------
        ScanResult
        """
        if self._geometry is None:
            self._setup(scan)
        self._check_scan(scan)
        for c in clicks:
            self._check_click(c)
        self._pending.extend(clicks)
        t = scan.time
        self._last_time = t
        self._n_scans += 1
        self._history.append(scan.power)
        updates, ends = self._update_tracks(scan)
        resolutions = self._close_episodes(t, ended={e.track_id for e in ends})
        alerts = self._feed_crossings(t)
        starts = self._start_tracks(scan)
        return ScanResult(time=t, updates=tuple(updates), starts=tuple(starts), ends=tuple(ends),
                          alerts=tuple(alerts), resolutions=tuple(resolutions))

    def _update_tracks(self, scan: Scan) -> tuple[list[TrackUpdate], list[TrackEnd]]:
        """Steps 1-3 for every live track."""
        if not self._live:
            return [], []
        t = scan.time
        meas: list[BearingMeasurement] = []
        preds = []
        for tr in self._live:
            preds.append(tr.graph.predict(t))
            row = scan.power[:, tr.bins[0]] if len(tr.bins) == 1 else (
                scan.power[:, list(tr.bins)].mean(axis=1))
            meas.append(self.measurer.measure(row, float(preds[-1][0][0]),
                                              search_beams=tr.search))
        self._memory = self.tqi.step(self._memory, np.array([m.amplitude for m in meas]),
                                     np.array([m.residual_deg for m in meas]))
        states = self._memory.state
        self._episodes.observe(t, {tr.track_id: m.beam for tr, m in zip(self._live, meas,
                                                                          strict=True)},
                               {tr.track_id: tr.lobe_beams for tr in self._live})
        updates, ends, keep = [], [], []
        for i, (tr, m) in enumerate(zip(self._live, meas, strict=True)):
            state = TrackQuality(int(states[i]))
            lost = state == TrackQuality.LOST
            q_scale = self.smoother.uncertain_q_factor if state == TrackQuality.UNCERTAIN else 1.0
            x_pred, p_pred = preds[i] if q_scale == 1.0 else tr.graph.predict(t, q_scale=q_scale)
            s_innov = m.innovation_std(p_pred[0, 0])
            episode = self._episodes.member_of(tr.track_id)
            use = (not lost and episode is None
                   and m.in_gate(x_pred[0], p_pred[0, 0], self.smoother.gate))
            if episode is not None:
                episode.record(tr.track_id, t, bearing=m.bearing, sigma=m.sigma,
                               predicted=float(x_pred[0]), innovation_std=s_innov,
                               context=list(tr.recent))
            x, p = tr.graph.update(t, bearing=m.bearing if use else None,
                                   sigma=m.sigma if use else None, q_scale=q_scale)
            if use:
                tr.recent.append((t, m.bearing, m.sigma))
            tr.labels.append(state.label)
            tr.last = TrackUpdate(
                track_id=tr.track_id, time=t, bearing_deg=math.degrees(x[0]),
                bearing_rate_deg_per_min=math.degrees(x[1]) * 60.0,
                sigma_bearing_deg=math.degrees(math.sqrt(p[0, 0])),
                sigma_rate_deg_per_min=math.degrees(math.sqrt(p[1, 1])) * 60.0,
                tqi=state.label, amplitude=m.amplitude, residual_deg=m.residual_deg,
                measured=use, in_crossing=episode is not None)
            updates.append(tr.last)
            if lost:
                tr.end = TrackEnd(track_id=tr.track_id, time=t)
                ends.append(tr.end)
                self._done.append(tr)
                logger.info("track %d lost at t=%.1f s", tr.track_id, t)
            else:
                keep.append(i)
        if len(keep) < len(self._live):
            self._live = [self._live[i] for i in keep]
            self._memory = _memory_take(self._memory, np.array(keep, dtype=np.int64))
        return updates, ends

    def _close_episodes(self, t: float, *, ended: set[int]) -> list[CrossingResolution]:
        """Resolve the crossing episodes that close now; hand each track its bearings."""
        out = []
        by_id = {tr.track_id: tr for tr in self._live}
        for ep in self._episodes.close_due(t, ended=ended):
            res, assigned = self.resolver.resolve(ep, scan_period=self._geometry.scan_period,
                                                  q=self._q)
            for tid, (times, bearings, sigmas) in assigned.items():
                tr = by_id.get(tid)
                if tr is not None and times.size:
                    tr.graph.add_bearings(times, bearings, sigmas)
                    tr.recent.extend(zip(times.tolist(), bearings.tolist(), sigmas.tolist(),
                                         strict=True))
            out.append(res)
            self._resolutions.append(res)
        return out

    def _feed_crossings(self, t: float) -> list[CrossingAlert]:
        """Step 4: the crossing detector every K s; predicted crossings schedule episodes."""
        if t < self._next_feed - 1e-9 * self.crossing.K:
            return []
        while self._next_feed <= t + 1e-9 * self.crossing.K:
            self._next_feed += self.crossing.K
        ids = np.array([tr.track_id for tr in self._live], dtype=np.int64)
        bearings = np.array([math.degrees(tr.graph.estimate[0][0]) for tr in self._live])
        alerts = self.crossing.step(t, ids, bearings)
        by_id = {tr.track_id: tr for tr in self._live}
        for al in alerts:
            a, b = by_id.get(al.track_a), by_id.get(al.track_b)
            if al.kind != AlertKind.PREDICTED or a is None or b is None:
                continue
            if min(abs(i - j) for i in a.bins for j in b.bins) > 1:
                continue  # lines in different bands do not merge
            xa, xb = a.graph.estimate[0], b.graph.estimate[0]
            brg = float(np.clip(xa[0] + xa[1] * (al.t_cross - t), 0.0, math.pi))
            bw = math.radians(float(beamwidth_deg(math.degrees(brg), wavelength=a.wavelength,
                                                  aperture=self._geometry.aperture)))
            self._episodes.schedule((a.track_id, b.track_id), now=t, t_cross=al.t_cross,
                                    rate_diff=float(xa[1] - xb[1]), beamwidth=bw)
        self._alerts.extend(alerts)
        return alerts

    def _start_tracks(self, scan: Scan) -> list[TrackStart]:
        """Step 5: due clicks, then automatic starts."""
        if len(self._history) < self.acquisition_scans:
            return []
        starts = []
        due = [c for c in self._pending if c.time is None or c.time <= scan.time + 1e-9]
        if due:
            self._pending = [c for c in self._pending if c not in due]
            cube = self._history_cube()
            for c in due:
                res = self.acquisition.acquire(cube, beam=c.beam, freq_hz=c.freq_hz)
                starts.append(self._start(scan, res, beam=c.beam, freq_hz=c.freq_hz,
                                          source="click"))
        if self.starter is not None and self._n_scans % self.starter.every_scans == 0:
            starts += self._auto_starts(scan)
        return starts

    def _history_cube(self) -> Cube:
        g = self._geometry
        power = np.stack(list(self._history)[-self.acquisition_scans:])
        return Cube(power=power, freqs=g.freqs, scan_period=g.scan_period, aperture=g.aperture,
                    sound_speed=g.sound_speed)

    def _held(self) -> list[tuple[float, int]]:
        n_beams = self._geometry.n_beams
        out = []
        for tr in self._live:
            beam = float(beam_from_bearing(float(np.clip(tr.graph.estimate[0][0], 0, math.pi)),
                                           n_beams))
            out += [(beam, int(f)) for f in tr.bins]
        return out

    def _auto_starts(self, scan: Scan) -> list[TrackStart]:
        """Candidates of the line starter that the acquisition confirms."""
        g = self._geometry
        # the main lobe per frequency bin in beams (beams are uniform in cosine over [-1, 1])
        lobe = np.array([beamwidth_cos(g.sound_speed / f, g.aperture) for f in g.freqs]
                        ) * (g.n_beams - 1) / 2.0
        history = np.stack(list(self._history))
        cands = self.starter.candidates(history, held=self._held(), lobe_beams=lobe)
        if not cands:
            return []
        cube = self._history_cube()
        starts = []
        for c in cands:
            res = self.acquisition.acquire(cube, beam=c.beam, freq_hz=float(g.freqs[c.bin]))
            if res.default_used:
                continue
            beam = float(beam_from_bearing(math.radians(res.bearing_deg), g.n_beams))
            if self.starter.excluded(beam, c.bin, held=self._held(), lobe_beams=lobe):
                continue  # the acquisition walked onto a held line
            starts.append(self._start(scan, res, beam=c.beam, freq_hz=float(g.freqs[c.bin]),
                                      source="auto"))
        return starts

    def _start(self, scan: Scan, res: AcquisitionResult, *, beam: int, freq_hz: float,
               source: str) -> TrackStart:
        """A new track whose first state, at this scan, carries the acquisition prior."""
        g = self._geometry
        bins = tuple(int(b) for b in res.ibw_bins)
        f0 = float(g.freqs[bins[len(bins) // 2]])
        wavelength = g.sound_speed / f0
        prior = self.prior.prior(res, click_beam=beam, n_beams=g.n_beams, wavelength=wavelength,
                                 aperture=g.aperture, scan_period=g.scan_period)
        graph = FixedLagBearingTrack(prior=prior, t0=scan.time, lag_s=self.smoother.lag_s,
                                     q=self._q, block_s=self.smoother.block * g.scan_period)
        start = TrackStart(
            track_id=self._next_id, time=scan.time, source=source, beam=int(beam),
            freq_hz=f0, bearing_deg=math.degrees(prior.bearing),
            bearing_rate_deg_per_min=math.degrees(prior.rate) * 60.0,
            sigma_bearing_deg=math.degrees(prior.sigma_bearing),
            sigma_rate_deg_per_min=math.degrees(prior.sigma_rate) * 60.0,
            snr_db=float(res.snr_db), default_used=bool(res.default_used))
        self._next_id += 1
        self._live.append(_Track(
            start=start, graph=graph, bins=bins,
            search=beam_tolerance(wavelength, g.aperture, g.n_beams), wavelength=wavelength,
            lobe_beams=beamwidth_cos(wavelength, g.aperture) * (g.n_beams - 1) / 2.0,
            labels=[""], recent=deque(maxlen=self.smoother.context_scans)))
        fresh = self.tqi.initial_memory(1)
        self._memory = fresh if self._memory is None else _memory_join(self._memory, fresh)
        logger.info("track %d started (%s) at t=%.1f s: %.2f deg, %.2f deg/min, %.1f Hz",
                    start.track_id, source, scan.time, start.bearing_deg,
                    start.bearing_rate_deg_per_min, f0)
        return start

    # -- output ---------------------------------------------------------------------------------
    def result(self) -> PassiveResult:
        """Smoothed tracks (fixed-lag; the last lag by all data so far), alerts, resolutions."""
        if self._pending:
            logger.warning("%d click(s) not served yet (their time or a full acquisition window "
                           "of %d scans not reached)", len(self._pending), self.acquisition_scans)
        tracks = []
        for tr in sorted(self._done + self._live, key=lambda x: x.track_id):
            st = tr.graph.states()
            tracks.append(PassiveTrack(
                track_id=tr.track_id, time=st.time, bearing_deg=np.degrees(st.state[:, 0]),
                bearing_rate_deg_per_min=np.degrees(st.state[:, 1]) * 60.0,
                sigma_bearing_deg=np.degrees(st.sigma[:, 0]),
                sigma_rate_deg_per_min=np.degrees(st.sigma[:, 1]) * 60.0,
                tqi=np.array(tr.labels, dtype=LABELS.dtype), freq_hz=tr.start.freq_hz,
                start=tr.start, end=tr.end))
        return PassiveResult(tracks=tuple(tracks), alerts=tuple(self._alerts),
                             resolutions=tuple(self._resolutions), n_scans=self._n_scans)

    def run(self, cubes: Cube | Sequence[Cube], clicks: Sequence[Click] = (), *,
            on_scan: Callable[[int], None] | None = None) -> PassiveResult:
        """Process whole cubes (consecutive cubes of one recording) from a fresh start.

        Parameters
        ----------
        cubes : Cube or sequence of Cube
            Normalised beam/frequency/time power (:func:`~fusion.pipelines.passive.types.
            scans_of`: scan ``k`` at ``k * scan_period``).
        clicks : sequence of Click
            Operator clicks, given at the first scan; each waits for its time.
        on_scan : callable, keyword-only
            ``on_scan(1)`` after each scan (a progress bar's ``update``); None: not called.

        Returns
        -------
        PassiveResult
        """
        self.reset()
        for i, scan in enumerate(scans_of(cubes)):
            self.step(scan, clicks=clicks if i == 0 else ())
            if on_scan is not None:
                on_scan(1)
        return self.result()
