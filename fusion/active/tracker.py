"""Multistatic active tracker: Kalman prediction, fuzzy association, M-of-N track management.

Implements the tracker of "Target tracking using fuzzy logic association" (Section 3, "Tracker
overview"; Section 2.5, "Tracker"; Section 7, "Results"):

1. *Kalman stage* (Section 3). Every track is a constant-velocity Kalman filter with state
   ``[x, y, vx, vy]`` (m, m/s) and white-noise acceleration; its prediction to the ping time gives,
   for every (track, detection) pair, the innovation ``nu`` (m), its covariance ``S`` (m^2), the
   squared Mahalanobis distance ``d2 = nu^T S^-1 nu``, the Gaussian likelihood ``N(nu; 0, S)``
   and the likelihood ratio to its peak ``L = exp(-d2 / 2)`` (the fuzzy input "likelihood").
   Pairs with ``d2`` above the chi-square gate (2 degrees of freedom) are not candidates.
   ``S = H P H^T + R`` uses each detection's own position covariance ``R``
   (:func:`bistatic_covariance`, see below).
2. *Fuzzy stage* (Sections 3-6). For gated pairs the rule base ranks each detection from ``L``
   and the clues present in the data (classifier score, SNR, equivalent aspect angle, distance to
   the nearest clutter-map hotspot); rules whose inputs are absent are left out. Each track takes
   its highest-ranked detection; conflicts (two tracks wanting one detection) are resolved by an
   assignment that maximises the summed rank (:func:`scipy.optimize.linear_sum_assignment`). A
   pair ranked below the rank threshold is never associated (Section 7: clutter tracks did not
   form because "the ranks were all too low"). The threshold is read off the rule base for the
   clues the pair actually has (:func:`derived_min_rank`): the rank of a detection at the edge
   of the acceptance region, likelihood ratio ``L = 0.25`` (Mahalanobis ``d2`` = 2.77, inside
   which a true detection falls with probability 0.75), with every other present clue at its
   neutral (crossover) value. So positions-only data are held to the likelihood rules' own
   standard, not to a threshold calibrated with every clue.
3. *Track management* (Section 2.5). A detection that no track takes, that lies in no track's
   gate and is not near a hotspot starts a tentative track; a tentative (potential) track that
   comes within the same distance of a hotspot region is dropped, since it is the hotspot,
   unless its own detections show that it moves (:func:`motion_statistic`: a hotspot stands
   still, a submarine does not); a tentative track is confirmed once it
   has ``confirm_hits`` hits within its first ``confirm_window`` pings (the paper's tracks are "at
   least three detections long") and deleted when that can no longer happen; a confirmed track is
   deleted after ``max_misses`` consecutive misses. In fuzzy mode a track whose own detections
   do not move (the same motion test) is not confirmed but held tentative: a feature echoes
   from one place, and the clutter map may not have flagged it yet when a track on it reaches
   its third hit (see "Choices" below).

``mode="kalman"`` is the paper's comparison tracker: nearest neighbour on the likelihood alone
(pairs inside the gate, highest ``L`` wins, same assignment and track management), no clutter map.

Choices where the paper is silent
---------------------------------
- Position error of a detection. An active-sonar position comes from a bistatic range sum and
  a receiver bearing, so its error is an ellipse whose size and orientation follow the geometry
  (long across the line of sight of a far receiver, where the bearing error dominates; long
  along it when the bistatic angle is wide). When the data give ``src_x, src_y, rcv_x, rcv_y``,
  each detection's 2 x 2 covariance is propagated to first order from the sensor accuracies
  ``range_sum_sigma_m`` (default 30 m) and ``bearing_sigma_deg`` (default 1 deg)
  (:func:`bistatic_covariance`); it is used in the Kalman update, likelihood and gate, as a new
  track's position covariance, in the clutter map (the smallest extent of a hotspot is the mean
  covariance of its detections) and in the motion test. Without those columns (e.g. radar),
  for detections where the propagation is undefined (on the source-receiver baseline), or with
  ``position_errors="isotropic"``, the error is ``position_sigma_m`` per axis.
- Conflicts: confirmed tracks are assigned first, tentative tracks then share the remaining
  detections, so a fresh clutter track cannot take a confirmed track's detection.
- The detections of one event are treated as simultaneous, at the time of the event's first row.
- Equivalent aspect angle when the data give source and receiver positions but no ``aspect_deg``
  (see :func:`equivalent_aspect_deg`): the angle between the track heading and the bistatic
  bisector at the detection; it is left out for tracks whose speed is not larger than its own
  standard deviation (heading unknown, e.g. a track born on the previous ping).
- Motion test of a tentative track near a hotspot: the generalised least-squares velocity of
  its own associated detections (constant velocity, no process noise, each detection with its
  own position covariance) against zero, chi-square with 2 degrees of freedom at
  ``motion_probability`` (default 0.999), from its third detection on. The Kalman velocity is
  not used for this: its covariance carries the process noise and stays too wide for a slow
  target to ever look significant. A slow target seen by several receivers piles its echoes
  into one clutter-map neighbourhood on its first pings and looks like a hotspot there; the test
  keeps its track alive once it has moved significantly. The high confidence (0.999) dates from
  isotropic errors, when far-geometry hotspot echoes scattered by more than ``position_sigma_m``
  and inflated the statistic of a stationary track; with geometric errors 0.99 was tried and
  confirmed more false tracks on the validation seeds, so 0.999 stays.
- Confirmation of stationary tracks. The clutter map flags a feature once a 3 x 3 cell
  neighbourhood has been visited on ``min_pings`` (3) pings; a feature seen by one or two
  receivers in far geometry scatters its echoes over more than one neighbourhood (bearing
  errors of ~170 m per axis against 150-m cells) or skips a ping (it echoes on 70 % of them),
  so it often becomes a hotspot one or two pings after a 3-of-4 track on it is confirmed (on
  its third ping), too late for the hotspot drop, which only ends tentative tracks. On
  validation seeds 200-299 these were 25 of the 51 confirmed false tracks. The track's own
  detections are the same evidence the map looks for (echoes from one place on most pings), so
  on the ping that would confirm it a track must also pass the motion test (as above, at
  ``motion_probability``); if it does not, it stays tentative, is confirmed on a later hit that
  makes it move, is dropped once the map flags the feature, and is deleted after
  ``max_misses`` consecutive misses, like a confirmed track. A slow sonar target is held only
  until it has moved significantly. With a fast update rate and small position errors (the
  Autoferry radar: scans seconds apart, 10-m errors) slow boats take many scans to move
  significantly and are held that long, which costs coverage there (see RESULTS).
  ``hold_stationary=False`` restores confirmation on hits alone.
- Missing event numbers (pings without any detection) are stepped through as empty pings at
  interpolated times, so that they count as misses.
- Every ping is one vectorised pass: the Kalman statistics of all (track, detection) pairs at
  once (closed-form 2 x 2 inverses), then ONE call of the fuzzy system on the gated pairs only
  (two when the aspect angle is computed from geometry and unknown for some tracks, as the
  engine takes no missing values).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from fusion.active.clutter import ClutterMap
from fusion.io import Table

__all__ = [
    "CLUE_NAMES",
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

#: Clue inputs of the fuzzy rule base besides the likelihood.
CLUE_NAMES: tuple[str, ...] = ("score", "snr_db", "aspect_deg", "hotspot_distance_m")

_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
#: Detections a tentative track needs before its motion test may clear it of a hotspot (with
#: two, the least-squares velocity has no residual and one bad association decides).
_MOTION_MIN_DETECTIONS = 3


# ------------------------------------------------------------------------------------------
# Kalman filter, vectorised over tracks
# ------------------------------------------------------------------------------------------
def cv_model(dt: float, accel_psd: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Constant-velocity transition and process noise for state ``[x, y, vx, vy]``.

    Parameters
    ----------
    dt : float
        Time step, s (>= 0).
    accel_psd : float
        Power spectral density ``q`` of the white acceleration noise, m^2/s^3.

    Returns
    -------
    F : ndarray, shape (4, 4)
        ``[[I, dt I], [0, I]]``.
    Q : ndarray, shape (4, 4)
        ``q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]]`` (continuous white-noise acceleration).
    """
    if not np.isfinite(dt) or dt < 0:
        raise ValueError(f"time step must be >= 0, got {dt!r}")
    eye = np.eye(2)
    F = np.block([[eye, dt * eye], [np.zeros((2, 2)), eye]])
    Q = accel_psd * np.block([[dt**3 / 3 * eye, dt**2 / 2 * eye], [dt**2 / 2 * eye, dt * eye]])
    return F, Q


