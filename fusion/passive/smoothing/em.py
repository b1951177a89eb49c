"""The M-step of the crossing-cluster EM in closed form: shared bearings as a low-rank update.

In a crossing cluster of :class:`~fusion.passive.smoothing.multitrack.MultiTrackSmoother`, each
member track's graph holds its own (hard) bearings, the motion factors, a prior and the cluster's
shared bearings ``z_j`` weighted by ``w_j`` (a bearing factor of ``sigma / sqrt(w_j)``). With the
Gaussian loss the graph is linear apart from the wrap, and only the weights change from one EM
iteration to the next. The E-step needs the track's bearings at the shared detections only.

:class:`SharedBearingPosterior` solves the member's graph once without the cluster's shared
bearings (GTSAM, QR along the chain) and keeps, at the shared detections' states, its bearings
``theta_0`` and their joint covariance ``S`` (:func:`~fusion.passive.smoothing.graph.
_chain_bearing_covariance`). Adding the shared bearings back is Gaussian conditioning:

.. math::

    \\theta(w) = \\theta_0 + S D^{1/2} (I + D^{1/2} S D^{1/2})^{-1} D^{1/2} (z' - \\theta_0),
    \\quad D = \\operatorname{diag}(w_j / \\sigma^2),

``z'`` each bearing on the branch nearest ``theta_0``: the minimum of the member's graph with
the weights ``w``, at the shared detections, in a few small dense operations instead of a new
graph per iteration (``I + D^{1/2} S D^{1/2}`` is at least the identity, so the solve is
well-conditioned for any weights, zero included). When the weights have settled, the member's
states over its whole span follow from the same factorisation (:meth:`SharedBearingPosterior.
states_at`).
"""

from __future__ import annotations

import gtsam
import numpy as np
from numpy.typing import NDArray

from factors.angles import nearest_branch
from fusion.passive.smoothing.graph import (
    _chain_bearing_covariance,
    _Measurements,
    _Model,
    _optimize,
)
from fusion.passive.smoothing.types import TrackPrior

__all__ = ["SharedBearingPosterior"]

FloatArray = NDArray[np.float64]


class SharedBearingPosterior:
    """A member track's bearings at its shared detections as a function of their weights.

    Parameters
    ----------
    times : ndarray, shape (n,)
        State times of the member's graph, s.
    meas : _Measurements
        Its bearings: hard ones (weight index -1) and weighted ones (indices into `weights`).
    prior : TrackPrior
        Prior on its first state.
    model : _Model
        Noise scales (Gaussian loss).
    init : ndarray, shape (n, 2)
        Linearisation point (current estimate).
    weights : ndarray
        Weights of every pair; those of `free` are left out of the solve (they are the
        argument of :meth:`bearings`), the others enter as they are.
    free : ndarray of int, shape (k,)
        Pair indices of the shared detections whose weights EM re-estimates.
    free_state : ndarray of int, shape (k,)
        State index of each of them.
    free_bearing : ndarray, shape (k,)
        Their measured bearings, rad.
    """

    def __init__(self, times: FloatArray, meas: _Measurements, prior: TrackPrior,
                 model: _Model, init: FloatArray, weights: FloatArray,
                 free: NDArray[np.int64], free_state: NDArray[np.int64],
                 free_bearing: FloatArray) -> None:
        base = weights.copy()
        base[free] = 0.0  # weight 0: the factor is left out of the graph
        graph, _, states, bn = _optimize(times, meas, prior, model, "none", base, init)
        self.states = states
        self.theta0 = states[free_state, 0]
        self.cov = _chain_bearing_covariance(graph, times.size, free_state, bn)
        self.z = nearest_branch(free_bearing, self.theta0)
        self.sigma = model.sigma_bearing
        self._bn, self._state = bn, np.asarray(free_state, np.int64)

    def _gain(self, w: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``D^{1/2}`` and ``(I + D^{1/2} S D^{1/2})^{-1} D^{1/2} (z' - theta_0)``."""
        d = np.sqrt(np.clip(w, 0.0, None)) / self.sigma
        m = np.eye(d.size) + d[:, None] * self.cov * d[None, :]
        return d, np.linalg.solve(m, d * (self.z - self.theta0))

    def bearings(self, w: FloatArray) -> FloatArray:
        """Bearings (k,) at the shared detections of the graph minimum with weights `w`, rad."""
        d, u = self._gain(w)
        return self.theta0 + self.cov @ (d * u)

    def states_at(self, w: FloatArray) -> FloatArray:
        """All states (n, 2) of the graph minimum with weights `w`.

        The shared bearings add ``g = C^T D^{1/2} u`` to the normal equations (``C`` picks the
        bearing of each shared detection's state): the states move by ``(R^T R)^{-1} g``, two
        triangular solves on the QR factor ``R`` of the graph without them.
        """
        d, u = self._gain(w)
        g = np.zeros((self.states.shape[0], 2))
        np.add.at(g[:, 0], self._state, d * u)
        gx = gtsam.VectorValues()
        for k in range(g.shape[0]):
            gx.insert(k, g[k])
        dx = self._bn.backSubstitute(self._bn.backSubstituteTranspose(gx))
        return self.states + np.array([dx.at(k) for k in range(g.shape[0])])
