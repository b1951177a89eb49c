"""Stone Soup's GNN and JPDA position trackers on a multistatic detections file: the external
baselines of ``bench_active.py --grid --stonesoup`` (issue 20).

Built only from Stone Soup components: a nearly-constant-velocity Kalman filter per track
(``ConstantVelocity`` on x and y), a Cartesian ``LinearGaussian`` measurement per detection, global
nearest neighbour (``GNNWith2DAssignment`` with a Mahalanobis ``DistanceHypothesiser``) or joint
probabilistic data association (``JPDAwithEHM``, the exact JPDA marginals computed by efficient
hypothesis management, with a ``PDAHypothesiser``; the brute-force ``JPDA`` enumerates the
product of every track's hypotheses, exponential in the number of tracks), Gaussian-mixture
reduction per scan (``MultiTargetMixtureTracker``), tracks started by a
``MultiMeasurementInitiator`` (GNN over holding tracks, confirmed by track length: ``min_points``
updates) and deleted by an ``UpdateTimeDeleter`` (no update for ``max_misses`` ping periods).

Each receiver's detections of a ping are one scan at the ping's time (sequential multi-sensor
updating: a track can take one detection per receiver and ping). A detection's measurement
covariance is its bistatic error ellipse (:func:`fusion.active.bistatic.bistatic_covariance`)
for the stated sensor accuracies (100 m range sum, 1.5 deg bearing: the ``fusion track --noise
fixed`` values), isotropic at the fitted position sigma where the geometry gives none. The
scales (scan period, process noise, speed prior, clutter density) are the ones ``fusion track``
reads from the same file (:func:`fusion.active.settings.track_settings`); the clutter density
per scan is divided among the receivers of the ping. Nothing from the truth is used.

To keep the runs short, each associator hypothesises only the detections that can pass its
gate: a detection farther than ``g * sqrt(trace S_max)`` from a track's predicted position
(``S_max`` the largest innovation covariance of the scan, ``g`` the gate in sigmas) has a
Mahalanobis distance above ``g``, so this pre-selection drops no hypothesis the gate would keep.
"""

from __future__ import annotations

import datetime

import numpy as np
from _jpda import T0, _Scans  # the one Stone Soup scan reader of the benchmarks
from scipy.spatial import cKDTree
from scipy.stats import chi2
from stonesoup.base import Base, Property
from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
from stonesoup.dataassociator.probability import JPDAwithEHM
from stonesoup.deleter.time import UpdateTimeDeleter
from stonesoup.hypothesiser.distance import DistanceHypothesiser
from stonesoup.hypothesiser.probability import PDAHypothesiser
from stonesoup.initiator.simple import MultiMeasurementInitiator
from stonesoup.measures import Mahalanobis
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import (
    CombinedLinearGaussianTransitionModel,
    ConstantVelocity,
)
from stonesoup.predictor.kalman import KalmanPredictor
from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
from stonesoup.types.array import StateVector
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState
from stonesoup.updater.kalman import KalmanUpdater

from fusion.active.bistatic import bistatic_covariance

#: Stated sensor accuracies of the measurement covariances (``fusion track --noise fixed``).
RANGE_SUM_SIGMA_M = 100.0
BEARING_SIGMA_DEG = 1.5


class _NearbyMixIn(Base):
    """Hypothesise only the detections within the gate's Euclidean bound of each track."""

    gate_sigmas: float = Property(default=4.0, doc="gate, sigmas (the Euclidean bound's g)")

    def generate_hypotheses(self, tracks, detections, timestamp, **kwargs):
        if not tracks or not detections:
            return {t: self.hypothesiser.hypothesise(t, detections, timestamp, **kwargs)
                    for t in tracks}
        dets = list(detections)
        xy = np.array([[float(d.state_vector[0, 0]), float(d.state_vector[1, 0])] for d in dets])
        r_max = max(float(np.trace(d.measurement_model.covar())) for d in dets)
        tree = cKDTree(xy)
        out = {}
        predictor = self.hypothesiser.predictor
        for t in tracks:
            pred = predictor.predict(t, timestamp=timestamp)
            pos = np.array([float(pred.state_vector[0, 0]), float(pred.state_vector[2, 0])])
            radius = self.gate_sigmas * np.sqrt(pred.covar[0, 0] + pred.covar[2, 2] + r_max)
            near = {dets[i] for i in tree.query_ball_point(pos, radius)}
            out[t] = self.hypothesiser.hypothesise(t, near, timestamp, **kwargs)
        return out


class _NearbyGNN(_NearbyMixIn, GNNWith2DAssignment):
    pass


class _NearbyJPDA(_NearbyMixIn, JPDAwithEHM):
    pass


