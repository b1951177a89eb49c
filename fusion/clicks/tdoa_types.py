"""The result of the TDOA refinement: a sub-sample TDOA of one pair, its drift and uncertainty.

Produced by :class:`fusion.clicks.tdoa.TdoaRefiner`; importable from :mod:`fusion.clicks.tdoa`
too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["RefinedTdoa"]


@dataclass(frozen=True)
class RefinedTdoa:
    """A sub-sample TDOA of one sensor pair in one window, and its drift over the window.

    Attributes
    ----------
    pair : (int, int)
        Sensor indices ``(i, j)``.
    tau_s : float
        ``t_i - t_j`` at `t_ref_s`, s.
    sigma_s : float
        Standard deviation of `tau_s`, s: `crb_s` times ``max(1, birge)`` (with a carrier
        period added in quadrature when the cycle is not resolved).
    t_ref_s : float
        Time the TDOA refers to, s from the start of the audio on sensor ``i``'s clock (the
        weighted centroid of the clicks used, or the requested reference time).
    rate : float
        Drift ``d tau / dt`` at `t_ref_s`, s/s (0 for a constant fit).
    n_clicks_used : int
        Matched click pairs in the fit (after the SNR screen and outlier rejection).
    n_clicks_screened : int
        Matched click pairs that passed the SNR screen (the fit kept `n_clicks_used` of them).
    snr_db : float
        Measured energy-to-noise ratio ``2E/N0`` of a click, dB: per click the harmonic mean of
        the two channels, median over the clicks used.
    crb_s : float
        Cramér-Rao bound on the standard deviation of `tau_s` at the measured SNRs, s.
    cycle_t : float
        Paired t statistic (over the clicks) of the summed correlation at the chosen carrier
        cycle of the delay track against the cycles one period either side (the smaller).
    cycle_resolved : bool
        Whether `cycle_t` passes a one-sided test at 1 %; when not, `sigma_s` includes one
        carrier period `period_s` in quadrature.
    period_s : float
        ``1 / beta`` with ``beta`` the RMS frequency of the clicks: the spacing of the fine
        structure of their correlation, s.
    birge : float
        ``sqrt(chi2 / dof)`` of the per-click delays about the fit with their bounds as
        sigmas (1 expected; NaN without a degree of freedom).
    coef : ndarray, shape (degree + 1,)
        The fitted drift: ``tau(t) = sum_k coef[k] (t - t_ref_s)^k``, s and s/s^k.
    coef_cov : ndarray, shape (degree + 1, degree + 1)
        Covariance of `coef` at the Cramér-Rao level (multiply by ``max(1, birge)^2``).
    click_times_s : ndarray, shape (n_clicks_used,)
        Sensor ``i`` times of the clicks used, s.
    click_delays_s : ndarray, shape (n_clicks_used,)
        Their measured delays ``t_i - t_j``, s.
    click_sigma_s : ndarray, shape (n_clicks_used,)
        Per-click Cramér-Rao bound at the measured SNRs, s.
    """

    pair: tuple[int, int]
    tau_s: float
    sigma_s: float
    t_ref_s: float
    rate: float
    n_clicks_used: int
    n_clicks_screened: int
    snr_db: float
    crb_s: float
    cycle_t: float
    cycle_resolved: bool
    period_s: float
    birge: float
    coef: NDArray[np.float64]
    coef_cov: NDArray[np.float64]
    click_times_s: NDArray[np.float64]
    click_delays_s: NDArray[np.float64]
    click_sigma_s: NDArray[np.float64]

    @property
    def degree(self) -> int:
        """Degree of the fitted drift polynomial (0: constant TDOA)."""
        return int(self.coef.size - 1)

    @property
    def sigma_over_crb(self) -> float:
        """``sigma_s / crb_s`` (1 when the delays scatter no more than the bound predicts)."""
        return float(self.sigma_s / self.crb_s)

    def tau_at(self, t_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The fitted TDOA and its standard deviation at other times of the window.

        Parameters
        ----------
        t_s : array_like, any shape
            Times on sensor ``i``'s clock, s from the start of the audio.

        Returns
        -------
        tau, sigma : ndarray, same shape as `t_s`
            ``t_i - t_j`` and its standard deviation (scaled like `sigma_s`), s.
        """
        u = np.asarray(t_s, dtype=float) - self.t_ref_s
        x = u[..., None] ** np.arange(self.coef.size)
        var = np.einsum("...k,kl,...l->...", x, self.coef_cov, x)
        inflate = max(1.0, self.birge) if np.isfinite(self.birge) else 1.0
        sigma = inflate * np.sqrt(var)
        if not self.cycle_resolved:
            sigma = np.hypot(sigma, self.period_s)
        return x @ self.coef, sigma
