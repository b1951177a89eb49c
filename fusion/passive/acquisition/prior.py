"""The prior of a track started by an acquisition: :class:`AcquisitionPrior`.

It turns an :class:`~fusion.passive.acquisition.result.AcquisitionResult` into a Gaussian prior
on the track's first state (a :class:`fusion.passive.smoothing.TrackPrior`), with an uncertainty
derived from the acquisition's own SNR, beamwidth and trace length. The track itself grows on
:class:`fusion.passive.smoothing.fixed_lag.FixedLagBearingTrack`.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from numpy.typing import NDArray

from fusion._validation import check_positive
from fusion.geometry import beam_from_bearing, beamwidth_cos, beamwidth_deg, bearing_from_beam
from fusion.passive.acquisition.result import AcquisitionResult
from fusion.passive.smoothing import TrackPrior

__all__ = ["AcquisitionPrior"]

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


class AcquisitionPrior:
    """Prior on a track's first state from an acquisition result.

    Parameters
    ----------
    default_sigma_rate_deg_per_min : float
        Rate standard deviation when the acquisition output its defaults (rate 0), deg/min.
    snr_floor : float
        Smallest linear IBW SNR used in the uncertainty model (the defaults' threshold, 1).
    inflation : float
        Factor on both standard deviations (1: the model as derived).
    max_walk_lobes : float
        An estimate farther than this many main-lobe widths (in beams) from the clicked beam has
        walked onto another line: the prior is then the defaults at the clicked beam.

    Notes
    -----
    The acquisition (*Acquisition system particularly suited for tracking targets having high
    bearing rates*, segments 46-54) fits a constant-rate trace through ``n`` scans of the IBW
    BTR. Each scan places the line to about ``sigma_1 = BW / sqrt(2 snr)`` (BW the main-lobe
    width in bearing at the estimate, :func:`fusion.geometry.beamwidth_deg`; ``snr`` the
    linear IBW SNR of the best trace, ``AcquisitionResult.snr_ibw``), and a straight-line fit of
    ``n`` equally spaced points has, at its latest end and in its slope,

    ``sigma_bearing = sigma_1 sqrt((4 n - 2) / (n (n + 1)))``,
    ``sigma_rate = sigma_1 sqrt(12 / (n (n^2 - 1))) / T``.

    On tuning seeds 100-259 of single-line cubes (3-12 dB per bin, rates within 12 deg/min) the
    errors divided by these sigmas had RMS 0.66-0.87: the model is slightly conservative and is
    used as derived. When the acquisition output its defaults (clicked beam, rate 0), or its
    estimate lies more than `max_walk_lobes` main lobes from the click (on those seeds, clicks on
    a weak line a few beams from a stronger one in the same bin ended on the stronger line), the
    prior is the defaults: the clicked beam's bearing with half a beamwidth, rate 0 with
    `default_sigma_rate_deg_per_min`.
    """

    def __init__(
        self,
        *,
        default_sigma_rate_deg_per_min: float = 10.0,
        snr_floor: float = 1.0,
        inflation: float = 1.0,
        max_walk_lobes: float = 1.0,
    ) -> None:
        self.default_sigma_rate_deg_per_min = check_positive(
            "default_sigma_rate_deg_per_min", default_sigma_rate_deg_per_min)
        self.snr_floor = check_positive("snr_floor", snr_floor)
        self.inflation = check_positive("inflation", inflation)
        self.max_walk_lobes = check_positive("max_walk_lobes", max_walk_lobes)

    def prior(
        self, result: AcquisitionResult, *, click_beam: int, n_beams: int, wavelength: float,
        aperture: float, scan_period: float,
    ) -> TrackPrior:
        """The prior of the state at the acquisition's latest scan.

        Parameters
        ----------
        result : AcquisitionResult
            The acquisition's estimate.
        click_beam : int
            The clicked beam.
        n_beams : int
            Beams of the array (equally spaced in cosine).
        wavelength, aperture : float
            Wavelength of the clicked line and the array aperture, m.
        scan_period : float
            Time between scans, s.

        Returns
        -------
        TrackPrior
            Bearing (rad) and rate (rad/s) of the acquisition with the model's sigmas.
        """
        theta = math.radians(result.bearing_deg)
        rate = math.radians(result.bearing_rate_deg_per_min) / 60.0
        lobe_beams = beamwidth_cos(wavelength, aperture) * (n_beams - 1) / 2.0
        walked = (abs(float(beam_from_bearing(theta, n_beams)) - click_beam)
                  > self.max_walk_lobes * lobe_beams)
        line = result.best_line
        if result.default_used or walked or line is None or line.n_scans_used < 3:
            if walked:
                logger.info("acquisition at %.2f deg is more than %g main lobes from the "
                            "clicked beam %d: defaults", result.bearing_deg,
                            self.max_walk_lobes, click_beam)
            theta, rate = float(bearing_from_beam(click_beam, n_beams)), 0.0
        bw = math.radians(float(beamwidth_deg(math.degrees(theta), wavelength=wavelength,
                                              aperture=aperture)))
        if result.default_used or walked or line is None or line.n_scans_used < 3:
            sig_b = 0.5 * bw
            sig_r = math.radians(self.default_sigma_rate_deg_per_min) / 60.0
        else:
            n = float(line.n_scans_used)
            snr = max(float(result.snr_ibw), self.snr_floor)
            s1 = bw / math.sqrt(2.0 * snr)  # one scan's line position
            sig_b = s1 * math.sqrt((4.0 * n - 2.0) / (n * (n + 1.0)))  # latest end of the fit
            sig_r = s1 * math.sqrt(12.0 / (n * (n * n - 1.0))) / scan_period  # its slope
        return TrackPrior(bearing=theta, rate=rate, sigma_bearing=self.inflation * sig_b,
                          sigma_rate=self.inflation * sig_r)
