"""Multistatic active tracker: Kalman prediction, fuzzy association, M-of-N track management.

Implements the tracker of "Target tracking using fuzzy logic association" (Section 3, "Tracker
overview"; Section 2.5, "Tracker"; Section 7, "Results") by composing its stages, one module
each:

1. *Kalman stage* (:mod:`fusion.active.kalman`): constant-velocity prediction of every track,
   innovation statistics of every (track, detection) pair, the chi-square gate; each detection
   with its own position covariance (:mod:`fusion.active.bistatic`).
2. *Fuzzy stage* (:mod:`fusion.active.association`): the rule base ranks the gated pairs from the
   likelihood ratio and the clues present; the rank threshold is read off the rule base for each
   pair's clue set; conflicts are settled by an assignment maximising the summed rank, confirmed
   tracks first.
3. *Track management* (:mod:`fusion.active.lifecycle`): a detection that no track takes, that
   lies in no track's gate and is not near a hotspot starts a tentative track; M-of-N
   confirmation, deletion after consecutive misses, the hotspot drop and the stationary hold
   (motion test of the track's own detections). The clutter map is
   :class:`fusion.active.clutter.ClutterMap`.

``mode="kalman"`` is the paper's comparison tracker: nearest neighbour on the likelihood alone
(pairs inside the gate, highest ``L`` wins, same assignment and track management), no clutter map.

Choices where the paper is silent, besides those documented in the stage modules:

- The detections of one event are treated as simultaneous, at the time of the event's first row.
- Missing event numbers (pings without any detection) are stepped through as empty pings at
  interpolated times, so that they count as misses (:func:`fusion.active.types.pings_from_columns`).
- Every ping is one vectorised pass: the Kalman statistics of all (track, detection) pairs at
  once (closed-form 2 x 2 inverses), then ONE call of the fuzzy system on the gated pairs only
  (two when the aspect angle is computed from geometry and unknown for some tracks, as the
  engine takes no missing values).

The names of the stage modules are also importable from here, as before the split.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from fusion.active.association import (
    CLUE_NAMES,
    EDGE_LIKELIHOOD,
    PairRanker,
    assign,
    assign_by_priority,
    derived_min_rank,
    neutral_value,
)
from fusion.active.bistatic import MeasurementModel, bistatic_covariance, equivalent_aspect_deg
from fusion.active.clutter import ClutterMap
from fusion.active.kalman import (
    PairStatistics,
    cv_model,
    gate_threshold,
    kf_predict,
    kf_update,
    pair_statistics,
)
from fusion.active.lifecycle import (
    Lifecycle,
    MotionTest,
    advance_status,
    motion_statistic,
    next_lifecycle,
    track_status,
)
from fusion.active.types import Columns, Ping, PingResult, TrackingResult, pings_from_columns

__all__ = [
    "CLUE_NAMES",
    "EDGE_LIKELIHOOD",
    "Lifecycle",
    "PairStatistics",
    "Ping",
    "PingResult",
    "Tracker",
    "TrackingResult",
    "advance_status",
    "assign",
    "bistatic_covariance",
    "cv_model",
    "derived_min_rank",
    "equivalent_aspect_deg",
    "gate_threshold",
    "kf_predict",
    "kf_update",
    "motion_statistic",
    "neutral_value",
    "pair_statistics",
    "pings_from_table",
    "track_status",
]

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
        Which of :data:`CLUE_NAMES` may be used (default all); those absent from the data are
        left out anyway. ``aspect_deg`` covers both a given column and the angle computed from
        source/receiver positions.
    position_sigma_m : float, optional
        Standard deviation of each position coordinate of a detection without source/receiver
        positions (or with ``position_errors="isotropic"``), m (default 100).
    accel_psd : float, optional
        White-acceleration spectral density, m^2/s^3 (default 0.01: about a 90 deg turn in
        10 min at 3 m/s, a ~ 0.008 m/s^2, sustained over a ping interval).
    speed_sigma_mps : float, optional
        Standard deviation of each velocity component of a new track, m/s (default 3, about the
        speed of a submarine on patrol).
    gate_probability : float, optional
        Chi-square gate probability (default 0.99).
    min_rank : float, optional
        Lowest rank (fuzzy mode) that may be associated, the same for every pair. Default None:
        derived from the rule base for the clues each pair actually has
        (:func:`derived_min_rank` at ``edge_likelihood``), so that data with fewer clues (e.g.
        positions only) are not held to a threshold calibrated with all of them.
    edge_likelihood : float, optional
        Likelihood ratio at the edge of the acceptance region used by the derived threshold
        (default :data:`EDGE_LIKELIHOOD` = 0.25, the crossover of "unlikely").
    confirm_hits, confirm_window : int, optional
        M-of-N confirmation (default 3 of 4).
    max_misses : int, optional
        Consecutive misses that delete a confirmed track (default 3).
    init_exclusion_m : float, optional
        Detections closer than this to a hotspot region start no track (fuzzy mode; default
        300 m, where the default "near" membership is 1/2).
    motion_probability : float, optional
        Confidence of the motion test that keeps a tentative track near a hotspot alive
        (default 0.999), in (0, 1); see :func:`motion_statistic`. Fuzzy mode only.
    hold_stationary : bool, optional
        Fuzzy mode: a track that reaches ``confirm_hits`` hits while its own detections do not
        move significantly (:func:`motion_statistic` at ``motion_probability``, from
        ``confirm_hits`` detections) stays tentative until they do (default True); such a
        held track is deleted after ``max_misses`` consecutive misses.
    clutter_map : ClutterMap, optional
        Clutter map (default ``ClutterMap(position_sigma_m=position_sigma_m)``); fuzzy mode
        only.
    position_errors : {"geometry", "isotropic"}, optional
        ``geometry`` (default): detections with ``src_x, src_y, rcv_x, rcv_y`` get the bistatic
        error ellipse of :func:`bistatic_covariance`; ``isotropic``: every detection gets
        ``position_sigma_m`` per axis.
    range_sum_sigma_m : float, optional
        Accuracy (standard deviation) of the bistatic range sum, m (default 30, the
        simulator's sonar value), >= 0.
    bearing_sigma_deg : float, optional
        Accuracy of the bearing at the receiver, deg (default 1, the simulator's sonar value),
        >= 0.

    Notes
    -----
    :meth:`step` processes one ping (streaming); :meth:`run` a whole detections table.
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
        init_exclusion_m: float = 300.0,
        clutter_map: ClutterMap | None = None,
        motion_probability: float = 0.999,
        hold_stationary: bool = True,
        position_errors: Literal["geometry", "isotropic"] = "geometry",
        range_sum_sigma_m: float = 30.0,
        bearing_sigma_deg: float = 1.0,
    ) -> None:
        if mode not in ("fuzzy", "kalman"):
            raise ValueError(f"mode must be 'fuzzy' or 'kalman', got {mode!r}")
        if not np.isfinite(speed_sigma_mps) or speed_sigma_mps <= 0:
            raise ValueError(f"speed_sigma_mps must be positive, got {speed_sigma_mps!r}")
        if not np.isfinite(accel_psd) or accel_psd < 0:
            raise ValueError(f"accel_psd must be >= 0, got {accel_psd!r}")
        if not 1 <= confirm_hits <= confirm_window:
            raise ValueError("need 1 <= confirm_hits <= confirm_window, got "
                             f"{confirm_hits} and {confirm_window}")
        if max_misses < 1:
            raise ValueError(f"max_misses must be >= 1, got {max_misses!r}")
        if mode == "fuzzy" and system is None:
            from fusion.active.rulebase import default_association_system

            system = default_association_system()
        self.mode = mode
        self.system = system
        self.ranker = PairRanker(system, clues=clues, min_rank=min_rank,
                                 edge_likelihood=edge_likelihood)
        self.measurement_model = MeasurementModel(
            position_errors=position_errors, position_sigma_m=position_sigma_m,
            range_sum_sigma_m=range_sum_sigma_m, bearing_sigma_deg=bearing_sigma_deg)
        self.motion_test = MotionTest(probability=motion_probability)
        self.accel_psd = float(accel_psd)
        self.speed_sigma_mps = float(speed_sigma_mps)
        self.gate = gate_threshold(gate_probability)
        self._model: tuple[float, NDArray[np.float64], NDArray[np.float64]] | None = None
        self.m, self.n, self.max_misses = int(confirm_hits), int(confirm_window), int(max_misses)
        self.init_exclusion_m = float(init_exclusion_m)
        self.hold_stationary = bool(hold_stationary)
        if mode == "fuzzy":
            self.clutter_map = (clutter_map if clutter_map is not None
                                else ClutterMap(position_sigma_m=position_sigma_m))
        else:
            self.clutter_map = None
        self.reset()

    @property
    def clues(self) -> frozenset[str]:
        """Clues the rank may use (a subset of :data:`CLUE_NAMES`)."""
        return self.ranker.clues

    def reset(self) -> None:
        """Forget all tracks (and the clutter map's content)."""
        self._ids = np.zeros(0, np.int64)
        self._x = np.zeros((0, 4))
        self._P = np.zeros((0, 4, 4))
        self._life: list[Lifecycle] = []
        # Per track: time, x, y, R_xx, R_xy, R_yy of its detections while tentative (motion test).
        self._seen: list[list[list[float]]] = []
        self._next_id = 0
        self._time: float | None = None
        if self.clutter_map is not None:
            self.clutter_map = self.clutter_map.empty_copy()

    def threshold(self, present: Iterable[str]) -> float:
        """Lowest associable rank for pairs whose rank used the inputs ``present``
        (:meth:`fusion.active.association.PairRanker.threshold`)."""
        return self.ranker.threshold(present)

    def measurement_covariances(self, ping: Ping) -> tuple[NDArray[np.float64], bool]:
        """Position covariance of each detection of a ping, m^2, and whether any is geometric
        (:meth:`fusion.active.bistatic.MeasurementModel.covariances`)."""
        return self.measurement_model.covariances(ping)

    def step(self, ping: Ping) -> PingResult:
        """Process one ping: predict, rank, associate, update, manage tracks.

        Parameters
        ----------
        ping : Ping
            Detections of the event; events must come in increasing time.

        Returns
        -------
        PingResult
        """
        if self._time is not None and ping.time < self._time:
            raise ValueError(f"event {ping.event}: time {ping.time} goes back before {self._time}")
        dt = 0.0 if self._time is None else ping.time - self._time
        self._time = ping.time
        if self._model is None or self._model[0] != dt:
            self._model = (dt, *cv_model(dt, self.accel_psd))
        self._x, self._P = kf_predict(self._x, self._P, self._model[1], self._model[2])
        nt, nd = self._ids.size, ping.n
        Rz, geometric = self.measurement_model.covariances(ping)

        # The clutter map counts this ping too, so a feature echoing on every ping is a hotspot
        # from its min_pings-th ping on, before a track on it can be confirmed.
        if self.clutter_map is not None:
            self.clutter_map.update(ping.xy, ping.time, cov=Rz if geometric else None)
            hot_d = self.clutter_map.distance(ping.xy)
        else:
            hot_d = np.full(nd, np.inf)

        # Kalman stage: gate all pairs; fuzzy stage: rank only the gated ones, in one call.
        stats = pair_statistics(self._x, self._P, ping.xy, Rz)
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
                rank, limit = self.ranker.rank(ping, ti, di, L, hot_d, self._x, self._P)
                score[ti, di] = rank
                valid[ti, di] = rank >= limit
        confirmed = np.fromiter((lc.status == "confirmed" for lc in self._life), bool, nt)
        det_of = assign_by_priority(score, valid, confirmed)
        hit = det_of >= 0
        taken = np.zeros(nd, dtype=bool)
        taken[det_of[hit]] = True
        if hit.any():
            self._x[hit], self._P[hit] = kf_update(self._x[hit], self._P[hit], ping.xy[det_of[hit]],
                                                   Rz[det_of[hit]])
        rank = np.full(nt, np.nan)
        rank[hit] = score[np.flatnonzero(hit), det_of[hit]]

        # Track management. Motion-test rows of the detections: time, x, y, R_xx, R_xy, R_yy.
        rows = np.column_stack([np.full(nd, ping.time), ping.xy, Rz[:, 0, 0], Rz[:, 0, 1],
                                Rz[:, 1, 1]]).tolist()
        for i in np.flatnonzero(hit & ~confirmed):
            self._seen[i].append(rows[det_of[i]])
        dropped = self._on_hotspot(confirmed)
        held = self._held(hit & ~confirmed & ~dropped)
        self._life = [next_lifecycle(lc, h, dropped=d, held=s, m=self.m, n=self.n,
                                     max_misses=self.max_misses)
                      for lc, h, d, s in zip(self._life, hit.tolist(), dropped.tolist(),
                                             held.tolist(), strict=True)]

        # New tentative tracks: free detections outside every gate and away from hotspots.
        free = ~taken & ~gated.any(axis=0)
        if self.mode == "fuzzy":
            free &= hot_d > self.init_exclusion_m
        new = np.flatnonzero(free)
        ids = np.arange(self._next_id, self._next_id + new.size, dtype=np.int64)
        self._next_id += new.size
        x_new = np.zeros((new.size, 4))
        x_new[:, :2] = ping.xy[new]
        P_new = np.zeros((new.size, 4, 4))
        P_new[:, :2, :2] = Rz[new]
        P_new[:, 2:, 2:] = np.eye(2) * self.speed_sigma_mps**2

        det_all = np.concatenate([det_of, new])
        used = det_all >= 0
        z = np.full((det_all.size, 2), np.nan)
        z[used] = ping.xy[det_all[used]]
        Rz_all = np.full((det_all.size, 2, 2), np.nan)
        Rz_all[used] = Rz[det_all[used]]
        status = np.array([lc.status for lc in self._life] + ["tentative"] * new.size, dtype=str)
        result = PingResult(
            event=ping.event,
            time=ping.time,
            track_id=np.concatenate([self._ids, ids]),
            state=np.concatenate([self._x, x_new]),
            status=status,
            detection=det_all,
            rank=np.concatenate([rank, np.full(new.size, np.nan)]),
            hotspots=(self.clutter_map.hotspots().positions if self.clutter_map is not None
                      else np.zeros((0, 2))),
            covariance=np.concatenate([self._P, P_new]),
            measurement=z,
            measurement_cov=Rz_all,
        )
        alive = status != "deleted"
        alive_l, status_l = alive.tolist(), status.tolist()
        self._ids = result.track_id[alive]
        self._x = result.state[alive]
        self._P = result.covariance[alive]
        self._life = [lc for lc, a in zip(self._life + [Lifecycle()] * new.size, alive_l,
                                          strict=True) if a]
        seen = self._seen + [[rows[j]] for j in new.tolist()]
        self._seen = [[] if st == "confirmed" else h
                      for h, a, st in zip(seen, alive_l, status_l, strict=True) if a]
        logger.debug("event %d: %d detections, %d tracks, %d new", ping.event, nd, nt, new.size)
        return result

    def _on_hotspot(self, confirmed: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Tentative tracks to drop: within ``init_exclusion_m`` of a hotspot and not moving.

        A potential track inside a hotspot's reach is the hotspot, not a target: it is dropped,
        as a detection there starts no track (same distance), unless its own detections move
        significantly (a slow target mistaken for a hotspot).
        """
        nt = confirmed.size
        on_hot = np.zeros(nt, dtype=bool)
        if self.clutter_map is not None and nt and not confirmed.all():
            on_hot[~confirmed] = (self.clutter_map.distance(self._x[~confirmed, :2])
                                  <= self.init_exclusion_m)
            for i in np.flatnonzero(on_hot):
                on_hot[i] = self.motion_test.moves(self._seen[i]) is not True
        return on_hot

    def _held(self, candidates: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Tentative tracks with a hit that would be confirmed but whose detections stand still.

        A feature echoes from one place, a submarine moves. The clutter map may not have flagged
        the feature yet (its echoes scatter over several cells, or it skipped a ping), so this is
        the track-level form of the map's test; once the map flags it, the hotspot drop ends the
        track.
        """
        hold = np.zeros(candidates.size, dtype=bool)
        if self.clutter_map is not None and self.hold_stationary:
            for i in np.flatnonzero(candidates).tolist():
                if self._life[i].hits + 1 >= self.m:
                    hold[i] = self.motion_test.moves(self._seen[i]) is False
        return hold

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
