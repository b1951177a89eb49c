"""Narrowband bearing measurement of one track in one scan: :class:`PeakMeasurer`.

The measurement step of the narrowband bearing tracker (:mod:`fusion.passive.tracker`, steps
2-5), in one home: the power of the cell at the predicted beam (the tracker amplitude ``A(k)``
of the track quality indicator), the peak near the predicted beam refined by a power-weighted
centroid, and its bearing residual. :class:`fusion.passive.tracker.BearingTracker` and the
passive pipeline (:mod:`fusion.pipelines.passive`) both measure through it.

Beams are equally spaced in cosine (beam 0 at forward endfire); bearings are cone angles in
``[0, pi]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion._validation import check_positive
from fusion.geometry import beam_from_bearing, bearing_from_beam

__all__ = ["BearingMeasurement", "PeakMeasurer"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class BearingMeasurement:
    """One track's measurement in one scan.

    Attributes
    ----------
    amplitude : float
        Power of the cell at the predicted beam, linear, normalised (noise mean 1).
    bearing : float
        Measured bearing, rad (centroid of the peak near the predicted beam).
    beam : float
        Fractional beam of the measured bearing.
    peak_power : float
        Power of the peak cell, linear.
    sigma : float
        Standard deviation of the measured bearing, rad.
    residual_deg : float
        Measured minus predicted bearing, deg (the error residual ``ES`` of the TQI).
    local_peak : bool
        Whether the strongest beam of the search is a local maximum of the row (False when it is
        at the edge of the search with stronger power just outside: the flank of a line beyond
        the search, not a line within it).
    """

    amplitude: float
    bearing: float
    beam: float
    peak_power: float
    sigma: float
    residual_deg: float
    local_peak: bool

    def innovation_std(self, predicted_variance: float) -> float:
        """Standard deviation of the innovation against a prediction of variance
        `predicted_variance` (rad^2): ``sqrt(P + sigma^2)``, rad."""
        return math.sqrt(predicted_variance + self.sigma**2)

    def in_gate(self, predicted: float, predicted_variance: float, gate: float) -> bool:
        """Whether the measurement may update a track predicted at `predicted` (rad) with
        variance `predicted_variance`: a local peak within `gate` innovation standard
        deviations of the prediction."""
        return self.local_peak and abs(self.bearing - predicted) <= gate * self.innovation_std(
            predicted_variance)


class PeakMeasurer:
    """Bearing measurement near a predicted bearing in one beam row of a scan.

    Parameters
    ----------
    beam_sigma : float
        Standard deviation of the centroid, beams; mapped to bearing through
        ``dtheta/db = 2 / ((N - 1) sin theta)`` with the sine floored half a beam off endfire.
    noise_mean : float
        Mean noise power of the normalised spectra (subtracted in the centroid weights).

    Notes
    -----
    The measurement of the narrowband bearing tracker (:class:`fusion.passive.tracker.
    BearingTracker`, module steps 2-5) for one scan: amplitude at the nearest beam to
    ``b = (N - 1)(1 - cos theta) / 2`` (eq. 5 of the acquisition text), the strongest beam within
    ``search_beams`` of it, and the centroid of that beam and its two neighbours above the noise
    mean. Added: whether that beam is a local maximum of the row, so that the flank of a stronger
    line just outside the search is not taken for the track's line.
    """

    def __init__(self, *, beam_sigma: float = 0.5, noise_mean: float = 1.0) -> None:
        self.beam_sigma = check_positive("beam_sigma", beam_sigma)
        self.noise_mean = check_positive("noise_mean", noise_mean)

    def sigma(self, bearing: float, n_beams: int) -> float:
        """Bearing standard deviation of a measurement at `bearing` (rad), rad."""
        sin_floor = math.sin(float(bearing_from_beam(0.5, n_beams)))
        s = max(math.sin(min(max(bearing, 0.0), math.pi)), sin_floor)
        return self.beam_sigma * 2.0 / ((n_beams - 1) * s)

    def measure(
        self, row: FloatArray, predicted_bearing: float, *, search_beams: int
    ) -> BearingMeasurement:
        """Measure the line near `predicted_bearing` in one row of beam powers.

        Parameters
        ----------
        row : ndarray, shape (n_beams,)
            Normalised power of the track's band in every beam at this scan.
        predicted_bearing : float
            Predicted bearing, rad (clipped to ``[0, pi]``).
        search_beams : int
            Half-width of the peak search, beams.

        Returns
        -------
        BearingMeasurement
        """
        n_beams = row.shape[0]
        theta_pred = min(max(float(predicted_bearing), 0.0), math.pi)
        ib = int(min(max(math.floor(float(beam_from_bearing(theta_pred, n_beams)) + 0.5), 0),
                     n_beams - 1))
        amp = float(row[ib])  # A(k): the predicted cell, before the scan is searched
        lo, hi = max(ib - search_beams, 0), min(ib + search_beams, n_beams - 1)
        peak = lo + int(np.argmax(row[lo:hi + 1]))
        local = not ((peak == lo and lo > 0 and row[lo - 1] > row[lo])
                     or (peak == hi and hi < n_beams - 1 and row[hi + 1] > row[hi]))
        cells = np.clip(np.arange(peak - 1, peak + 2), 0, n_beams - 1)
        w = np.maximum(row[cells] - self.noise_mean, 0.0)
        total = float(w.sum())
        beam = float(np.dot(w, cells) / total) if total > 0 else float(peak)
        theta = float(bearing_from_beam(beam, n_beams))
        return BearingMeasurement(
            amplitude=amp, bearing=theta, beam=beam, peak_power=float(row[peak]),
            sigma=self.sigma(theta_pred, n_beams),
            residual_deg=math.degrees(theta - theta_pred), local_peak=local,
        )
