"""Narrowband bearing tracker: follows one line through a beam/frequency/time cube, scan by scan.

The tracker is the recursive narrowband tracker that the acquisition method (*Acquisition system
particularly suited for tracking targets having high bearing rates*, US 6,980,486) initialises and
whose amplitude estimate and error residual feed the track quality indicator (*Track Quality
Indicator with Hysteresis*, inputs ``A(k)`` and ``ES``).

Per scan ``k`` (period ``T``):

1. **Predict** a constant-bearing-rate state ``x = (theta, theta_dot)`` (rad, rad/s) with a
   :class:`filterpy.kalman.KalmanFilter`: ``x = F x``, ``P = F P F' + Q`` with
   ``F = [[1, T], [0, 1]]`` and ``Q`` the discrete white-noise acceleration model
   (:func:`filterpy.common.Q_discrete_white_noise`).
2. **Amplitude** ``A(k)``: the power of the cell at the predicted beam (nearest beam to
   ``b = (N - 1)(1 - cos theta) / 2``) and the tracked frequency bin, on the normalised scale
   (noise mean 1). Reading it at the prediction, before this scan's data are searched, keeps its
   statistics those of one cell: exponential of mean 1 for noise alone
   (:func:`cell_power_statistics`).
3. **Measure** by a local search in cosine-beam space: the strongest cell within ``search_beams``
   beams of the predicted beam, refined by the power-weighted centroid, above the noise mean, of that
   cell and its two neighbours; the fractional beam becomes a bearing
   ``arccos(1 - 2 b / (N - 1))``.
4. **Residual**: measured minus predicted bearing, deg (the error detector output ``ES``).
5. **Update** the Kalman filter with the measured bearing; its noise is ``beam_sigma`` beams
   mapped to bearing through ``dtheta/db = 2 / ((N - 1) sin theta)`` (sine floored half a beam off
   endfire).

Steps 2-4 and the measurement noise of step 5 are :class:`fusion.passive.measurement.PeakMeasurer`
(their one home, shared with the passive pipeline).

Examples
--------
>>> from fusion.simulate.cube import simulate_cube
>>> sc = simulate_cube(seed=3, n_scans=40, bearing0_deg=80.0, bearing_rate_deg_per_min=20.0,
...                    snr_db=15.0)
>>> hist = BearingTracker().track(sc.cube, bearing_deg=80.0, bearing_rate_deg_per_min=20.0,
...                               freq_hz=sc.click_freq, init_scan=0)
>>> bool(abs(hist.bearing_deg[-1] - sc.bearing_deg[-1]) < 2.0)
True
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import beam_from_bearing, beam_tolerance, beamwidth_deg
from fusion.passive.measurement import PeakMeasurer
from fusion.types import Cube

__all__ = ["BearingTracker", "TrackHistory", "beamwidth_deg", "cell_power_statistics"]

logger = logging.getLogger(__name__)


def cell_power_statistics(
    snr_db: ArrayLike, *, n_looks: int = 1, noise_mean: float = 1.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and standard deviation of the tracker's cell power at a per-cell SNR.

    The cell power is the mean of ``L`` periodogram looks ``|s + n|^2`` of a line of power
    ``S = snr * noise_mean`` in circular complex Gaussian noise of power ``noise_mean``. Each look
    has mean ``noise_mean (1 + snr)`` and variance ``noise_mean^2 (1 + 2 snr)`` (non-central
    chi-square with 2 degrees of freedom, scaled), so the mean of ``L`` looks has standard
    deviation ``noise_mean sqrt((1 + 2 snr) / L)``.

    Parameters
    ----------
    snr_db : float or array_like
        Per-cell SNR, dB (``-inf`` for noise alone).
    n_looks : int, optional
        Independent looks averaged in the cell.
    noise_mean : float, optional
        Mean noise power (1 for normalised spectra).

    Returns
    -------
    mean : ndarray
        Mean cell power, same shape as `snr_db`.
    std : ndarray
        Standard deviation of the cell power.

    Examples
    --------
    >>> m, s = cell_power_statistics(10.0)
    >>> float(m), float(s ** 2)
    (11.0, 21.0)
    """
    if int(n_looks) != n_looks or n_looks < 1:
        raise ValueError(f"n_looks must be a positive integer, got {n_looks!r}")
    if not np.isfinite(noise_mean) or noise_mean <= 0:
        raise ValueError(f"noise_mean must be positive, got {noise_mean!r}")
    s = 10.0 ** (np.asarray(snr_db, dtype=float) / 10.0)
    if np.any(np.isnan(s)):
        raise ValueError("snr_db contains NaN")
    return noise_mean * (1.0 + s), noise_mean * np.sqrt((1.0 + 2.0 * s) / n_looks)


