"""The result of an acquisition: initial bearing, bearing rate and SNR of a clicked target.

Produced by :class:`fusion.passive.acquisition.acquire.Acquisition`; importable from
:mod:`fusion.passive.acquisition.acquire` and the package too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.passive.acquisition.fans import BestLine

__all__ = ["AcquisitionResult"]


@dataclass(frozen=True)
class AcquisitionResult:
    """Initial bearing, bearing rate and SNR of a clicked narrowband target.

    Attributes
    ----------
    bearing_deg : float
        Bearing from the forward axis at the latest scan, lag-corrected, deg in ``[0, 180]``.
    bearing_rate_deg_per_min : float
        Bearing rate, deg/min (positive: bearing increasing, toward aft endfire).
    snr_db : float
        SNR in a 1 Hz band, dB (eq. 4 of the method text; the default's value when
        `default_used`).
    default_used : bool
        True when the IBW SNR was too low (``snr_ibw <= min_snr_ibw``) and the defaults were output:
        rate 0, the clicked beam's bearing, the default SNR.
    snr_ibw : float
        Linear SNR in the IBW, ``(S+N - N) / N`` (measured, also when defaults are output; NaN when
        no line qualified).
    bearing_uncorrected_deg : float
        Bearing of the best line's latest end before the lag correction (the method's
        ``bestbrguncorrected``): the anchor beam of a straight line, the refined end beam of a
        constant-bearing-rate trace, deg.
    best_line : BestLine or None
        The overall best line (None when no line of any fan qualified).
    btr : ndarray, shape (n_scans, n_beams)
        IBW BTR, chronological rows (row ``n_scans - 1`` the latest scan).
    band_noise_level : float
        Mean BTR value off the trace.
    beamwidth_deg : float
        Approximate beamwidth of the clicked beam, deg.
    beam_tolerance : int
        Beams on each side of the clicked beam used as anchors.
    anchor_beams : tuple of int
        The anchor beams searched.
    ibw_bins : tuple of int
        Bin indices of the IBW.
    """

    bearing_deg: float
    bearing_rate_deg_per_min: float
    snr_db: float
    default_used: bool
    snr_ibw: float
    bearing_uncorrected_deg: float
    best_line: BestLine | None
    btr: NDArray[np.float64]
    band_noise_level: float
    beamwidth_deg: float
    beam_tolerance: int
    anchor_beams: tuple[int, ...]
    ibw_bins: tuple[int, ...]

    def to_json(self) -> dict[str, float | bool]:
        """The ``fusion acquire`` output: bearing, bearing rate, SNR, whether defaults were used."""
        return {
            "bearing_deg": float(self.bearing_deg),
            "bearing_rate_deg_per_min": float(self.bearing_rate_deg_per_min),
            "snr_db": float(self.snr_db),
            "default_used": bool(self.default_used),
        }
