"""Results of the SCM correlation (step 48): candidate TDOA peaks and a window's correlations.

Produced by :class:`fusion.clicks.scm.ClickMapCorrelator`; importable from
:mod:`fusion.clicks.scm` too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["ScmCorrelation", "TdoaPeak"]


@dataclass(frozen=True)
class TdoaPeak:
    """A candidate TDOA: a local maximum of the SCM correlation of one sensor pair.

    Attributes
    ----------
    pair : (int, int)
        Sensor indices ``(i, j)``.
    tau_s : float
        Delay ``t_i - t_j`` of the peak (parabolic-interpolated on the synthetic grid), s.
    value : float
        Interpolated correlation value: about the window-weighted number of matched clicks.
    rate : float
        Drift ``d tau / dt`` (s/s) under which sensor ``j``'s clicks were correlated (0 without
        drift compensation): `tau_s` holds at the window centre.
    """

    pair: tuple[int, int]
    tau_s: float
    value: float
    rate: float = 0.0


@dataclass(frozen=True)
class ScmCorrelation:
    """SCM correlations (eq. 6) of the sensor pairs of one window and their candidate peaks.

    Attributes
    ----------
    t0_s : float
        Start of the window, s from the start of the audio.
    pairs : ndarray of int, shape (n_pairs, 2)
        Sensor pairs ``(i, j)``.
    lags_s : ndarray, shape (n_lags,)
        Delays ``tau`` of the correlation samples, ``-T/4 .. T/4`` on the synthetic grid, s.
    values : ndarray, shape (n_pairs, n_lags)
        ``c(tau)`` of eq. 6 for each pair.
    max_delay_s : ndarray, shape (n_pairs,)
        Largest ``|tau|`` searched for peaks in each pair, s.
    peaks : tuple of TdoaPeak
        Candidate TDOAs, pair by pair in the order of `pairs`, strongest first within a pair.
    """

    t0_s: float
    pairs: NDArray[np.int64]
    lags_s: NDArray[np.float64]
    values: NDArray[np.float64]
    max_delay_s: NDArray[np.float64]
    peaks: tuple[TdoaPeak, ...]

    def peaks_of(self, pair: tuple[int, int]) -> tuple[TdoaPeak, ...]:
        """The candidate peaks of one pair, strongest first."""
        key = (int(pair[0]), int(pair[1]))
        return tuple(p for p in self.peaks if p.pair == key)
