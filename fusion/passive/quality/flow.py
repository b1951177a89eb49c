"""Equations of the track quality indicator: the hysteresis flow and its design quantities.

*Track Quality Indicator with Hysteresis* (W. R. Lane, US patent application 10/241389): the
state transition of FIGS. 2A-2C (steps 102-132), the amplitude statistics at the design SNRs and the
error detector's angular centre frequency. The module notes of :mod:`fusion.passive.quality.indicator`
give the readings of the method text; these names are importable from there too.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.passive.quality.types import TrackQuality
from fusion.passive.tracker import cell_power_statistics

__all__ = ["design_statistics", "omega_for_beamwidth", "tqi_transition"]


def omega_for_beamwidth(beamwidth_deg: float, *, n: float = 0.5) -> float:
    """Effective angular centre frequency ``Omega`` (1/deg) whose linear range ``n / Omega`` is one beamwidth.

    Parameters
    ----------
    beamwidth_deg : float
        Main-lobe width of the tracked beam in bearing, deg.
    n : float, optional
        The method's constant ``n`` (0.5).

    Returns
    -------
    float
        ``n / beamwidth_deg``, 1/deg.
    """
    if not np.isfinite(beamwidth_deg) or beamwidth_deg <= 0:
        raise ValueError(f"beamwidth_deg must be positive, got {beamwidth_deg!r}")
    return n / beamwidth_deg


def design_statistics(
    snr_db: ArrayLike, *, n_looks: int = 1, noise_mean: float = 1.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean ``C`` and standard deviation ``O`` of the amplitude estimate at design SNRs.

    The amplitude estimate is the tracker's cell power minus the noise mean; its statistics follow
    from the cell power statistics of the tracker (mean ``noise_mean (1 + s)``, standard deviation
    ``noise_mean sqrt((1 + 2 s) / L)`` for ``L`` averaged looks, SNR ``s`` linear).

    Parameters
    ----------
    snr_db : float or array_like, shape (m,)
        Per-cell SNRs, dB.
    n_looks : int, optional
        Independent looks averaged in one cell of the spectra.
    noise_mean : float, optional
        Noise mean of the normalised power (1 for normalised spectra).

    Returns
    -------
    C : ndarray, shape (m,)
        Means of the amplitude estimate (power above the noise mean), linear.
    O : ndarray, shape (m,)
        Standard deviations, linear.
    """
    mean, std = cell_power_statistics(snr_db, n_looks=n_looks, noise_mean=noise_mean)
    return np.atleast_1d(mean - noise_mean), np.atleast_1d(std)


def tqi_transition(
    previous: ArrayLike,
    sllr0: ArrayLike,
    sllr1: ArrayLike,
    residual_high: ArrayLike,
    *,
    tl: float = -3.5,
    tu: float = 1.75,
    ts: float = 7.0,
    lh: float = 1.5,
    sh: float = 2.0,
) -> NDArray[np.int8]:
    """One step of the hysteresis flow, steps 102-132 of the TQI method, for many trackers.

    Parameters
    ----------
    previous : array_like of int, shape (n,)
        ``TQI(k-1)``: a :class:`TrackQuality` code, or
        :data:`~fusion.passive.quality.types.START` before the first update.
    sllr0, sllr1 : array_like, shape (n,)
        ``SLLR_0(k)`` and ``SLLR_1(k)``.
    residual_high : array_like of bool, shape (n,)
        Whether the smoothed residual exceeds ``ERR_max`` (step 122).
    tl, tu, ts : float, optional
        Lost (``TL``) and uncertain (``TU``) thresholds of ``SLLR_0``, strong threshold (``TS``)
        of ``SLLR_1``.
    lh, sh : float, optional
        Low-SNR and strong-SNR hysteresis constants (``LH``, ``SH``); 0 gives single thresholds.

    Returns
    -------
    ndarray of int8, shape (n,)
        ``TQI(k)`` codes.

    Notes
    -----
    Step 102/104/110: lost if ``SLLR_0 <= TL + LH`` after a lost track, ``SLLR_0 <= TL``
    otherwise. Step 108/112: after an uncertain or lost track, uncertain if
    ``SLLR_0 < TU + LH``; step 116/118: after a low-SNR or strong track, uncertain if
    ``SLLR_0 < TU``. Step 122: uncertain if ``|ES| > ERR_max``. Step 124/126/132: strong if
    ``SLLR_1 >= TS - SH`` after a strong track, ``SLLR_1 >= TS + SH`` otherwise; else low SNR.
    :data:`~fusion.passive.quality.types.START` falls through every "no" branch.
    """
    prev = np.asarray(previous)
    s0 = np.asarray(sllr0, dtype=float)
    s1 = np.asarray(sllr1, dtype=float)
    high = np.asarray(residual_high, dtype=bool)
    was_lost = prev == TrackQuality.LOST
    # steps 102, 104, 110
    lost = np.where(was_lost, s0 <= tl + lh, s0 <= tl)
    # steps 108, 112 / 116, 118 (START and unknown codes skip both tests)
    was_weak = was_lost | (prev == TrackQuality.UNCERTAIN)
    was_good = (prev == TrackQuality.LOW_SNR) | (prev == TrackQuality.STRONG)
    uncertain = (was_weak & (s0 < tu + lh)) | (was_good & (s0 < tu))
    # step 122
    uncertain |= high
    # steps 124, 126, 132
    strong = np.where(prev == TrackQuality.STRONG, s1 >= ts - sh, s1 >= ts + sh)
    out = np.where(
        lost,
        TrackQuality.LOST,
        np.where(uncertain, TrackQuality.UNCERTAIN,
                 np.where(strong, TrackQuality.STRONG, TrackQuality.LOW_SNR)),
    )
    return out.astype(np.int8)
