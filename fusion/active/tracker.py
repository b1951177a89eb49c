"""Multistatic active tracker: Kalman prediction, fuzzy association, track score, M-of-N.

Implements the tracker of "Target tracking using fuzzy logic association" (Section 3, "Tracker
overview"; Section 2.5, "Tracker"; Section 7, "Results") by composing its stages, one module
each:

1. *Kalman stage* (:mod:`fusion.active.kalman`): constant-velocity prediction of every track,
   innovation statistics of every (track, detection) pair, the chi-square gate; each detection
   with its own position covariance (:mod:`fusion.active.bistatic`), from range-sum and bearing
   accuracies learnt per receiver (:mod:`fusion.active.noise`).
2. *Fuzzy stage* (:mod:`fusion.active.association`): the rule base ranks the gated pairs from the
   likelihood ratio and the clues present; the rank threshold is read off the rule base for each
   pair's clue set; conflicts are settled by an assignment maximising the summed rank, confirmed
   tracks first.
3. *Track management* (:mod:`fusion.active.lifecycle`, :mod:`fusion.active.track_score`): a
   detection that no track takes and that lies in no track's gate starts a tentative track;
   M-of-N confirmation together with a track score (log-likelihood ratio of target against
   clutter, with per-receiver detection probabilities and clutter intensities estimated from the
   data), deletion after consecutive misses, the stationary hold (motion test of the track's own
   detections). The clutter map (:mod:`fusion.active.clutter`) learns where returns recur; it
   feeds the rank's hotspot rule and the track score's clutter intensity.

``mode="kalman"``, the paper's comparison: nearest neighbour on the likelihood alone (highest
``L`` in the gate wins; same assignment and M-of-N), no clutter map, no track score.

Choices where the paper is silent: ``docs/tracking.md`` and the stage modules.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from fusion.active.association import EDGE_LIKELIHOOD, PairRanker, assign_by_priority
from fusion.active.births import birth_blockers, start_tracks, successor_flags
from fusion.active.bistatic import MeasurementModel
from fusion.active.clutter import ClutterIntensity, ClutterMapBase, DensityClutterMap
from fusion.active.kalman import cv_model, gate_threshold, kf_predict, kf_update, pair_statistics
from fusion.active.lifecycle import (
    Lifecycle,
    coast_misses,
    hold_tests,
    hotspot_drop,
    next_lifecycle,
    stationary_hold,
)
from fusion.active.motion import STILL_WANDER_S
from fusion.active.noise import NoiseEstimator
from fusion.active.ping_scan import PingScan, ping_result, score_gate
from fusion.active.platform import sensor_positions
from fusion.active.track_score import TrackScorer
from fusion.active.types import (
    Columns,
    Ping,
    PingResult,
    TrackingResult,
    check_tracker_options,
    pings_from_columns,
    receiver_groups,
)

__all__ = ["Ping", "PingResult", "Tracker", "TrackingResult", "pings_from_table"]

logger = logging.getLogger(__name__)


#: Former name of :func:`fusion.active.types.pings_from_columns` (any named columns will do).
pings_from_table = pings_from_columns


class Tracker:
    """Fuzzy-association (or Kalman nearest-neighbour) multistatic tracker.

    Parameters
    ----------
    mode : {"fuzzy", "kalman"}, optional
        ``fuzzy`` (default): the paper's fuzzy rank; ``kalman``: likelihood alone, no clutter map.
    system : FuzzySystem, optional
        Rule base (default :func:`fusion.active.rulebase.default_association_system`).
    clues : iterable of str, optional
        Which of :data:`fusion.active.association.CLUE_NAMES` may be used (default all).
    position_sigma_m : float, optional
        Standard deviation of each position coordinate of a detection without source/receiver
        positions (or with ``position_errors="isotropic"``), m (default 100).
    accel_psd : float, optional
        White-acceleration spectral density, m^2/s^3 (default 0.04).
    speed_sigma_mps : float, optional
        Standard deviation of each velocity component of a new track, m/s (default 3, about the
        speed of a submarine on patrol).
    gate_probability : float, optional
        Chi-square gate probability (default 0.99).
    min_rank : float, optional
        Lowest rank (fuzzy mode) that may be associated, the same for every pair. Default None:
        derived from the rule base for the clues each pair actually has
        (:func:`fusion.active.association.derived_min_rank` at ``edge_likelihood``).
    edge_likelihood : float, optional
        Likelihood ratio at the edge of the acceptance region used by the derived threshold
        (default :data:`fusion.active.association.EDGE_LIKELIHOOD` = 0.25).
    confirmed_edge_likelihood : float, optional
        The same for confirmed tracks (default 0.1; None: as `edge_likelihood`).
    confirm_hits, confirm_window : int, optional
        M-of-N confirmation (default 3 of 4).
    max_misses : int, optional
        Consecutive misses that delete a confirmed track (default 5).
    init_exclusion_m : float, optional
        Detections closer than this to a hotspot region start no track (fuzzy mode; default 0).
    hotspot_drop : bool, optional
        Fuzzy mode: delete a tentative track within ``init_exclusion_m`` of a hotspot region
        unless its own detections move significantly (default False).
    motion_probability : float, optional
        Confidence of the motion test (stationary hold and hotspot drop), default 0.999, in
        (0, 1); see :func:`fusion.active.motion.motion_statistic`. Fuzzy mode only.
    min_speed_mps, still_wander_s : float, optional
        Speeds up to `min_speed_mps` count as standing still in the motion test, m/s (default
        None: ``position_sigma_m / still_wander_s``, `still_wander_s` default 250 s;
        :func:`fusion.active.lifecycle.hold_tests`).
    hold_stationary : bool, optional
        Fuzzy mode: a track whose own detections do not move significantly stays tentative
        (default True; :func:`fusion.active.lifecycle.stationary_hold`).
    reject_platform_fixed : bool, optional
        Fuzzy mode: hold tracks steady relative to a sensor that moved (default True;
        :class:`fusion.active.platform.PlatformTest` at ``motion_probability``, ``min_speed_mps``).
    clutter_map : ClutterMapBase, optional
        Clutter map (default ``DensityClutterMap(position_sigma_m=position_sigma_m)``, see
        :mod:`fusion.active.clutter`); fuzzy mode only.
    position_errors : {"geometry", "isotropic"}, optional
        ``geometry`` (default): detections with ``src_x, src_y, rcv_x, rcv_y`` get the bistatic
        error ellipse of :func:`fusion.active.bistatic.bistatic_covariance`; ``isotropic``:
        every detection gets ``position_sigma_m`` per axis.
    range_sum_sigma_m : float, optional
        Accuracy of the bistatic range sum, m (default 100): the prior of the per-receiver
        estimate (``noise="estimate"``) or the value for every receiver (``noise="fixed"``).
    bearing_sigma_deg : float, optional
        Accuracy of the bearing at the receiver, deg (default 1.5), >= 0; as
        `range_sum_sigma_m`.
    noise : {"estimate", "fixed"}, optional
        ``estimate`` (default): accuracies learnt per receiver
        (:class:`fusion.active.noise.NoiseEstimator`); ``fixed``: the two values above.
    aspect : {"geometry", "measured"}, optional
        Equivalent aspect angle from the track heading and the geometry (default) or from an
        ``aspect_deg`` column (:class:`fusion.active.association.PairRanker`).
    score_threshold : float, optional
        Classifier-score gate (Section 2.2 of the paper: only detections whose score passes a
        threshold go on): detections with ``score`` below it start no track and join none; the
        clutter map still sees every detection. None (default, chosen on varied scenarios, see
        RESULTS) or data without a ``score`` column: no gate.
    confirm_llr : float, optional
        Fuzzy mode: besides its M-of-N hits, a tentative track needs a track score
        (:mod:`fusion.active.track_score`) of at least this (default 3); its score and
        ``max_misses`` delete it, not the M-of-N window. None: M-of-N alone (the paper).
    delete_llr : float, optional
        A tentative track whose score falls below this is deleted (default -4).
    detection_probability : float, optional
        ``P_D`` of a receiver per ping, for the track score; None (default): estimated.
    clutter_intensity : float, optional
        Clutter detections per m^2 per ping and receiver; None (default): estimated per
        receiver (:class:`fusion.active.clutter.ClutterIntensity`, kernel
        ``intensity_bandwidth_m`` = 1000 m).
    score_evidence : bool, optional
        The track score weighs each hit's classifier score (default True;
        :meth:`fusion.active.track_score.TrackScorer.score_delta`).
    motion_recent : bool, optional
        The motion test also fits the later half of the detections (default False).
    pd_from_tentative : bool, optional
        ``P_D`` also learnt from tentative tracks at `confirm_llr` (default True; False: confirmed alone).
    coast_probability : float, optional
        Confirmed tracks coast for `lifecycle.coast_misses` misses (default 0.01; None: `max_misses`).
    intensity_leave_one_out, intensity_leave_track_out, hits_per_detection : bool, optional
    coast_gate_births, successor_llr, snr_evidence, birth_evidence, track_pd_prior_pings : optional
        Alternatives measured and kept off (defaults False / None; ``docs/tracking.md``): the
        clutter intensity at a hit leaves out the hit's kernel or the track's own detections
        (`TrackScorer`); each detection counts a hit; births in coasting tracks' gates with a
        starting score (:mod:`fusion.active.births`); SNR in the score and births at their
        features' ratio; each track's own ``P_D`` (:mod:`fusion.active.track_pd`).
    shadow : bool, optional
        Fuzzy mode, monostatic sensors (detections with ``own_x, own_y`` and no ``rcv_x,
        rcv_y``): hold tentative tracks behind a near confirmed track (default True;
        :class:`fusion.active.shadow.ShadowTest` at `shadow_extent_sigmas`, default 8).
    """

    def __init__(
        self,
        *,
        mode: Literal["fuzzy", "kalman"] = "fuzzy",
        system: object | None = None,
        clues: Iterable[str] | None = None,
        position_sigma_m: float = 100.0,
        accel_psd: float = 0.04,
        speed_sigma_mps: float = 3.0,
        gate_probability: float = 0.99,
        min_rank: float | None = None,
        edge_likelihood: float = EDGE_LIKELIHOOD,
        confirm_hits: int = 3,
        confirm_window: int = 4,
        max_misses: int = 5,
        init_exclusion_m: float = 0.0,
        clutter_map: ClutterMapBase | None = None,
        motion_probability: float = 0.999,
        hold_stationary: bool = True,
        position_errors: Literal["geometry", "isotropic"] = "geometry",
        range_sum_sigma_m: float = 100.0,
        bearing_sigma_deg: float = 1.5,
        noise: Literal["estimate", "fixed"] = "estimate",
        aspect: Literal["geometry", "measured"] = "geometry",
        score_threshold: float | None = None,
        confirm_llr: float | None = 3.0,
        delete_llr: float = -4.0,
        detection_probability: float | None = None,
        clutter_intensity: float | None = None,
        score_evidence: bool = True,
        min_speed_mps: float | None = None,
        still_wander_s: float = STILL_WANDER_S,
        hotspot_drop: bool = False,
        reject_platform_fixed: bool = True,
        confirmed_edge_likelihood: float | None = 0.1,
        intensity_bandwidth_m: float = 1000.0,
        motion_recent: bool = False,
        pd_from_tentative: bool = True,
        coast_probability: float | None = 0.01,
        shadow: bool = True,
        shadow_extent_sigmas: float = 8.0, intensity_leave_one_out: bool = False,
        intensity_leave_track_out: bool = False, hits_per_detection: bool = False,
        coast_gate_births: bool = False, successor_llr: float | None = None,
        snr_evidence: bool = False, birth_evidence: bool = False,
        track_pd_prior_pings: float | None = None,
    ) -> None:
        check_tracker_options(mode=mode, speed_sigma_mps=speed_sigma_mps, accel_psd=accel_psd,
                              confirm=(confirm_hits, confirm_window), max_misses=max_misses,
                              coast_probability=coast_probability, noise=noise,
                              score_threshold=score_threshold)
        if mode == "fuzzy" and system is None:
            from fusion.active.rulebase import default_association_system
            system = default_association_system()
        self.mode = mode
        self.system = system
        self.ranker = PairRanker(system, clues=clues, min_rank=min_rank,
                                 edge_likelihood=edge_likelihood, aspect=aspect,
                                 confirmed_edge_likelihood=confirmed_edge_likelihood)
        self.measurement_model = MeasurementModel(
            position_errors=position_errors, position_sigma_m=position_sigma_m,
            range_sum_sigma_m=range_sum_sigma_m, bearing_sigma_deg=bearing_sigma_deg,
            noise=(NoiseEstimator(range_sum_sigma_m=max(range_sum_sigma_m, 1e-3),
                                  bearing_sigma_deg=max(bearing_sigma_deg, 1e-3))
                   if noise == "estimate" else None))
        self.score_threshold = None if score_threshold is None else float(score_threshold)
        self.hotspot_drop = bool(hotspot_drop)
        self.pd_from_tentative = bool(pd_from_tentative)
        self.coast_probability = coast_probability
        self.scorer = (TrackScorer(confirm_llr=confirm_llr, delete_llr=delete_llr,
                                   detection_probability=detection_probability,
                                   clutter_intensity=clutter_intensity, score_evidence=score_evidence,
                                   leave_one_out=intensity_leave_one_out,
                                   leave_track_out=intensity_leave_track_out, snr_evidence=snr_evidence,
                                   track_pd_prior_pings=track_pd_prior_pings,
                                   intensity=ClutterIntensity(bandwidth_m=intensity_bandwidth_m))
                       if mode == "fuzzy" and confirm_llr is not None else None)
        holds = hold_tests(fuzzy=mode == "fuzzy", position_sigma_m=position_sigma_m,
                           motion_probability=motion_probability, min_speed_mps=min_speed_mps,
                           still_wander_s=still_wander_s, motion_recent=motion_recent,
                           reject_platform_fixed=reject_platform_fixed, shadow=shadow,
                           shadow_extent_sigmas=shadow_extent_sigmas)
        self.min_speed_mps, self.motion_test = holds.min_speed_mps, holds.motion
        self.shadow_test, self.platform_test = holds.shadow, holds.platform
        self.accel_psd = float(accel_psd)
        self.speed_sigma_mps = float(speed_sigma_mps)
        self.gate = gate_threshold(gate_probability)
        self._model: tuple[float, NDArray[np.float64], NDArray[np.float64]] | None = None
        self.m, self.n, self.max_misses = int(confirm_hits), int(confirm_window), int(max_misses)
        self.init_exclusion_m = float(init_exclusion_m)
        self.hold_stationary, self.hits_per_detection = bool(hold_stationary), bool(hits_per_detection)
        self.coast_gate_births, self.birth_evidence = bool(coast_gate_births), bool(birth_evidence)
        self.successor_llr = None if successor_llr is None else float(successor_llr)
        if mode == "fuzzy":
            self.clutter_map = (clutter_map if clutter_map is not None
                                else DensityClutterMap(position_sigma_m=position_sigma_m))
        else:
            self.clutter_map = None
        self.reset()

    @property
    def clues(self) -> frozenset[str]:
        """Clues the rank may use (a subset of :data:`fusion.active.association.CLUE_NAMES`)."""
        return self.ranker.clues

    def reset(self) -> None:
        """Forget all tracks (and the clutter map's content)."""
        self._ids = np.zeros(0, np.int64)
        self._llr = np.zeros(0)
        self._succ = np.zeros(0, dtype=bool)
        self._x = np.zeros((0, 4))
        self._P = np.zeros((0, 4, 4))
        self._life: list[Lifecycle] = []
        # Per track: time, x, y, R_xx, R_xy, R_yy, sensor x, y of its tentative detections.
        self._seen: list[list[list[float]]] = []
        self._next_id = 0
        self._time: float | None = None
        if self.clutter_map is not None:
            self.clutter_map = self.clutter_map.empty_copy()
        if self.measurement_model.noise is not None:
            self.measurement_model.noise.reset()
        if self.scorer is not None:
            self.scorer.reset()
        if self.shadow_test is not None:
            self.shadow_test.reset()

    def threshold(self, present: Iterable[str]) -> float:
        """Lowest associable rank for pairs whose rank used the inputs ``present``
        (:meth:`fusion.active.association.PairRanker.threshold`)."""
        return self.ranker.threshold(present)

    def measurement_covariances(self, ping: Ping) -> tuple[NDArray[np.float64], bool]:
        """Position covariance of each detection of a ping, m^2, and whether any is geometric
        (:meth:`fusion.active.bistatic.MeasurementModel.covariances`)."""
        return self.measurement_model.covariances(ping)

    def step(self, ping: Ping) -> PingResult:
        """Process one ping (events in increasing time): predict, rank, associate, update,
        manage tracks; the ping's :class:`PingResult`."""
        if self._time is not None and ping.time < self._time:
            raise ValueError(f"event {ping.event}: time {ping.time} goes back before {self._time}")
        dt = 0.0 if self._time is None else ping.time - self._time
        self._time = ping.time
        if self._model is None or self._model[0] != dt:
            self._model = (dt, *cv_model(dt, self.accel_psd))
        self._x, self._P = kf_predict(self._x, self._P, self._model[1], self._model[2])
        if self.measurement_model.noise is not None:
            self.measurement_model.noise.update(ping)
        Rz, geometric = self.measurement_model.covariances(ping)

        # The clutter map counts this ping too, so a feature echoing on every ping is a hotspot
        # from its min_pings-th ping on, before a track on it can be confirmed. It sees every
        # detection; the score gate applies to tracking only.
        if self.clutter_map is not None:
            self.clutter_map.update(ping.xy, ping.time, cov=Rz if geometric else None)
        full_index, ping = score_gate(ping, self.score_threshold)
        Rz = Rz[full_index]
        hot_d = (self.clutter_map.distance(ping.xy) if self.clutter_map is not None
                 else np.full(ping.n, np.inf))
        n0 = self._ids.size
        confirmed0 = np.fromiter((lc.status == "confirmed" for lc in self._life), bool, n0)
        scan = PingScan(ping=ping, Rz=Rz, hot_d=hot_d, confirmed=confirmed0,
                         dets=[[] for _ in range(n0)], rank=[np.nan] * n0,
                         rows=np.column_stack([np.full(ping.n, ping.time), ping.xy, Rz[:, 0, 0],
                                               Rz[:, 0, 1], Rz[:, 1, 1],
                                               sensor_positions(ping)]).tolist())
        # Each receiver's detections are a scan of their own at the ping time: a track takes at
        # most one detection per receiver, and a track born from one receiver's echo may take
        # the echoes of the same place from the receivers after it.
        groups = receiver_groups(ping)
        for key, idx in groups:
            self._scan(scan, key, idx)
        return self._manage(scan, full_index, n0, [k for k, _ in groups])

    def _scan(self, scan: PingScan, key: tuple[float, ...] | None,
              idx: NDArray[np.int64]) -> None:
        """Associate one receiver's detections of the ping; update, score, start tracks."""
        ping = scan.ping
        xy, R, hot = ping.xy[idx], scan.Rz[idx], scan.hot_d[idx]
        nt, nd = self._ids.size, idx.size
        confirmed = np.zeros(nt, dtype=bool)
        confirmed[:scan.confirmed.size] = scan.confirmed
        # Kalman stage: gate all pairs; fuzzy stage: rank only the gated ones, in one call.
        stats = pair_statistics(self._x, self._P, xy, R)
        gated = stats.d2 <= self.gate
        ti, di = np.nonzero(gated)
        score = np.zeros(gated.shape)
        valid = np.zeros(gated.shape, dtype=bool)
        if ti.size:
            L = np.exp(-0.5 * stats.d2[ti, di])
            if self.mode == "kalman":
                score[ti, di] = L
                valid[ti, di] = True
            else:
                rank, limit = self.ranker.rank(ping.subset(idx), ti, di, L, hot, self._x, self._P,
                                               confirmed=confirmed)
                score[ti, di] = rank
                valid[ti, di] = rank >= limit
        det_of = assign_by_priority(score, valid, confirmed)
        hit = det_of >= 0
        taken = np.zeros(nd, dtype=bool)
        taken[det_of[hit]] = True
        if self.shadow_test is not None and "rcv_x" not in ping.clues and (hit & confirmed).any():
            c = np.flatnonzero(hit & confirmed)
            self.shadow_test.learn(self._ids[c], self._x[c, :2], xy[det_of[c]],
                                   [scan.rows[idx[j]][6:8] for j in det_of[c].tolist()])
        if hit.any():
            self._x[hit], self._P[hit] = kf_update(self._x[hit], self._P[hit], xy[det_of[hit]],
                                                   R[det_of[hit]])
        for i in np.flatnonzero(hit).tolist():
            j = int(det_of[i])
            if not scan.dets[i]:
                scan.rank[i] = float(score[i, j])
            scan.dets[i].append(int(idx[j]))
            if not confirmed[i]:
                self._seen[i].append(scan.rows[idx[j]])
        if self.scorer is not None:
            i = np.flatnonzero(hit)
            j = det_of[i]
            self._llr = self._llr + self.scorer.scan_delta(
                key, xy=xy, cov=R, track_xy=self._x[:, :2], hits=i, dets=j,
                scores=ping.clues["score"][idx] if "score" in ping.clues else None,
                hotspots=self.clutter_map.hotspots() if self.clutter_map is not None else None,
                log_pdf=-0.5 * stats.d2[i, j] - np.log(2.0 * np.pi) - 0.5 * np.log(stats.det[i, j]),
                confirmed=confirmed, contested=~hit & gated[:, taken].any(axis=1),
                teach=confirmed | (self.pd_from_tentative & (self._llr >= self.scorer.confirm_llr)),
                own=self.scorer.own_rows(i, key),
                snr_db=ping.clues["snr_db"][idx] if "snr_db" in ping.clues else None)
            self.scorer.remember(i, j, key, xy)

        # New tentative tracks: free detections (taken by no track, inside no blocking track's
        # gate, fusion.active.births) away from hotspots.
        free = ~taken & ~gated[birth_blockers(hit, confirmed,
                                              coast_gate_births=self.coast_gate_births)].any(axis=0)
        if self.mode == "fuzzy":
            free &= hot > self.init_exclusion_m
        new = np.flatnonzero(free)
        if new.size:
            start_tracks(self, scan, key, idx, new, xy, R, successor_flags(gated, hit, confirmed, new))

    def _manage(self, scan: PingScan, full_index: NDArray[np.int64], n0: int,
                keys: Sequence[object] = ()) -> PingResult:
        """Track management after all receivers of a ping; the ping's result."""
        ping = scan.ping
        nt = self._ids.size
        hit = np.fromiter((bool(d) for d in scan.dets), bool, nt)
        confirmed = np.zeros(nt, dtype=bool)
        confirmed[:n0] = scan.confirmed
        old = np.arange(nt) < n0
        dropped = np.zeros(nt, dtype=bool)
        if self.clutter_map is not None and self.hotspot_drop:
            tent = ~confirmed & old
            dropped[tent] = (self.clutter_map.distance(self._x[tent, :2])
                             <= self.init_exclusion_m)
            dropped = hotspot_drop(dropped, self._seen, self.motion_test)
        if self.scorer is not None:
            dropped |= old & ~confirmed & (self._llr < self.scorer.delete_llr)
        counts = [len(d) for d in scan.dets] if self.hits_per_detection else hit.tolist()
        m_each = self.m - self._succ.astype(int)
        held = stationary_hold(
            cand := old & hit & ~confirmed & ~dropped, self._life, self._seen, m=m_each,
            motion_test=(self.motion_test if self.clutter_map is not None and self.hold_stationary
                         else None),
            score_short=(self._llr < self.scorer.confirm_llr if self.scorer is not None
                         else None),
            platform_test=self.platform_test, shadowed=None if self.shadow_test is None else
            self.shadow_test.shadowed_tracks(cand, self._seen, self._ids[confirmed],
                                             self._x[confirmed, :2]),
            counts=counts)
        born = {c: Lifecycle(hits=int(c)) for c in set(counts[n0:])}  # immutable: shared
        self._life[n0:] = [born[c] for c in counts[n0:]]
        coast = (self.max_misses if self.scorer is None or self.coast_probability is None
                 else coast_misses([self.scorer.pd(k) for k in keys],
                                   probability=self.coast_probability, floor=self.max_misses))
        life = [next_lifecycle(lc, h, dropped=d, held=s, m=m_i, n=self.n,
                               max_misses=coast if lc.status == "confirmed" else self.max_misses,
                               window=self.scorer is None)
                for lc, h, d, s, m_i in zip(self._life[:n0], counts[:n0], dropped[:n0].tolist(),
                                            held[:n0].tolist(), m_each[:n0].tolist(), strict=True)]
        self._life = life + self._life[n0:]

        status = np.array([lc.status for lc in self._life], dtype=str)
        result = ping_result(
            scan, full_index=full_index, track_id=self._ids, state=self._x,
            covariance=self._P, status=status,
            hotspots=(self.clutter_map.hotspots().positions if self.clutter_map is not None
                      else np.zeros((0, 2))))
        alive = status != "deleted"
        alive_l = alive.tolist()
        self._ids, self._x, self._P = self._ids[alive], self._x[alive], self._P[alive]
        self._llr = self._llr[alive]
        self._succ = self._succ[alive]
        self._life = [lc for lc, a in zip(self._life, alive_l, strict=True) if a]
        if self.scorer is not None:
            self.scorer.keep_tracks(alive)
        self._seen = [[] if st == "confirmed" else h
                      for h, a, st in zip(self._seen, alive_l, status.tolist(), strict=True) if a]
        logger.debug("event %d: %d detections, %d tracks, %d new", ping.event, ping.n, n0, nt - n0)
        return result

    def run(self, detections: Iterable[Ping] | Columns) -> TrackingResult:
        """Track a whole run from a fresh start.

        Parameters
        ----------
        detections : iterable of Ping, or named columns
            The pings, or detection columns (``event,time,x,y`` + optional clues, e.g. a
            :class:`fusion.io.Table`) grouped by :func:`fusion.active.types.pings_from_columns`.

        Returns
        -------
        TrackingResult
        """
        named = hasattr(detections, "__contains__") and not isinstance(detections, Sequence)
        pings = pings_from_columns(detections) if named else list(detections)
        self.reset()
        return TrackingResult(tuple(self.step(p) for p in pings))
