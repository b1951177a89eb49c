"""Kalman stage of the multistatic tracker: constant-velocity prediction, update, pair statistics.

Section 3 of "Target tracking using fuzzy logic association" ("Tracker overview"): every track is
a constant-velocity Kalman filter with state ``[x, y, vx, vy]`` (m, m/s) and white-noise
acceleration; its prediction to the ping time gives, for every (track, detection) pair, the
innovation ``nu`` (m), its covariance ``S = H P H^T + R`` (m^2, with each detection's own ``R``),
the squared Mahalanobis distance ``d2 = nu^T S^-1 nu``, the Gaussian likelihood ``N(nu; 0, S)``
and the likelihood ratio to its peak ``L = exp(-d2 / 2)`` (the fuzzy input "likelihood"). Pairs
with ``d2`` above the chi-square gate (2 degrees of freedom) are not candidates.

All functions are vectorised over tracks (and detections); the motion model is the one of
:mod:`factors.motion`, shared with the factor graphs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from factors.motion import transition_matrix, wna_covariance

__all__ = [
    "PairStatistics",
    "cv_model",
    "fuse_positions",
    "gate_threshold",
    "kf_predict",
    "kf_update",
    "pair_statistics",
]

#: Measurement matrix of a position measurement of ``[x, y, vx, vy]``.
H_POSITION = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


def cv_model(dt: float, accel_psd: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Constant-velocity transition and process noise for state ``[x, y, vx, vy]``.

    Parameters
    ----------
    dt : float
        Time step, s (>= 0).
    accel_psd : float
        Power spectral density ``q`` of the white acceleration noise, m^2/s^3 (>= 0).

    Returns
    -------
    F : ndarray, shape (4, 4)
        ``[[I, dt I], [0, I]]`` (:func:`factors.motion.transition_matrix`).
    Q : ndarray, shape (4, 4)
        ``q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]]`` (continuous white-noise acceleration,
        :func:`factors.motion.wna_covariance`); zero when ``dt`` or ``q`` is 0 (detections of one
        time, or a model without process noise).

    Examples
    --------
    >>> F, Q = cv_model(2.0, 3.0)
    >>> float(F[0, 2]), float(Q[0, 0])
    (2.0, 8.0)
    """
    if not np.isfinite(dt) or dt < 0:
        raise ValueError(f"time step must be >= 0, got {dt!r}")
    if not np.isfinite(accel_psd) or accel_psd < 0:
        raise ValueError(f"accel_psd must be >= 0, got {accel_psd!r}")
    F = transition_matrix(dt, 2)
    Q = wna_covariance(dt, accel_psd, 2) if dt > 0 and accel_psd > 0 else np.zeros((4, 4))
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
    I_KH = np.eye(4) - K @ H_POSITION
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
        :func:`fusion.active.bistatic.bistatic_covariance`).

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


def fuse_positions(
    z: NDArray[np.float64], R: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One equivalent measurement for simultaneous position measurements of one object.

    Parameters
    ----------
    z : ndarray, shape (k, 2)
        Positions, m.
    R : ndarray, shape (k, 2, 2)
        Their covariances, m^2.

    Returns
    -------
    z_f : ndarray, shape (2,)
        ``C sum R_i^-1 z_i``, m.
    C : ndarray, shape (2, 2)
        ``(sum R_i^-1)^-1``, m^2; a Kalman update with ``(z_f, C)`` equals the sequential updates
        with every ``(z_i, R_i)``.
    """
    info = np.linalg.inv(R)
    C = np.linalg.inv(info.sum(axis=0))
    return C @ np.einsum("nij,nj->i", info, z), C


def gate_threshold(probability: float, *, dof: int = 2) -> float:
    """Chi-square gate on ``d2`` that keeps a true detection with the given probability."""
    if not 0.0 < probability < 1.0:
        raise ValueError(f"gate probability must lie in (0, 1), got {probability!r}")
    return float(chi2.ppf(probability, dof))