def _scans(det, fallback_sigma_m: float) -> tuple[list, list[int], list[int]]:
    """Per ping and receiver, one scan of Detections; the ping's event and count of receivers."""
    ev = np.asarray(det["event"]).astype(np.int64)
    t = np.asarray(det["time"], dtype=float)
    xy = np.column_stack([det["x"], det["y"]]).astype(float)
    if all(c in det for c in ("src_x", "src_y", "rcv_x", "rcv_y")):
        src = np.column_stack([det["src_x"], det["src_y"]]).astype(float)
        rcv = np.column_stack([det["rcv_x"], det["rcv_y"]]).astype(float)
        cov = bistatic_covariance(xy, src, rcv, RANGE_SUM_SIGMA_M, BEARING_SIGMA_DEG)
    else:
        rcv = np.zeros_like(xy)
        cov = np.full((len(xy), 2, 2), np.nan)
    bad = ~np.all(np.isfinite(cov.reshape(len(xy), -1)), axis=1)
    cov[bad] = np.eye(2) * fallback_sigma_m**2
    scans, events, receivers = [], [], []
    for e in np.unique(ev):
        rows = np.flatnonzero(ev == e)
        tm = T0 + datetime.timedelta(seconds=float(t[rows[0]]))
        groups = {}
        for j in rows:
            groups.setdefault((rcv[j, 0], rcv[j, 1]), []).append(j)
        for key in sorted(groups):
            dets = set()
            for j in groups[key]:
                mm = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=cov[j])
                dets.add(Detection(StateVector(xy[j]), timestamp=tm, measurement_model=mm))
            scans.append((tm, dets))
            events.append(int(e))
        receivers.append(len(groups))
    return scans, events, receivers


def run_stonesoup(det, settings, *, associator: str, prob_detect: float = 0.7,
                  min_points: int = 4, max_misses: float = 3.0, holding_misses: float = 1.0,
                  gate_sigmas: float = 4.0) -> dict:
    """Stone Soup's GNN (``associator="gnn"``) or JPDA (``"jpda"``) tracker on one detections
    table; returns ``track_id, event, x, y, status`` columns (every released track is
    ``confirmed``) at the end of each ping, for :func:`fusion.metrics.multistatic.score_tracks`.

    ``settings`` is the :class:`fusion.active.settings.TrackSettings` read from the same
    detections. ``max_misses`` and ``holding_misses``: ping periods without an update after
    which a confirmed or a holding track is deleted (plus half a period).
    """
    period = float(settings.period_s)
    q = float(settings.accel_psd)
    tm_model = CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])
    predictor = KalmanPredictor(tm_model)
    updater = KalmanUpdater(LinearGaussian(ndim_state=4, mapping=(0, 2),
                                           noise_covar=np.eye(2)))
    scans, events, receivers = _scans(det, float(settings.position_sigma_m))
    n_rcv = max(1, int(np.median(receivers)))
    if associator == "gnn":
        assoc = _NearbyGNN(DistanceHypothesiser(predictor, updater, Mahalanobis(),
                                                missed_distance=gate_sigmas),
                           gate_sigmas=gate_sigmas)
        tracker_cls = MultiTargetTracker
    elif associator == "jpda":
        prob_gate = 0.99
        assoc = _NearbyJPDA(PDAHypothesiser(
            predictor=predictor, updater=updater, prob_detect=prob_detect, prob_gate=prob_gate,
            clutter_spatial_density=max(float(settings.clutter_density), 1e-12) / n_rcv),
            gate_sigmas=float(np.sqrt(chi2.ppf(prob_gate, 2))))
        tracker_cls = MultiTargetMixtureTracker
    else:
        raise ValueError(f"associator must be 'gnn' or 'jpda', got {associator!r}")
    v = float(settings.speed_sigma_mps) ** 2
    init = MultiMeasurementInitiator(
        prior_state=GaussianState(StateVector([0.0, 0.0, 0.0, 0.0]), np.diag([0.0, v, 0.0, v])),
        deleter=UpdateTimeDeleter(datetime.timedelta(seconds=(holding_misses + 0.5) * period)),
        data_associator=_NearbyGNN(DistanceHypothesiser(predictor, updater, Mahalanobis(),
                                                        missed_distance=gate_sigmas),
                                   gate_sigmas=gate_sigmas),
        updater=updater, min_points=min_points)
    deleter = UpdateTimeDeleter(datetime.timedelta(seconds=(max_misses + 0.5) * period))
    tracker = tracker_cls(initiator=init, deleter=deleter, detector=_Scans(scans=scans),
                          data_associator=assoc, updater=updater)
    ids: dict = {}
    rows = {"track_id": [], "event": [], "x": [], "y": []}
    for k, (_, tracks) in enumerate(tracker):
        if k + 1 < len(events) and events[k + 1] == events[k]:
            continue                                   # not the ping's last receiver yet
        for tr in tracks:
            s = tr.state.state_vector
            rows["track_id"].append(ids.setdefault(tr.id, len(ids)))
            rows["event"].append(events[k])
            rows["x"].append(float(s[0, 0]))
            rows["y"].append(float(s[2, 0]))
    out = {k: np.asarray(v) for k, v in rows.items()}
    out["track_id"] = out["track_id"].astype(np.int64)
    out["event"] = out["event"].astype(np.int64)
    out["status"] = np.full(len(out["x"]), "confirmed")
    return out
