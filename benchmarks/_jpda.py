"""Stone Soup's JPDA tracker on unlabelled bearings: the external baseline of the association
ablation (issue 18).

A constant-rate Kalman filter per track on (bearing, bearing rate) with the bearing innovation
wrapped (Stone Soup's ``Bearing`` type in the detections), joint probabilistic data
association (``JPDA`` with a ``PDAHypothesiser``: clutter density and detection probability),
Gaussian-mixture reduction per scan (``MultiTargetMixtureTracker``), tracks started by a
``MultiMeasurementInitiator`` (global nearest neighbour over ``n_confirm`` scans) and deleted
after ``max_misses`` scans without an update. Settings: the same fitted ones as the factor-graph
smoother's. Each detection is labelled with the track that gave it the largest association
probability, when that is at least one half.
"""

from __future__ import annotations

import datetime

import numpy as np
from stonesoup.base import Property
from stonesoup.buffered_generator import BufferedGenerator
from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
from stonesoup.dataassociator.probability import JPDA
from stonesoup.deleter.time import UpdateTimeStepsDeleter
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
from stonesoup.reader.base import DetectionReader
from stonesoup.tracker.simple import MultiTargetMixtureTracker
from stonesoup.types.angle import Bearing
from stonesoup.types.array import StateVector
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState
from stonesoup.updater.kalman import KalmanUpdater

T0 = datetime.datetime(2000, 1, 1)


class _Scans(DetectionReader):
    scans: list = Property(doc="(time, set of Detection) per scan")

    @property
    def detections(self):
        return self._dets

    @BufferedGenerator.generator_method
    def detections_gen(self):
        for tm, dets in self.scans:
            self._dets = dets
            yield tm, dets


def run_jpda(t, z, *, sigma: float, q: float, p_detect: float, clutter_density: float,
             init_sigma_rate: float, max_misses: int, n_confirm: int = 3, gate: float = 4.0):
    """Labels (-1 none) and per-track (times, bearings) of Stone Soup's JPDA tracker."""
    mm = LinearGaussian(ndim_state=2, mapping=(0,), noise_covar=np.array([[sigma**2]]))
    tm = CombinedLinearGaussianTransitionModel([ConstantVelocity(q)])
    predictor, updater = KalmanPredictor(tm), KalmanUpdater(mm)
    hyp = PDAHypothesiser(predictor=predictor, updater=updater,
                          clutter_spatial_density=clutter_density, prob_detect=p_detect)
    deleter = UpdateTimeStepsDeleter(time_steps_since_update=max_misses)
    init = MultiMeasurementInitiator(
        prior_state=GaussianState(StateVector([0.0, 0.0]),
                                  np.diag([np.pi**2, init_sigma_rate**2])),
        measurement_model=mm, deleter=UpdateTimeStepsDeleter(time_steps_since_update=2),
        data_associator=GNNWith2DAssignment(DistanceHypothesiser(
            predictor, updater, Mahalanobis(), missed_distance=gate)),
        updater=updater, min_points=n_confirm)
    index: dict[int, int] = {}
    scans = []
    for tk in np.unique(t):
        dets = set()
        for j in np.flatnonzero(t == tk):
            d = Detection(StateVector([Bearing(z[j])]), timestamp=T0 + datetime.timedelta(
                seconds=float(tk)), measurement_model=mm)
            index[id(d)] = int(j)
            dets.add(d)
        scans.append((T0 + datetime.timedelta(seconds=float(tk)), dets))
    tracker = MultiTargetMixtureTracker(initiator=init, deleter=deleter,
                                        detector=_Scans(scans=scans),
                                        data_associator=JPDA(hypothesiser=hyp), updater=updater)
    every = set()
    for _, tracks in tracker:
        every |= tracks
    prob = np.zeros(t.size)
    labels = np.full(t.size, -1, np.int64)
    out = {}
    for m, track in enumerate(sorted(every, key=lambda tr: tr.states[0].timestamp)):
        times = np.array([(s.timestamp - T0).total_seconds() for s in track.states])
        out[m] = (times, np.array([float(s.state_vector[0, 0]) for s in track.states]))
        for s in track.states:
            hs = getattr(s, "hypothesis", None)
            hs = [] if hs is None else (list(hs) if hasattr(hs, "__iter__") else [hs])
            for h in hs:
                meas = getattr(h, "measurement", None)
                j = index.get(id(meas)) if meas is not None else None
                p = float(getattr(h, "probability", 1.0))
                if j is not None and p > prob[j] and p >= 0.5:
                    prob[j], labels[j] = p, m
    return labels, out