def kf_predict(
    x: NDArray[np.float64], P: NDArray[np.float64], F: NDArray[np.float64], Q: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Kalman prediction of many tracks at once.

    Parameters
    ----------
    x : ndarray, shape (n, 4)
        States.
    P : ndarray, shape (n, 4, 4)
        Covariances.
    F, Q : ndarray, shape (4, 4)
        Transition and process noise.

    Returns
    -------
    x, P : ndarray, shapes (n, 4), (n, 4, 4)
        ``x <- F x``, ``P <- F P F^T + Q`` (new arrays).
    """
    return x @ F.T, F @ P @ F.T + Q


def kf_update(
    x: NDArray[np.float64], P: NDArray[np.float64], z: NDArray[np.float64], R: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Kalman update of many tracks, each with one position measurement.

    Parameters
    ----------
    x : ndarray, shape (n, 4)
        Predicted states.
    P : ndarray, shape (n, 4, 4)
        Predicted covariances.
    z : ndarray, shape (n, 2)
        Measured positions, m.
    R : ndarray, shape (2, 2) or (n, 2, 2)
        Measurement covariance, m^2.

    Returns
    -------
    x, P : ndarray, shapes (n, 4), (n, 4, 4)
        Posterior; the covariance in Joseph form ``(I - K H) P (I - K H)^T + K R K^T``.
    """
    S = P[:, :2, :2] + R                                   # S = H P H^T + R
    PHt = P[:, :, :2]                                      # P H^T
    K = np.linalg.solve(S, np.swapaxes(PHt, 1, 2)).swapaxes(1, 2)  # K = P H^T S^-1 (S symmetric)
    nu = z - x[:, :2]                                      # innovation z - H x
    x_new = x + np.einsum("nij,nj->ni", K, nu)
    I_KH = np.eye(4) - K @ _H
    P_new = I_KH @ P @ np.swapaxes(I_KH, 1, 2) + K @ np.broadcast_to(R, S.shape) @ np.swapaxes(K, 1, 2)
    return x_new, 0.5 * (P_new + np.swapaxes(P_new, 1, 2))


@dataclass(frozen=True)
class PairStatistics:
    """Kalman statistics of every (track, detection) pair.

    Attributes
    ----------
    d2 : ndarray, shape (n_tracks, n_detections)
        Squared Mahalanobis distance of the innovation.
    det : ndarray, shape (n_tracks, n_detections)
        Determinant of the innovation covariance ``S`` of each pair, m^4.

    Notes
    -----
    :attr:`log_pdf` and :attr:`likelihood_ratio` are computed on access (a ping needs the
    likelihood ratio of the gated pairs only).
    """

    d2: NDArray[np.float64]
    det: NDArray[np.float64]

    @property
    def log_pdf(self) -> NDArray[np.float64]:
        """Log of the Gaussian likelihood ``N(z; H x, S)`` (z in m, density in 1/m^2)."""
        return -0.5 * self.d2 - np.log(2 * np.pi) - 0.5 * np.log(self.det)

    @property
    def likelihood_ratio(self) -> NDArray[np.float64]:
        """``L = exp(-d2 / 2)`` in (0, 1], the rule base's "likelihood"."""
        return np.exp(-0.5 * self.d2)


def pair_statistics(
    x: NDArray[np.float64], P: NDArray[np.float64], z: NDArray[np.float64], R: NDArray[np.float64]
) -> PairStatistics:
    """Innovation statistics of every track against every detection.

    Parameters
    ----------
    x : ndarray, shape (n_tracks, 4)
        Predicted states.
    P : ndarray, shape (n_tracks, 4, 4)
        Predicted covariances.
    z : ndarray, shape (n_detections, 2)
        Detection positions, m.
    R : ndarray, shape (2, 2) or (n_detections, 2, 2)
        Measurement covariance, m^2: one for all detections or one per detection (e.g.
        :func:`bistatic_covariance`).

    Returns
    -------
    PairStatistics
        With ``S = H P_t H^T + R_d`` per pair.
    """
    Rd = np.broadcast_to(np.asarray(R, dtype=float), (z.shape[0], 2, 2))
    # S per pair (closed-form 2 x 2 inverse): a, b, c of shape (n_tracks, n_detections).
    a = P[:, None, 0, 0] + Rd[None, :, 0, 0]
    b = P[:, None, 0, 1] + Rd[None, :, 0, 1]
    c = P[:, None, 1, 1] + Rd[None, :, 1, 1]
    det = a * c - b * b
    dx = z[None, :, 0] - x[:, None, 0]                     # (nt, nd)
    dy = z[None, :, 1] - x[:, None, 1]
    d2 = (c * dx * dx - 2.0 * b * dx * dy + a * dy * dy) / det
    return PairStatistics(d2, det)


def gate_threshold(probability: float, *, dof: int = 2) -> float:
    """Chi-square gate on ``d2`` that keeps a true detection with the given probability."""
    if not 0.0 < probability < 1.0:
        raise ValueError(f"gate probability must lie in (0, 1), got {probability!r}")
    return float(chi2.ppf(probability, dof))


def bistatic_covariance(
    xy: ArrayLike,
    source: ArrayLike,
    receiver: ArrayLike,
    range_sum_sigma_m: float,
    bearing_sigma_deg: float,
) -> NDArray[np.float64]:
    """Position covariance of bistatic echoes, by first-order propagation of the sensor errors.

    A bistatic position ``p`` (:func:`fusion.simulate.multistatic.bistatic_position`) is the
    point of the ellipse with foci ``s`` (source) and ``r`` (receiver) and range sum
    ``rho = |p - s| + |p - r|`` on the bearing line ``theta`` from the receiver. With
    ``u = (sin theta, cos theta)`` the unit vector from the receiver to the echo,
    ``u' = du/dtheta = (cos theta, -sin theta)``, ``e`` the unit vector from the source to the
    echo, ``d = |p - r|`` and ``k = 1 + e . u`` (``2 cos^2`` of half the bistatic angle),
    differentiating ``|r + d u - s| + d = rho`` gives the Jacobian columns

    - ``dp/drho = u / k`` (along the receiver's line of sight, long when the bistatic angle is
      wide),
    - ``dp/dtheta = d (u' - u (e . u') / k)`` (across it, growing with the receiver range),

    and the covariance ``J diag(sigma_rho^2, sigma_theta^2) J^T``.

    Parameters
    ----------
    xy : array_like, shape (n, 2)
        Echo positions (x east, y north), m: the Jacobian is evaluated there.
    source, receiver : array_like, shape (n, 2) or (2,)
        Source and receiver positions, m.
    range_sum_sigma_m : float
        Standard deviation of the bistatic range sum, m (>= 0).
    bearing_sigma_deg : float
        Standard deviation of the bearing at the receiver, degrees (>= 0).

    Returns
    -------
    ndarray, shape (n, 2, 2)
        Covariances, m^2. NaN where the echo lies on the source or on the receiver (no
        direction) or where ``k`` < 1e-6 (on the baseline between source and receiver, where
        the range sum says nothing about the position along the baseline).

    Examples
    --------
    Monostatic, echo 1 km north: ``sigma_rho / 2`` in range, ``d sigma_theta`` across.

    >>> c = bistatic_covariance([[0.0, 1000.0]], [0.0, 0.0], [0.0, 0.0], 30.0, 1.0)
    >>> np.sqrt(np.diag(c[0])).round(2).tolist()
    [17.45, 15.0]
    """
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    s = np.broadcast_to(np.asarray(source, dtype=float), p.shape)
    r = np.broadcast_to(np.asarray(receiver, dtype=float), p.shape)
    sig_rho = float(range_sum_sigma_m)
    sig_th = float(np.radians(bearing_sigma_deg))
    with np.errstate(invalid="ignore", divide="ignore"):
        rx, ry = p[:, 0] - r[:, 0], p[:, 1] - r[:, 1]
        sx, sy = p[:, 0] - s[:, 0], p[:, 1] - s[:, 1]
        d = np.hypot(rx, ry)
        ux, uy = rx / d, ry / d                                  # u; du/dtheta = (uy, -ux)
        a = np.hypot(sx, sy)
        ex, ey = sx / a, sy / a
        k = 1.0 + ex * ux + ey * uy
        k[~(k >= 1e-6)] = np.nan
        jrx, jry = sig_rho * ux / k, sig_rho * uy / k            # sigma_rho dp/drho
        w = (ex * uy - ey * ux) / k                              # (e . u') / k
        jtx, jty = sig_th * d * (uy - ux * w), sig_th * d * (-ux - uy * w)
    out = np.empty((p.shape[0], 2, 2))
    out[:, 0, 0] = jrx * jrx + jtx * jtx
    out[:, 0, 1] = out[:, 1, 0] = jrx * jry + jtx * jty
    out[:, 1, 1] = jry * jry + jty * jty
    return out


def motion_statistic(
    times: ArrayLike, xy: ArrayLike, sigma_m: float | None = None, *, cov: ArrayLike | None = None
) -> float:
    """Chi-square statistic of "the detections move": least-squares velocity against zero.

    Parameters
    ----------
    times : array_like, shape (k,)
        Detection times, s.
    xy : array_like, shape (k, 2)
        Detection positions, m.
    sigma_m : float, optional
        Position error per axis, the same for every detection, m (> 0).
    cov : array_like, shape (k, 2, 2), optional
        Position covariance of each detection, m^2 (instead of ``sigma_m``), e.g. from
        :func:`bistatic_covariance`.

    Returns
    -------
    float
        ``v^T Cov(v)^-1 v`` for the generalised least-squares fit ``p_i = p_0 + v t_i + e_i``,
        ``e_i ~ N(0, C_i)``: chi-square with 2 degrees of freedom for a stationary object.
        With one ``sigma_m`` for all, ``|v|^2 S_tt / sigma^2`` with
        ``v = sum (t - t_mean)(p - p_mean) / S_tt`` and ``S_tt = sum (t - t_mean)^2``.
        0 when all times are equal.

    Examples
    --------
    >>> round(motion_statistic([0.0, 90.0, 180.0], [[0, 0], [180, 0], [360, 0]], 100.0), 2)
    6.48
    """
    if (sigma_m is None) == (cov is None):
        raise ValueError("give exactly one of sigma_m and cov")
    t = np.asarray(times, dtype=float)
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    tt = t - t.mean()
    stt = float(tt @ tt)
    if stt <= 0.0:
        return 0.0
    if cov is None:
        v = tt @ (p - p.mean(axis=0)) / stt
        return float(v @ v) * stt / float(sigma_m) ** 2
    # Generalised least squares for theta = (p_0, v) with weights W_i = C_i^-1 (times centred).
    W = np.linalg.inv(np.asarray(cov, dtype=float).reshape(-1, 2, 2))
    A = np.empty((4, 4))
    A[:2, :2] = W.sum(axis=0)
    A[:2, 2:] = A[2:, :2] = np.einsum("i,ijk->jk", tt, W)
    A[2:, 2:] = np.einsum("i,ijk->jk", tt * tt, W)
    Wp = np.einsum("ijk,ik->ij", W, p)
    b = np.concatenate([Wp.sum(axis=0), tt @ Wp])
    try:
        theta = np.linalg.solve(A, b)
        cov_v = np.linalg.inv(A)[2:, 2:]
        return float(theta[2:] @ np.linalg.solve(cov_v, theta[2:]))
    except np.linalg.LinAlgError:
        return 0.0


# ------------------------------------------------------------------------------------------
# association
# ------------------------------------------------------------------------------------------
def assign(
    score: ArrayLike, valid: ArrayLike
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Pair rows with columns, at most once each, maximising the summed score of valid pairs.

    Parameters
    ----------
    score : array_like, shape (n_rows, n_cols)
        Pair scores (ranks or likelihood ratios), >= 0 where valid.
    valid : array_like of bool, shape (n_rows, n_cols)
        Pairs allowed.

    Returns
    -------
    rows, cols : ndarray of int
        The chosen pairs. When each row's best valid column is different, this is every row with
        its best column; otherwise the conflicts are settled by
        :func:`scipy.optimize.linear_sum_assignment`.
    """
    s = np.asarray(score, dtype=float)
    ok = np.asarray(valid, dtype=bool)
    if s.shape != ok.shape or s.ndim != 2:
        raise ValueError(f"score and valid must be 2-D of one shape, got {s.shape}, {ok.shape}")
    if s.size == 0 or not ok.any():
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    if np.any(s[ok] < 0):
        raise ValueError("scores of valid pairs must be >= 0")
    w = np.where(ok, s, -1.0)
    best = w.argmax(axis=1)
    has = ok[np.arange(s.shape[0]), best]
    if np.unique(best[has]).size == has.sum():       # no conflict: each row takes its best
        rows = np.flatnonzero(has)
        return rows.astype(np.int64), best[has].astype(np.int64)
    # Maximum-weight matching: invalid pairs weigh 0 and are dropped afterwards.
    r, c = linear_sum_assignment(np.where(ok, s, 0.0), maximize=True)
    keep = ok[r, c]
    return r[keep].astype(np.int64), c[keep].astype(np.int64)


def equivalent_aspect_deg(
    position: ArrayLike, velocity: ArrayLike, source: ArrayLike, receiver: ArrayLike
) -> NDArray[np.float64]:
    """Equivalent (bistatic) aspect angle of an echo, degrees in [0, 180].

    Parameters
    ----------
    position : array_like, shape (..., 2)
        Echo (target) position, m.
    velocity : array_like, shape (..., 2)
        Target velocity, m/s (only its direction matters).
    source, receiver : array_like, shape (..., 2)
        Source and receiver positions, m.

    Returns
    -------
    ndarray, shape (...)
        ``arccos(h . b)`` in degrees, with ``h`` the unit heading and ``b`` the unit bisector of
        the unit vectors from the target to the source and to the receiver: 0 = bow-on,
        90 = beam-on (specular for a hull), 180 = stern-on. NaN where the velocity is zero or the
        bisector vanishes (target on the source-receiver baseline).

    Notes
    -----
    A bistatic echo behaves like a monostatic one seen along the bisector of the angle
    source-target-receiver, so the equivalent aspect is the aspect of that bisector.

    Examples
    --------
    >>> float(equivalent_aspect_deg([0, 0], [0, 3], [5000, 0], [4000, 100]).round(1))
    89.3
    """
    p = np.asarray(position, dtype=float)
    v = np.asarray(velocity, dtype=float)
    us = np.asarray(source, dtype=float) - p
    ur = np.asarray(receiver, dtype=float) - p
    with np.errstate(invalid="ignore", divide="ignore"):
        us = us / np.linalg.norm(us, axis=-1, keepdims=True)
        ur = ur / np.linalg.norm(ur, axis=-1, keepdims=True)
        b = us + ur
        b = b / np.linalg.norm(b, axis=-1, keepdims=True)
        h = v / np.linalg.norm(v, axis=-1, keepdims=True)
        cos = np.clip(np.sum(h * b, axis=-1), -1.0, 1.0)
    return np.degrees(np.arccos(cos))


# ------------------------------------------------------------------------------------------
# rank threshold from the rule base
# ------------------------------------------------------------------------------------------
#: Likelihood ratio at the edge of the acceptance region (the crossover of the default
#: "unlikely" set, which falls from 1 at L = 0.1 to 0 at L = 0.4): a true detection has a
#: larger L with probability 0.75 (L is uniform on (0, 1] for true detections).
EDGE_LIKELIHOOD: float = 0.25


def neutral_value(variable: object) -> float:
    """Value of an input variable at which its terms say the least: its crossover point.

    Parameters
    ----------
    variable : LinguisticVariable
        A fuzzy input variable (``name``, ``universe``, ``terms``).

    Returns
    -------
    float
        The point of the universe where the largest ``|mu_t(x) - 0.5|`` over the variable's
        terms is smallest (for two complementary terms, where both are 1/2; for a single term,
        where it is 1/2); the smallest such point on ties. Candidates are a 2001-point grid of
        the universe and every point where a piecewise-linear term crosses 1/2.

    Examples
    --------
    >>> from fusion.active.rulebase import default_variables
    >>> [neutral_value(v) for v in default_variables()[1:]]
    [0.65, 70.0, 16.0, 300.0]
    """
    low, high = (float(v) for v in variable.universe)  # type: ignore[attr-defined]
    terms = list(variable.terms.values())  # type: ignore[attr-defined]
    cands = [np.linspace(low, high, 2001)]
    for mf in terms:
        kn = mf.knots()
        if kn is None:
            continue
        xs, ys = kn[0], kn[1]
        for x0, x1, y0, y1 in zip(xs[:-1], xs[1:], ys[:-1], ys[1:], strict=True):
            if x1 > x0 and (y0 - 0.5) * (y1 - 0.5) <= 0 and y0 != y1:
                cands.append(np.array([x0 + (0.5 - y0) * (x1 - x0) / (y1 - y0)]))
    x = np.unique(np.concatenate(cands))
    x = x[(x >= low) & (x <= high)]
    dev = np.max(np.abs(np.stack([mf(x) for mf in terms]) - 0.5), axis=0)
    return float(x[np.flatnonzero(dev <= dev.min() + 1e-12)[0]])


def derived_min_rank(
    system: object, present: Iterable[str], *, edge_likelihood: float = EDGE_LIKELIHOOD
) -> float:
    """Lowest acceptable rank for a clue set, read off the rule base.

    The rank the system gives a detection at the edge of the acceptance region (likelihood
    ratio ``edge_likelihood``) when every other input present is at its neutral value
    (:func:`neutral_value`: no evidence either way). A pair is associated when its rank is at
    least this value: with neutral clues exactly the pairs with ``L >= edge_likelihood``;
    favourable clues admit pairs further out (up to the chi-square gate), unfavourable ones
    refuse pairs closer in.

    Parameters
    ----------
    system : FuzzySystem
        The rule base; must have an input ``likelihood``.
    present : iterable of str
        Inputs given to the system besides ``likelihood`` (names not in the system are
        ignored).
    edge_likelihood : float, optional
        ``L = exp(-d2 / 2)`` at the edge, in (0, 1] (default :data:`EDGE_LIKELIHOOD`, 0.25:
        ``d2`` = 2.77, inside which a true detection falls with probability 0.75).

    Returns
    -------
    float
        The rank, in the output universe.

    Examples
    --------
    >>> from fusion.active.rulebase import default_association_system
    >>> system = default_association_system()
    >>> round(derived_min_rank(system, []), 4)
    0.4405
    """
    if not 0.0 < edge_likelihood <= 1.0:
        raise ValueError(f"edge_likelihood must lie in (0, 1], got {edge_likelihood!r}")
    by_name = {v.name: v for v in system.variables}  # type: ignore[attr-defined]
    if "likelihood" not in by_name:
        raise ValueError("the fuzzy system has no input 'likelihood'")
    inputs = {"likelihood": np.array([float(edge_likelihood)])}
    for name in present:
        if name in by_name and name != "likelihood":
            inputs[name] = np.array([neutral_value(by_name[name])])
    return float(system.evaluate(inputs).crisp[0])  # type: ignore[attr-defined]


# ------------------------------------------------------------------------------------------
# track management
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Lifecycle:
    """Track-management counters of one track.

    Attributes
    ----------
    status : {"tentative", "confirmed", "deleted"}
    age : int
        Pings since birth, the birth ping included.
    hits : int
        Pings with an associated detection, the birth ping included.
    misses : int
        Consecutive misses (counted once confirmed).
    """

    status: str = "tentative"
    age: int = 1
    hits: int = 1
    misses: int = 0


def advance_status(state: Lifecycle, hit: bool, *, m: int, n: int, max_misses: int) -> Lifecycle:
    """One ping of M-of-N confirmation and miss-count deletion.

    Parameters
    ----------
    state : Lifecycle
        Counters before the ping.
    hit : bool
        Whether the track got a detection on this ping.
    m, n : int
        Confirm once ``m`` hits are reached within the first ``n`` pings of the track; delete a
        tentative track when that can no longer happen.
    max_misses : int
        Delete a confirmed track after this many consecutive misses.

    Returns
    -------
    Lifecycle
    """
    if state.status == "deleted":
        return state
    age, hits = state.age + 1, state.hits + int(hit)
    if state.status == "tentative":
        if hits >= m:
            return Lifecycle("confirmed", age, hits, 0)
        if hits + (n - age) < m:
            return Lifecycle("deleted", age, hits, 0)
        return Lifecycle("tentative", age, hits, 0)
    misses = 0 if hit else state.misses + 1
    return Lifecycle("deleted" if misses >= max_misses else "confirmed", age, hits, misses)


def track_status(history: Sequence[bool], *, m: int, n: int, max_misses: int) -> str:
    """Status after a hit/miss history; ``history[0]`` is the birth ping (a hit).

    Examples
    --------
    >>> track_status([True, True, False, True], m=3, n=4, max_misses=3)
    'confirmed'
    >>> track_status([True, False, False], m=3, n=4, max_misses=3)
    'deleted'
    """
    state = Lifecycle()
    for hit in history[1:]:
        state = advance_status(state, bool(hit), m=m, n=n, max_misses=max_misses)
    return state.status


# ------------------------------------------------------------------------------------------
# data
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Ping:
    """The detections of one event (ping or scan).

    Attributes
    ----------
    event : int
        Event index.
    time : float
        Event time, s.
    xy : ndarray, shape (n, 2)
        Detection positions (x east, y north), m.
    clues : dict of str to ndarray, shape (n,)
        Optional per-detection clues among ``snr_db``, ``score``, ``aspect_deg`` and positions
        ``src_x, src_y, rcv_x, rcv_y`` (m).
    """

    event: int
    time: float
    xy: NDArray[np.float64]
    clues: Mapping[str, NDArray[np.float64]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        xy = np.asarray(self.xy, dtype=float).reshape(-1, 2) if np.size(self.xy) else np.zeros((0, 2))
        if not np.all(np.isfinite(xy)) or not np.isfinite(self.time):
            raise ValueError(f"event {self.event}: positions and time must be finite")
        clues = {}
        for k, v in self.clues.items():
            a = np.asarray(v, dtype=float).reshape(-1)
            if a.shape != (xy.shape[0],):
                raise ValueError(f"event {self.event}: clue {k!r} has {a.size} values for "
                                 f"{xy.shape[0]} detections")
            clues[k] = a
        object.__setattr__(self, "xy", xy)
        object.__setattr__(self, "clues", clues)

    @property
    def n(self) -> int:
        """Number of detections."""
        return int(self.xy.shape[0])


_POSITION_CLUES = ("src_x", "src_y", "rcv_x", "rcv_y")
_CLUE_COLUMNS = ("snr_db", "score", "aspect_deg", *_POSITION_CLUES)


def pings_from_table(table: Table) -> list[Ping]:
    """Split a detections table (``event,time,x,y`` + optional clues) into pings.

    Event numbers missing between the first and the last become empty pings at times
    interpolated linearly between their neighbours.

    Returns
    -------
    list of Ping
        One per event from the smallest to the largest event number.
    """
    if len(table) == 0:
        return []
    ev = np.asarray(table["event"]).astype(np.int64)
    order = np.argsort(ev, kind="stable")
    ev = ev[order]
    t = np.asarray(table["time"], dtype=float)[order]
    xy = np.column_stack([table["x"], table["y"]]).astype(float)[order]
    clues = {c: np.asarray(table[c], dtype=float)[order] for c in _CLUE_COLUMNS if c in table}
    uniq, start = np.unique(ev, return_index=True)
    stop = np.append(start[1:], ev.size)
    t_event = t[start]
    all_events = np.arange(uniq[0], uniq[-1] + 1)
    all_times = np.interp(all_events, uniq, t_event)
    by_event = {int(e): (a, b) for e, a, b in zip(uniq, start, stop, strict=True)}
    pings = []
    for e, te in zip(all_events, all_times, strict=True):
        a, b = by_event.get(int(e), (0, 0))
        pings.append(Ping(int(e), float(te), xy[a:b], {k: v[a:b] for k, v in clues.items()}))
    return pings


@dataclass(frozen=True)
class PingResult:
    """Tracks after one ping.

    Attributes
    ----------
    event : int
    time : float
        s.
    track_id : ndarray of int, shape (k,)
        Tracks alive before or born on this ping (deleted ones included once, with their last
        state).
    state : ndarray, shape (k, 4)
        ``x, y, vx, vy`` (m, m/s): posterior, or prediction for a track without a detection.
    status : ndarray of str, shape (k,)
        ``tentative``, ``confirmed`` or ``deleted``.
    detection : ndarray of int, shape (k,)
        Index of the associated detection in the ping, -1 when none (the birth detection for
        new tracks).
    rank : ndarray, shape (k,)
        Rank (fuzzy) or likelihood ratio (kalman) of the associated pair; NaN when none.
    hotspots : ndarray, shape (h, 2)
        Clutter-map hotspots after this ping, m (empty in kalman mode).
    """

    event: int
    time: float
    track_id: NDArray[np.int64]
    state: NDArray[np.float64]
    status: NDArray[np.str_]
    detection: NDArray[np.int64]
    rank: NDArray[np.float64]
    hotspots: NDArray[np.float64]


@dataclass(frozen=True)
class TrackingResult:
    """All pings of a run.

    Attributes
    ----------
    pings : tuple of PingResult
    """

    pings: tuple[PingResult, ...]

    def columns(self) -> dict[str, NDArray]:
        """Output rows ``track_id,event,time,x,y,vx,vy,status``, one per track per event."""
        if not self.pings:
            empty = np.zeros(0)
            return {"track_id": empty.astype(np.int64), "event": empty.astype(np.int64),
                    "time": empty, "x": empty, "y": empty, "vx": empty, "vy": empty,
                    "status": np.zeros(0, dtype=str)}
        k = [p.track_id.size for p in self.pings]
        state = np.concatenate([p.state for p in self.pings]).reshape(-1, 4)
        return {
            "track_id": np.concatenate([p.track_id for p in self.pings]).astype(np.int64),
            "event": np.repeat([p.event for p in self.pings], k).astype(np.int64),
            "time": np.repeat([p.time for p in self.pings], k).astype(float),
            "x": state[:, 0], "y": state[:, 1], "vx": state[:, 2], "vy": state[:, 3],
            "status": np.concatenate([p.status for p in self.pings]).astype(str),
        }

    def confirmed_ids(self) -> NDArray[np.int64]:
        """Ids of the tracks that were confirmed at some ping."""
        ids = [p.track_id[p.status == "confirmed"] for p in self.pings]
        return np.unique(np.concatenate(ids)) if ids else np.zeros(0, np.int64)


# ------------------------------------------------------------------------------------------
# the tracker
# ------------------------------------------------------------------------------------------
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
        chosen = set(CLUE_NAMES if clues is None else clues)
        unknown = chosen - set(CLUE_NAMES)
        if unknown:
            raise ValueError(f"unknown clue(s) {', '.join(sorted(unknown))} "
                             f"(choose from {', '.join(CLUE_NAMES)})")
        for name, v in (("position_sigma_m", position_sigma_m), ("speed_sigma_mps", speed_sigma_mps)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive, got {v!r}")
        if position_errors not in ("geometry", "isotropic"):
            raise ValueError("position_errors must be 'geometry' or 'isotropic', got "
                             f"{position_errors!r}")
        for name, v in (("range_sum_sigma_m", range_sum_sigma_m),
                        ("bearing_sigma_deg", bearing_sigma_deg)):
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name} must be >= 0, got {v!r}")
        if range_sum_sigma_m == 0 and bearing_sigma_deg == 0:
            raise ValueError("range_sum_sigma_m and bearing_sigma_deg cannot both be 0")
        if not np.isfinite(accel_psd) or accel_psd < 0:
            raise ValueError(f"accel_psd must be >= 0, got {accel_psd!r}")
        if min_rank is not None and not 0.0 <= min_rank <= 1.0:
            raise ValueError(f"min_rank must lie in [0, 1], got {min_rank!r}")
        if not 0.0 < edge_likelihood <= 1.0:
            raise ValueError(f"edge_likelihood must lie in (0, 1], got {edge_likelihood!r}")
        if not 1 <= confirm_hits <= confirm_window:
            raise ValueError("need 1 <= confirm_hits <= confirm_window, got "
                             f"{confirm_hits} and {confirm_window}")
        if not 0.0 < motion_probability < 1.0:
            raise ValueError(f"motion_probability must lie in (0, 1), got {motion_probability!r}")
        if max_misses < 1:
            raise ValueError(f"max_misses must be >= 1, got {max_misses!r}")
        if mode == "fuzzy" and system is None:
            from fusion.active.rulebase import default_association_system

            system = default_association_system()
        self.mode = mode
        self.system = system
        self.clues = frozenset(chosen)
        self.R = np.eye(2) * position_sigma_m**2
        self.position_errors = position_errors
        self.range_sum_sigma_m = float(range_sum_sigma_m)
        self.bearing_sigma_deg = float(bearing_sigma_deg)
        self.accel_psd = float(accel_psd)
        self.speed_sigma_mps = float(speed_sigma_mps)
        self.gate = gate_threshold(gate_probability)
        self.min_rank = None if min_rank is None else float(min_rank)
        self.edge_likelihood = float(edge_likelihood)
        self._thresholds: dict[frozenset[str], float] = {}
        self._model: tuple[float, NDArray[np.float64], NDArray[np.float64]] | None = None
        self.m, self.n, self.max_misses = int(confirm_hits), int(confirm_window), int(max_misses)
        self.init_exclusion_m = float(init_exclusion_m)
        self.motion_probability = float(motion_probability)
        self.hold_stationary = bool(hold_stationary)
        self._motion_gate = float(chi2.ppf(self.motion_probability, 2))
        if mode == "fuzzy":
            self.clutter_map = (clutter_map if clutter_map is not None
                                else ClutterMap(position_sigma_m=position_sigma_m))
        else:
            self.clutter_map = None
        self.reset()

    def reset(self) -> None:
        """Forget all tracks (and the clutter map's content)."""
        self._ids = np.zeros(0, np.int64)
        self._x = np.zeros((0, 4))
        self._P = np.zeros((0, 4, 4))
        self._life: list[Lifecycle] = []
        # Per track: times and positions of its detections while tentative (motion test).
        self._seen: list[list[tuple[float, float, float]]] = []
        self._next_id = 0
        self._time: float | None = None
        if self.clutter_map is not None:
            self.clutter_map = self.clutter_map.empty_copy()

    # --------------------------------------------------------------------------------------
    def threshold(self, present: Iterable[str]) -> float:
        """Lowest associable rank for pairs whose rank used the inputs ``present``.

        Parameters
        ----------
        present : iterable of str
            Inputs of the rank besides the likelihood.

        Returns
        -------
        float
            ``min_rank`` when given, else :func:`derived_min_rank` (cached per clue set).
        """
        if self.min_rank is not None:
            return self.min_rank
        key = frozenset(present)
        if key not in self._thresholds:
            self._thresholds[key] = derived_min_rank(self.system, key,
                                                     edge_likelihood=self.edge_likelihood)
            logger.info("rank threshold with clues {%s}: %.4f", ", ".join(sorted(key)),
                        self._thresholds[key])
        return self._thresholds[key]

    def measurement_covariances(self, ping: Ping) -> tuple[NDArray[np.float64], bool]:
        """Position covariance of each detection of a ping.

        Parameters
        ----------
        ping : Ping

        Returns
        -------
        R : ndarray, shape (n, 2, 2)
            m^2: :func:`bistatic_covariance` from ``range_sum_sigma_m`` and
            ``bearing_sigma_deg`` for detections with finite source and receiver positions
            (``position_errors="geometry"``); ``position_sigma_m^2 I`` for the others (no
            positions, e.g. radar, an echo on the source-receiver baseline, or
            ``position_errors="isotropic"``).
        geometric : bool
            Whether any detection got a geometry-derived covariance.
        """
        if (self.position_errors != "geometry" or ping.n == 0
                or not all(k in ping.clues for k in _POSITION_CLUES)):
            return np.broadcast_to(self.R, (ping.n, 2, 2)).copy(), False
        src = np.column_stack([ping.clues["src_x"], ping.clues["src_y"]])
        rcv = np.column_stack([ping.clues["rcv_x"], ping.clues["rcv_y"]])
        R = bistatic_covariance(ping.xy, src, rcv, self.range_sum_sigma_m, self.bearing_sigma_deg)
        with np.errstate(invalid="ignore"):
            bad = ~(R[:, 0, 0] * R[:, 1, 1] - R[:, 0, 1] ** 2 > 0)   # NaN or singular
        if bad.all():
            return np.broadcast_to(self.R, (ping.n, 2, 2)).copy(), False
        if bad.any():
            R[bad] = self.R
        return R, True

    def _ranks(
        self, ping: Ping, ti: NDArray[np.int64], di: NDArray[np.int64], L: NDArray[np.float64],
        hot_d: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Fuzzy rank and rank threshold of the gated pairs ``(ti, di)`` (one system call)."""
        inputs: dict[str, NDArray[np.float64]] = {"likelihood": L}
        for name in ("score", "snr_db"):
            if name in self.clues and name in ping.clues:
                inputs[name] = ping.clues[name][di]
        if "hotspot_distance_m" in self.clues:
            inputs["hotspot_distance_m"] = hot_d[di]
        aspect = None
        if "aspect_deg" in self.clues:
            if "aspect_deg" in ping.clues:
                aspect = ping.clues["aspect_deg"][di]
            elif all(k in ping.clues for k in ("src_x", "src_y", "rcv_x", "rcv_y")):
                v = self._x[ti, 2:]
                pv = self._P[ti, 2:, 2:]
                known = np.sum(v * v, axis=1) > pv[:, 0, 0] + pv[:, 1, 1]
                src = np.column_stack([ping.clues["src_x"], ping.clues["src_y"]])[di]
                rcv = np.column_stack([ping.clues["rcv_x"], ping.clues["rcv_y"]])[di]
                aspect = equivalent_aspect_deg(ping.xy[di], v, src, rcv)
                aspect[~known] = np.nan
        others = set(inputs) - {"likelihood"}
        if aspect is None or not np.isnan(aspect).any():
            if aspect is not None:
                inputs["aspect_deg"] = aspect
                others.add("aspect_deg")
            rank = np.asarray(self.system.evaluate(inputs).crisp, dtype=float)
            return rank, np.full(L.size, self.threshold(others))
        # Pairs with and without an aspect angle use different rule subsets (the engine takes
        # no missing values), hence two calls; each gets the threshold of its own clue set.
        rank = np.empty(L.size)
        limit = np.empty(L.size)
        ok = ~np.isnan(aspect)
        for sel, with_aspect in ((ok, True), (~ok, False)):
            if not sel.any():
                continue
            part = {k: v[sel] for k, v in inputs.items()}
            if with_aspect:
                part["aspect_deg"] = aspect[sel]
            rank[sel] = self.system.evaluate(part).crisp
            limit[sel] = self.threshold(others | ({"aspect_deg"} if with_aspect else set()))
        return rank, limit

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
        Rz, geometric = self.measurement_covariances(ping)

        # The clutter map counts this ping too, so a feature echoing on every ping is a hotspot
        # from its min_pings-th ping on, before a track on it can be confirmed.
        if self.clutter_map is not None:
            self.clutter_map.update(ping.xy, ping.time, cov=Rz if geometric else None)
            hot_d = self.clutter_map.distance(ping.xy)
        else:
            hot_d = np.full(nd, np.inf)
        stats = pair_statistics(self._x, self._P, ping.xy, Rz)
        gated = stats.d2 <= self.gate
        # Score only the gated pairs, all tracks and detections at once.
        ti, di = np.nonzero(gated)
        score = np.zeros(gated.shape)
        valid = np.zeros(gated.shape, dtype=bool)
        if ti.size:
            L = np.exp(-0.5 * stats.d2[ti, di])
            if self.mode == "kalman":
                score[ti, di] = L
                valid[ti, di] = True
            else:
                rank, limit = self._ranks(ping, ti, di, L, hot_d)
                score[ti, di] = rank
                valid[ti, di] = rank >= limit

        # Confirmed tracks choose first, tentative tracks share what is left.
        det_of = np.full(nt, -1, np.int64)
        confirmed = np.fromiter((lc.status == "confirmed" for lc in self._life), bool, nt)
        taken = np.zeros(nd, dtype=bool)
        for group in (np.flatnonzero(confirmed), np.flatnonzero(~confirmed)):
            if group.size == 0:
                continue
            r, c = assign(score[group], valid[group] & ~taken[None, :])
            det_of[group[r]] = c
            taken[c] = True

        hit = det_of >= 0
        if hit.any():
            self._x[hit], self._P[hit] = kf_update(self._x[hit], self._P[hit], ping.xy[det_of[hit]],
                                                   Rz[det_of[hit]])
        rank = np.full(nt, np.nan)
        rank[hit] = score[np.flatnonzero(hit), det_of[hit]]
        # Motion-test rows of the detections: time, x, y, R_xx, R_xy, R_yy.
        rows = np.column_stack([np.full(nd, ping.time), ping.xy, Rz[:, 0, 0], Rz[:, 0, 1],
                                Rz[:, 1, 1]]).tolist()
        for i in np.flatnonzero(hit & ~confirmed):
            self._seen[i].append(rows[det_of[i]])
        # A potential (tentative) track inside a hotspot's reach is the hotspot, not a target: it
        # is dropped, as a detection there starts no track (same distance, init_exclusion_m),
        # unless its own detections move significantly (a slow target mistaken for a hotspot).
        on_hot = np.zeros(nt, dtype=bool)
        if self.clutter_map is not None and nt and not confirmed.all():
            on_hot[~confirmed] = (self.clutter_map.distance(self._x[~confirmed, :2])
                                  <= self.init_exclusion_m)
            for i in np.flatnonzero(on_hot):
                seen = np.asarray(self._seen[i])
                if seen.shape[0] < _MOTION_MIN_DETECTIONS:
                    continue
                cov = seen[:, [3, 4, 4, 5]].reshape(-1, 2, 2)
                if motion_statistic(seen[:, 0], seen[:, 1:3], cov=cov) > self._motion_gate:
                    on_hot[i] = False
        # A potential track about to be confirmed whose own detections stand still is held
        # tentative: a feature echoes from one place, a submarine moves. The clutter map may not
        # have flagged the feature yet (its echoes scatter over several cells, or it skipped a
        # ping), so this is the track-level form of the map's test; once the map flags it, the
        # hotspot drop above ends the track.
        hold = np.zeros(nt, dtype=bool)
        if self.clutter_map is not None and self.hold_stationary:
            for i in np.flatnonzero(hit & ~confirmed & ~on_hot).tolist():
                lc = self._life[i]
                if lc.hits + 1 < self.m or len(self._seen[i]) < _MOTION_MIN_DETECTIONS:
                    continue
                seen = np.asarray(self._seen[i])
                cov = seen[:, [3, 4, 4, 5]].reshape(-1, 2, 2)
                hold[i] = motion_statistic(seen[:, 0], seen[:, 1:3], cov=cov) <= self._motion_gate
        life = []
        for lc, h, drop, held in zip(self._life, hit.tolist(), on_hot.tolist(), hold.tolist(),
                                     strict=True):
            if drop:
                life.append(Lifecycle("deleted", lc.age + 1, lc.hits + int(h), 0))
            elif held:
                life.append(Lifecycle("tentative", lc.age + 1, lc.hits + 1, 0))
            elif lc.status == "tentative" and lc.hits >= self.m and not h:
                # Held earlier, no detection now: ended like a confirmed track after
                # max_misses consecutive misses.
                misses = lc.misses + 1
                life.append(Lifecycle("deleted" if misses >= self.max_misses else "tentative",
                                      lc.age + 1, lc.hits, misses))
            else:
                life.append(advance_status(lc, bool(h), m=self.m, n=self.n,
                                           max_misses=self.max_misses))
        self._life = life

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

        status = np.array([lc.status for lc in self._life] + ["tentative"] * new.size, dtype=str)
        result = PingResult(
            event=ping.event,
            time=ping.time,
            track_id=np.concatenate([self._ids, ids]),
            state=np.concatenate([self._x, x_new]),
            status=status,
            detection=np.concatenate([det_of, new]),
            rank=np.concatenate([rank, np.full(new.size, np.nan)]),
            hotspots=(self.clutter_map.hotspots().positions if self.clutter_map is not None
                      else np.zeros((0, 2))),
        )
        alive = status != "deleted"
        alive_l, status_l = alive.tolist(), status.tolist()
        self._ids = result.track_id[alive]
        self._x = result.state[alive]
        self._P = np.concatenate([self._P, P_new])[alive]
        self._life = [lc for lc, a in zip(self._life + [Lifecycle()] * new.size, alive_l,
                                          strict=True) if a]
        seen = self._seen + [[rows[j]] for j in new.tolist()]
        self._seen = [[] if st == "confirmed" else h
                      for h, a, st in zip(seen, alive_l, status_l, strict=True) if a]
        logger.debug("event %d: %d detections, %d tracks, %d new", ping.event, nd, nt, new.size)
        return result

    def run(self, detections: Table | Sequence[Ping]) -> TrackingResult:
        """Track a whole run from a fresh start.

        Parameters
        ----------
        detections : Table or sequence of Ping
            A detections table (``event,time,x,y`` + optional clues) or its pings.

        Returns
        -------
        TrackingResult
        """
        pings = pings_from_table(detections) if isinstance(detections, Table) else list(detections)
        self.reset()
        return TrackingResult(tuple(self.step(p) for p in pings))