@dataclass(frozen=True)
class TrackHistory:
    """One tracker's outputs, one entry per processed scan.

    Attributes
    ----------
    scan : ndarray of int, shape (K,)
        Cube scan index.
    time : ndarray, shape (K,)
        Scan time, s (``scan * scan_period``).
    bearing_deg : ndarray, shape (K,)
        Updated bearing estimate, deg from the forward axis.
    bearing_rate_deg_per_min : ndarray, shape (K,)
        Updated bearing-rate estimate, deg/min.
    bearing_sigma_deg : ndarray, shape (K,)
        Standard deviation of the updated bearing, deg.
    predicted_bearing_deg : ndarray, shape (K,)
        Predicted bearing before the scan's measurement, deg.
    measured_bearing_deg : ndarray, shape (K,)
        Bearing measured by the local peak/centroid search, deg.
    beam : ndarray, shape (K,)
        Fractional beam of the updated bearing.
    amplitude : ndarray, shape (K,)
        Tracker amplitude estimate ``A(k)``: power in the predicted cell, linear, normalised.
    residual_deg : ndarray, shape (K,)
        Error residual: measured minus predicted bearing, deg.
    freq_hz : float
        Centre frequency of the tracked bin, Hz.
    """

    scan: NDArray[np.int64]
    time: NDArray[np.float64]
    bearing_deg: NDArray[np.float64]
    bearing_rate_deg_per_min: NDArray[np.float64]
    bearing_sigma_deg: NDArray[np.float64]
    predicted_bearing_deg: NDArray[np.float64]
    measured_bearing_deg: NDArray[np.float64]
    beam: NDArray[np.float64]
    amplitude: NDArray[np.float64]
    residual_deg: NDArray[np.float64]
    freq_hz: float

    def __len__(self) -> int:
        return int(self.scan.shape[0])

    def amplitude_columns(self, track_id: int = 0) -> dict[str, NDArray]:
        """Columns ``track_id,time,amplitude,residual`` of an amplitudes file (``fusion tqi`` input)."""
        return {
            "track_id": np.full(len(self), int(track_id), dtype=np.int64),
            "time": self.time,
            "amplitude": self.amplitude,
            "residual": self.residual_deg,
        }


