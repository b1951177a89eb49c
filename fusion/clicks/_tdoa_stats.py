"""Statistics of the sub-sample TDOA refinement (:class:`fusion.clicks.tdoa.TdoaRefiner`).

The RMS frequency of a click and the Cramér-Rao bound of a delay between two noisy copies, the
paired t test of a carrier cycle against its neighbours, and the quantiles they need (cached).
The public names are re-exported by :mod:`fusion.clicks.tdoa`.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from fusion._validation import check_positive

__all__ = ["cycle_contrast", "gamma_median", "rms_frequency_hz", "t_quantile_95", "tdoa_crb_s"]


@lru_cache(maxsize=64)
def t_quantile_95(dof: int) -> float:
    """95 % quantile of Student's t with `dof` degrees of freedom (cached)."""
    return float(stats.t.ppf(0.95, dof))


@lru_cache(maxsize=16)
def gamma_median(shape: float) -> float:
    """Median of the unit-scale gamma law of `shape` (cached)."""
    return float(stats.gamma.median(shape))


def cycle_contrast(d_minus: NDArray, d_plus: NDArray) -> tuple[float, bool]:
    """Paired one-sided t-test that the chosen carrier cycle beats both neighbours.

    `d_minus`, `d_plus`: per click, correlation at the chosen cycle minus that one cycle
    earlier / later, relative to the former. Returns the smaller t statistic and whether it
    passes at 1 %.
    """
    n = d_minus.size
    if n < 2:
        return float("nan"), False
    ts = []
    for dd in (d_minus, d_plus):
        sd = float(np.std(dd, ddof=1))
        ts.append(np.inf if sd == 0 and dd.mean() > 0 else float(dd.mean() / sd * np.sqrt(n))
                  if sd > 0 else 0.0)
    t = min(ts)
    return float(t), bool(t > t_quantile_95(n - 1))


def rms_frequency_hz(power: ArrayLike, freqs_hz: ArrayLike) -> float:
    """Root-mean-square frequency of a power spectrum, about 0 Hz.

    Parameters
    ----------
    power : array_like, shape (n,)
        Power (energy) spectral density at `freqs_hz`, any units, >= 0.
    freqs_hz : array_like, shape (n,)
        Frequencies, Hz (one side suffices: the measure is even in ``f``).

    Returns
    -------
    float
        ``beta = sqrt(sum f^2 P / sum P)``, Hz: the carrier and the bandwidth together
        (``beta^2 = f_c^2 + B_rms^2``), which is what sets the precision of a delay measured on
        the waveform itself (not on its envelope).
    """
    p = np.asarray(power, dtype=float)
    f = np.asarray(freqs_hz, dtype=float)
    if p.shape != f.shape or p.ndim != 1:
        raise ValueError("power and freqs_hz must be 1-D arrays of one length")
    if np.any(p < 0) or not np.sum(p) > 0:
        raise ValueError("power must be >= 0 with a positive sum")
    return float(np.sqrt(np.sum(f * f * p) / np.sum(p)))


def tdoa_crb_s(rms_freq_hz: float, enr_i: ArrayLike, enr_j: ArrayLike) -> NDArray[np.float64]:
    """Cramér-Rao bound on the standard deviation of the delay between two noisy click copies.

    Parameters
    ----------
    rms_freq_hz : float
        RMS frequency ``beta`` of the click (:func:`rms_frequency_hz`), Hz.
    enr_i, enr_j : array_like
        Energy-to-noise ratio ``2E/N0`` (linear) of the click on each channel, broadcast
        together: ``E = sum_t s(t)^2`` over ``N0/2 = sigma^2`` the variance per sample of white
        noise with the in-band spectral level.

    Returns
    -------
    ndarray
        ``sqrt((1/enr_i + 1/enr_j) / (2 pi beta)^2)``, s.

    Notes
    -----
    For a pulse of known shape in white Gaussian noise, the arrival time has
    ``var >= 1 / ((2E/N0) (2 pi beta)^2)`` (Kay, *Fundamentals of Statistical Signal Processing:
    Estimation Theory*, 1993, example 3.13, range estimation). The difference of two arrival
    times with independent noise on the two channels adds the two bounds; this is also the
    high-SNR limit of the bound for a delay between two noisy copies of an unknown signal (Knapp
    and Carter, *IEEE Trans. ASSP* 24(4), 1976, eq. 23 with ``|gamma|^2 / (1 - |gamma|^2)``
    ``-> 1 / (N_i/S + N_j/S)``). ``n`` clicks with independent noise give
    ``1 / sum_n (1 / var_n)``.
    """
    b = check_positive("rms_freq_hz", rms_freq_hz)
    ei, ej = np.broadcast_arrays(np.asarray(enr_i, dtype=float), np.asarray(enr_j, dtype=float))
    if np.any(~(ei > 0)) or np.any(~(ej > 0)):
        raise ValueError("energy-to-noise ratios must be > 0")
    return np.sqrt(1.0 / ei + 1.0 / ej) / (2.0 * np.pi * b)
