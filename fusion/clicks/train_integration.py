"""TDOAs of a sensor that hears a whale's clicks below the detection threshold: the train summed.

Where a whale's clicks arrive at a hydrophone 10-20 dB below those at the nearest one, the
detector finds few of them there (1-17 % below 10 dB per-click SNR, ``benchmarks/RESULTS.md``,
"Issue 17: low SNR"), no click map of that sensor holds the train, and the window has no fix.
The clicks detected on a strong sensor still say *when* the whale clicked. Summing the weak
sensor's detection statistic (the detector's own, noise mean 1:
:meth:`fusion.clicks.detect.ClickDetector.statistic`) at those times moved by a candidate delay
and drift,

    ``Z(tau, r) = sum_n S_k(t_n + tau + r (t_n - t_c))``,

integrates the train: N clicks at a per-click deflection ``d`` give ``N d`` over a noise sum
whose spread grows as ``sqrt(N)``. The delay grid spans the physically possible delays of the
pair (separation / sound speed, plus a margin) at the statistic's frame spacing; the drift grid
spans ``+-max_rate`` with a step that moves the window's end clicks by at most half the
statistic's smoothing length. The noise law of ``Z`` is read off ``Z`` itself (most cells hold
no source): its median and scaled MAD; a peak counts when its excess reaches the Gaussian
quantile for a false-alarm probability `false_alarms` per (window, pair) spread over the grid's
independent cells (Bonferroni; the statistic's frames are correlated over the STFT length). The
delay is then refined on a grid of an eighth of a frame within a frame of the peak (and a
quarter of a drift step), the statistic interpolated linearly at each click's own time, and a
parabola through the best three; its sigma from the curvature of the frame-grid peak and the
noise spread, ``sigma = hop * sd / (sqrt(2) |second difference|)``, with the fine grid's
step added in quadrature (a strong train's peak is no better than the grid it is read on, and
the far sensor's clicks are reshaped by absorption: 3-9 us off on tuning seed 4 at 24 dB).

An addition to *Localization of Short Duration Periodic Signals* (Baggenstoss, NUWC 102089),
whose TDOAs all come from click maps of detected clicks; ``docs/localization.md`` section 19.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import gamma

from fusion.click_defaults import TRAIN_FALSE_ALARMS

__all__ = ["TRAIN_FALSE_ALARMS", "TRAIN_MIN_CLICKS", "TrainDelay", "train_delay"]

#: Fewest reference clicks a train needs.
TRAIN_MIN_CLICKS = 8
#: Steps of the fine delay grid per frame, and frames searched on either side of the peak.
FINE_STEPS, FINE = 8, 8


@dataclass(frozen=True)
class TrainDelay:
    """A weak sensor's delay found by summing its statistic along a reference click train.

    Attributes
    ----------
    delay_s : float
        ``t_k - t_m`` (weak sensor k after reference sensor m) for a click arriving at m at
        the reference time `t_c_s`, s.
    rate : float
        Drift of that delay per second of the reference clock, s/s.
    sigma_s : float
        Standard deviation of `delay_s`, s.
    z : float
        Peak excess over the sum's noise median in robust standard deviations.
    z_threshold : float
        The excess a peak needed (the false-alarm probability over the grid's cells).
    n_clicks : int
        Reference clicks summed.
    t_c_s : float
        Reference time of `delay_s` on sensor m's clock, s.
    """

    delay_s: float
    rate: float
    sigma_s: float
    z: float
    z_threshold: float
    n_clicks: int
    t_c_s: float

    def times_at_weak(self, ref_times_s: ArrayLike) -> NDArray[np.float64]:
        """The weak sensor's arrival times of the reference clicks `ref_times_s`."""
        t = np.asarray(ref_times_s, dtype=float)
        return t + self.delay_s + self.rate * (t - self.t_c_s)


def _rows(stat: NDArray, first: NDArray[np.int64], n_tau: int) -> NDArray[np.float64]:
    """``sum_n stat[first[n] : first[n] + n_tau]`` (indices inside `stat` by construction)."""
    out = np.zeros(n_tau, dtype=np.float64)
    for a in first:
        out += stat[a:a + n_tau]
    return out


def train_delay(
    stat: ArrayLike,
    t_first_s: float,
    hop_s: float,
    ref_times_s: ArrayLike,
    *,
    max_delay_s: float,
    t_c_s: float,
    max_rate: float = 1.6e-3,
    smooth_s: float = 2.5e-4,
    false_alarms: float = TRAIN_FALSE_ALARMS,
    min_clicks: int = TRAIN_MIN_CLICKS,
    cap: float | None = None,
) -> TrainDelay | None:
    """The weak sensor's delay behind a reference train, or None (see the module notes).

    Parameters
    ----------
    stat : array_like, shape (n,)
        The weak sensor's detection statistic (noise mean 1) on a regular frame grid.
    t_first_s : float
        Time of ``stat[0]``, s.
    hop_s : float
        Frame spacing, s.
    ref_times_s : array_like, shape (N,)
        Click times of one whale at the reference sensor, s.
    max_delay_s : float
        Largest ``|t_k - t_m|`` searched, s (separation over sound speed plus a margin).
    t_c_s : float
        Reference time of the delay (the window centre on the reference clock), s.
    max_rate : float, optional
        Largest drift searched, s/s (0: none).
    smooth_s : float, optional
        Smoothing length of the statistic (the STFT length), s: sets the drift step and the
        number of independent cells.
    false_alarms : float, optional
        False-alarm probability of the search.
    min_clicks : int, optional
        Fewest reference clicks (fewer: None).
    cap : float, optional
        Each frame's statistic is clipped to this before the sum (the detection threshold:
        a click above it is detected anyway, and a transient or a strong click of another
        source adds at most this much to one cell instead of dominating it); default none.

    Returns
    -------
    TrainDelay or None
        None when the train is too short, the statistic does not cover it, or no peak reaches
        the threshold.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> hop = 62.5e-6
    >>> s = rng.exponential(1.0, 200_000)            # noise statistic, mean 1
    >>> ref = 1.0 + np.cumsum(rng.uniform(0.3, 0.45, 25))
    >>> idx = np.round((ref + 0.4321) / hop).astype(int)
    >>> s[idx] += 3.0                                # each click well below a 6.0 threshold
    >>> d = train_delay(s, 0.0, hop, ref, max_delay_s=1.5, t_c_s=6.0, max_rate=0.0)
    >>> round(d.delay_s, 4), d.z > d.z_threshold
    (0.4321, True)
    """
    s = np.asarray(stat, dtype=np.float32).ravel()
    if cap is not None:
        s = np.minimum(s, np.float32(cap))
    t = np.sort(np.asarray(ref_times_s, dtype=float).ravel())
    if not (hop_s > 0 and max_delay_s > 0 and 0 < false_alarms < 1):
        raise ValueError("hop_s and max_delay_s must be positive, false_alarms in (0, 1)")
    n_tau = 2 * int(math.ceil(max_delay_s / hop_s)) + 1
    half = n_tau // 2
    span = float(np.max(np.abs(t - t_c_s))) if t.size else 0.0
    rate_step = smooth_s / 2.0 / max(span, hop_s)
    n_r = int(math.ceil(max_rate / rate_step)) if max_rate > 0 else 0
    rates = np.linspace(-max_rate, max_rate, 2 * n_r + 1) if n_r else np.zeros(1)
    # the statistic padded with its median (noise) where a click's delay range leaves it
    t = t[(t >= t_first_s) & (t <= t_first_s + (s.size - 1) * hop_s)]
    if t.size < max(int(min_clicks), 1) or s.size < 3:
        return None
    pad = half + int(math.ceil(max_rate * span / hop_s)) + 4
    s = np.concatenate([np.full(pad, np.median(s), np.float32), s,
                        np.full(pad, np.median(s), np.float32)])
    surface = np.empty((rates.size, n_tau))
    for q, r in enumerate(rates):
        first = (np.round((t + r * (t - t_c_s) - t_first_s) / hop_s).astype(np.int64)
                 - half + pad)
        surface[q] = _rows(s, first, n_tau)
    # the noise law of a cell, read off a strided sample of the cells (most hold no source):
    # median and scaled MAD, then a gamma of the moments of the cells within 6 sd of the
    # median (sums of many skewed frames; the source's own cells left out)
    sample = surface.ravel()[::7]
    med = float(np.median(sample))
    sd = 1.4826 * float(np.median(np.abs(sample - med)))
    if not sd > 0:
        return None
    core = sample[np.abs(sample - med) <= 6.0 * sd]
    mu, var = float(core.mean()), float(core.var())
    cells = max(1.0, surface.size * hop_s / smooth_s)
    level = float(gamma.isf(false_alarms / cells, mu * mu / var, scale=var / mu))
    z_thr = (level - med) / sd
    q, j = np.unravel_index(int(np.argmax(surface)), surface.shape)
    z = (surface[q, j] - med) / sd
    if z < z_thr:
        return None
    # the peak on a finer grid: the statistic interpolated linearly at each click's own
    # (fractional) frame, delays within a frame of the peak, drifts within a step
    sigma = hop_s
    if 0 < j < n_tau - 1:
        a, b, c = surface[q, j - 1], surface[q, j], surface[q, j + 1]
        den = a - 2.0 * b + c
        if den < 0:
            sigma = hop_s * sd / (math.sqrt(2.0) * abs(den))
    fine_d = (j - half + np.arange(-FINE, FINE + 1) / FINE_STEPS) * hop_s
    fine_r = rates[q] + np.array([-0.5, -0.25, 0.0, 0.25, 0.5]) * (
        rates[1] - rates[0] if rates.size > 1 else 0.0)
    pos = ((t[None, None, :] + fine_d[None, :, None]
            + fine_r[:, None, None] * (t - t_c_s)[None, None, :] - t_first_s) / hop_s + pad)
    lo = np.floor(pos).astype(np.int64)
    w = pos - lo
    fine = (s[lo] * (1.0 - w) + s[lo + 1] * w).sum(axis=2)  # (rates, delays)
    fq, fj = np.unravel_index(int(np.argmax(fine)), fine.shape)
    delay = float(fine_d[fj])
    if 0 < fj < fine_d.size - 1:
        a, b, c = fine[fq, fj - 1], fine[fq, fj], fine[fq, fj + 1]
        den = a - 2.0 * b + c
        if den < 0:
            delay += float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)) * hop_s / FINE_STEPS
    return TrainDelay(delay_s=delay, rate=float(fine_r[fq]),
                      sigma_s=float(math.hypot(sigma, hop_s / FINE_STEPS)), z=float(z),
                      z_threshold=z_thr,
                      n_clicks=int(t.size), t_c_s=float(t_c_s))