class BearingTracker:
    """Kalman bearing / bearing-rate tracker of one narrowband line in a beam/frequency/time cube.

    Parameters
    ----------
    accel_sigma_deg_per_min2 : float, optional
        Standard deviation of the bearing acceleration driving the white-noise acceleration
        model, deg/min^2.
    beam_sigma : float, optional
        Standard deviation of the centroid measurement, beams.
    search_beams : int, optional
        Half-width of the local search, beams; default: the beam tolerance of the array at the
        tracked frequency (half a main lobe, at least 2 beams).
    init_bearing_sigma_deg : float, optional
        Standard deviation of the initial bearing, deg; default half the beamwidth at the initial
        bearing.
    init_rate_sigma_deg_per_min : float, optional
        Standard deviation of the initial bearing rate, deg/min.
    noise_mean : float, optional
        Mean noise power of the normalised spectra (subtracted in the centroid weights).

    Notes
    -----
    See the module docstring for the per-scan steps. The filter is filterpy's
    :class:`~filterpy.kalman.KalmanFilter`; its bearing is kept in ``[0, pi]``.
    """

    def __init__(
        self,
        *,
        accel_sigma_deg_per_min2: float = 2.0,
        beam_sigma: float = 0.5,
        search_beams: int | None = None,
        init_bearing_sigma_deg: float | None = None,
        init_rate_sigma_deg_per_min: float = 10.0,
        noise_mean: float = 1.0,
    ) -> None:
        for name, v in (("accel_sigma_deg_per_min2", accel_sigma_deg_per_min2),
                        ("beam_sigma", beam_sigma),
                        ("init_rate_sigma_deg_per_min", init_rate_sigma_deg_per_min),
                        ("noise_mean", noise_mean)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive, got {v!r}")
        if search_beams is not None and (int(search_beams) != search_beams or search_beams < 1):
            raise ValueError(f"search_beams must be a positive integer, got {search_beams!r}")
        if init_bearing_sigma_deg is not None and not (
            np.isfinite(init_bearing_sigma_deg) and init_bearing_sigma_deg > 0
        ):
            raise ValueError(
                f"init_bearing_sigma_deg must be positive, got {init_bearing_sigma_deg!r}"
            )
        self.accel_sigma_deg_per_min2 = float(accel_sigma_deg_per_min2)
        self.beam_sigma = float(beam_sigma)
        self.search_beams = None if search_beams is None else int(search_beams)
        self.init_bearing_sigma_deg = init_bearing_sigma_deg
        self.init_rate_sigma_deg_per_min = float(init_rate_sigma_deg_per_min)
        self.noise_mean = float(noise_mean)

    def _filter(self, theta: float, rate: float, sigma_theta: float, dt: float) -> KalmanFilter:
        kf = KalmanFilter(dim_x=2, dim_z=1)
        kf.x = np.array([[theta], [rate]])
        kf.F = np.array([[1.0, dt], [0.0, 1.0]])  # theta(k) = theta(k-1) + T theta_dot(k-1)
        kf.H = np.array([[1.0, 0.0]])  # the measurement is the bearing
        sigma_rate = np.radians(self.init_rate_sigma_deg_per_min) / 60.0
        kf.P = np.diag([sigma_theta**2, sigma_rate**2])
        accel = np.radians(self.accel_sigma_deg_per_min2) / 3600.0  # rad/s^2
        kf.Q = Q_discrete_white_noise(dim=2, dt=dt, var=accel**2)
        return kf

    def track(
        self,
        cube: Cube,
        *,
        bearing_deg: float,
        bearing_rate_deg_per_min: float,
        freq_hz: float,
        init_scan: int = 0,
        n_scans: int | None = None,
    ) -> TrackHistory:
        """Follow the line from an initial state through the following scans.

        Parameters
        ----------
        cube : fusion.io.Cube
            Normalised beam/frequency/time power, beams equally spaced in cosine.
        bearing_deg : float
            Initial bearing at scan `init_scan`, deg from the forward axis, in [0, 180].
        bearing_rate_deg_per_min : float
            Initial bearing rate, deg/min.
        freq_hz : float
            Line frequency, Hz; the nearest bin is tracked.
        init_scan : int, optional
            Scan at which the initial state holds; tracking starts at the next scan.
        n_scans : int, optional
            Number of scans to process (default: to the end of the cube).

        Returns
        -------
        TrackHistory

        Raises
        ------
        ValueError
            Bearing outside [0, 180], non-finite values, a frequency outside the cube's band, an
            initial scan outside the cube, nothing left to track.
        """
        for name, v in (("bearing_deg", bearing_deg),
                        ("bearing_rate_deg_per_min", bearing_rate_deg_per_min),
                        ("freq_hz", freq_hz)):
            if not np.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v!r}")
        if not 0.0 <= bearing_deg <= 180.0:
            raise ValueError(f"bearing_deg must lie in [0, 180], got {bearing_deg!r}")
        n_total, n_beams, _ = cube.power.shape
        if int(init_scan) != init_scan or not 0 <= init_scan < n_total - 1:
            raise ValueError(
                f"init_scan must be an integer in [0, {n_total - 2}] (cube has {n_total} scans), "
                f"got {init_scan!r}"
            )
        df = np.diff(cube.freqs).min() if cube.n_bins > 1 else np.inf
        fbin = int(np.argmin(np.abs(cube.freqs - freq_hz)))
        if abs(cube.freqs[fbin] - freq_hz) > 0.5 * df and cube.n_bins > 1:
            raise ValueError(
                f"freq_hz {freq_hz} lies outside the cube's band "
                f"[{cube.freqs[0]:.3f}, {cube.freqs[-1]:.3f}] Hz"
            )
        last = n_total - 1 if n_scans is None else init_scan + int(n_scans)
        if n_scans is not None and (int(n_scans) != n_scans or n_scans < 1):
            raise ValueError(f"n_scans must be a positive integer, got {n_scans!r}")
        if last > n_total - 1:
            raise ValueError(
                f"n_scans={n_scans} from init_scan={init_scan} runs past the cube's "
                f"{n_total} scans"
            )

        dt = cube.scan_period
        wavelength = cube.sound_speed / cube.freqs[fbin]
        half = (self.search_beams if self.search_beams is not None
                else beam_tolerance(wavelength, cube.aperture, n_beams))
        measurer = PeakMeasurer(beam_sigma=self.beam_sigma, noise_mean=self.noise_mean)
        theta0 = np.radians(bearing_deg)
        sigma0 = (np.radians(self.init_bearing_sigma_deg) if self.init_bearing_sigma_deg
                  else 0.5 * np.radians(float(beamwidth_deg(bearing_deg, wavelength=wavelength,
                                                            aperture=cube.aperture))))
        kf = self._filter(theta0, np.radians(bearing_rate_deg_per_min) / 60.0, sigma0, dt)

        scans = np.arange(init_scan + 1, last + 1)
        out = {k: np.empty(scans.size) for k in (
            "bearing", "rate", "sigma", "pred", "meas", "beam", "amp", "res")}
        for i, k in enumerate(scans):
            kf.predict()
            theta_pred = float(np.clip(kf.x[0, 0], 0.0, np.pi))
            # steps 2-4: A(k) at the predicted cell, the peak near it, its centroid, the residual
            m = measurer.measure(cube.power[k, :, fbin], theta_pred, search_beams=half)
            amp, theta_meas = m.amplitude, m.bearing
            kf.update(np.array([[theta_meas]]), R=np.array([[m.sigma**2]]))
            kf.x[0, 0] = np.clip(kf.x[0, 0], 0.0, np.pi)
            out["bearing"][i] = kf.x[0, 0]
            out["rate"][i] = kf.x[1, 0]
            out["sigma"][i] = np.sqrt(kf.P[0, 0])
            out["pred"][i] = theta_pred
            out["meas"][i] = theta_meas
            out["beam"][i] = float(beam_from_bearing(kf.x[0, 0], n_beams))
            out["amp"][i] = amp
            out["res"][i] = theta_meas - theta_pred  # residual ES: measured - predicted
        logger.debug("tracked %d scans at %.2f Hz, search +-%d beams", scans.size,
                     cube.freqs[fbin], half)
        return TrackHistory(
            scan=scans.astype(np.int64),
            time=scans * dt,
            bearing_deg=np.degrees(out["bearing"]),
            bearing_rate_deg_per_min=np.degrees(out["rate"]) * 60.0,
            bearing_sigma_deg=np.degrees(out["sigma"]),
            predicted_bearing_deg=np.degrees(out["pred"]),
            measured_bearing_deg=np.degrees(out["meas"]),
            beam=out["beam"],
            amplitude=out["amp"],
            residual_deg=np.degrees(out["res"]),
            freq_hz=float(cube.freqs[fbin]),
        )
