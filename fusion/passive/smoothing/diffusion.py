"""Bearing acceleration PSD of tracks, estimated from their bearings.

Two estimators for :func:`~fusion.passive.smoothing.settings.fit_smooth_settings`:

- :func:`rate_diffusion` -- from the changes of block-wise fitted bearing rates along tracks,
  less what the fits' own noise explains (one time scale: the block);
- :func:`lag_diffusion` -- from the growth of second differences along tracks with the lag,
  fitted by least squares over lags up to where the motion shows above the noise (every time
  scale up to the smoother's).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import nnls

from fusion._validation import check_grid

__all__ = ["lag_diffusion", "rate_diffusion"]

FloatArray = NDArray[np.float64]


def rate_diffusion(
    groups: list[tuple[FloatArray, FloatArray]], *, sigma: float, block_s: float,
    min_points: int = 4,
) -> tuple[float, FloatArray]:
    """Bearing acceleration PSD from block-wise bearing rates along tracks.

    Parameters
    ----------
    groups : list of (times, bearings)
        Per track, time-ordered times (s) and bearings (rad) of its detections.
    sigma : float, keyword-only
        Bearing noise standard deviation, rad.
    block_s : float, keyword-only
        Block length, s.
    min_points : int, keyword-only
        Fewest detections of a block with a fitted rate.

    Returns
    -------
    q : float
        Acceleration PSD, rad^2/s^3 (``nan`` without two adjacent blocks anywhere).
    rates : ndarray, shape (m,)
        The block rates, rad/s.

    Notes
    -----
    Under white-noise acceleration of PSD ``q`` the rate is a random walk: the mean rates of two
    abutting blocks of length ``B`` differ with variance ``(2/3) q B`` (the overlap of the two
    box averages of a Wiener process) plus the least-squares variances ``v = sigma^2 / sum (t -
    tbar)^2`` of the two fits. ``q = sum (d^2 - v_1 - v_2) / sum (2/3) B``, the largest 5 % of
    ``d^2`` left out (associations gone wrong), at least zero.
    """
    num, den, rates = [], [], []
    for t, z in groups:
        if t.size < 2 * min_points:
            continue
        u = np.unwrap(z)
        check_grid((t[-1] - t[0]) / block_s + 1, f"a track from {t[0]:g} s to {t[-1]:g} s in "
                   f"rate blocks of {block_s:g} s")
        edges = np.arange(t[0], t[-1] + block_s, block_s)
        blk = np.searchsorted(edges, t, side="right") - 1
        prev = None
        for b in range(edges.size - 1):
            m = blk == b
            if m.sum() < min_points:
                prev = None
                continue
            tc = t[m] - t[m].mean()
            sxx = float(np.sum(tc * tc))
            if sxx <= 0:
                prev = None
                continue
            rate = float(np.sum(tc * (u[m] - u[m].mean())) / sxx)
            var = sigma**2 / sxx
            rates.append(rate)
            if prev is not None:
                num.append((rate - prev[0]) ** 2 - var - prev[1])
                den.append(2.0 / 3.0 * block_s)
            prev = (rate, var)
    if not num:
        return float("nan"), np.asarray(rates)
    n = np.asarray(num)
    keep = n <= np.quantile(n, 0.95)
    q = float(np.sum(n[keep]) / np.sum(np.asarray(den)[keep]))
    return max(q, 0.0), np.asarray(rates)


def _lag_moments(
    t: FloatArray, u: FloatArray, *, noise: float | None, max_signal_to_noise: float,
    min_triplets: int,
) -> tuple[FloatArray, FloatArray]:
    """Per lag: the coefficients ``(a, b)`` of ``(q, sigma^2)`` and the robust mean of ``D^2``."""
    n = t.size
    rows, ys = [], []
    for lag in np.unique(np.round(np.geomspace(1, max(n // 4, 1), 40)).astype(int)):
        i = np.arange(lag, n - lag)
        h1 = t[i] - t[i - lag]
        h2 = t[i + lag] - t[i]
        ok = (h1 > 0) & (h2 > 0)  # equal times (one scan) give no slope
        if ok.sum() < min_triplets:
            break
        h1, h2, i = h1[ok], h2[ok], i[ok]
        d = (u[i + lag] - u[i]) / h2 - (u[i] - u[i - lag]) / h1  # change of slope, rad/s
        rows.append((float(np.median((h1 + h2) / 3.0)),
                     float(np.median(1 / h1**2 + 1 / h2**2 + (1 / h1 + 1 / h2) ** 2))))
        ys.append(float(np.median(d * d) / 0.4549))  # median of chi-square(1) = 0.4549
        if noise is None:
            noise = ys[0] / rows[0][1]  # the shortest lag: about the noise alone
        elif ys[-1] > (1.0 + max_signal_to_noise) * noise * rows[-1][1]:
            break  # the motion shows: longer lags see curvature the smoother need not follow
    return np.asarray(rows).reshape(-1, 2), np.asarray(ys)


def lag_diffusion(
    groups: list[tuple[FloatArray, FloatArray]], *, sigma: float | None = None,
    max_signal_to_noise: float = 4.0, min_triplets: int = 20, iterations: int = 5,
) -> tuple[float, float]:
    """Bearing acceleration PSD and noise from second differences across lags along tracks.

    Parameters
    ----------
    groups : list of (times, bearings)
        Per track, time-ordered times (s) and bearings (rad) of its detections.
    sigma : float, optional, keyword-only
        Bearing noise standard deviation, rad, if known (then only ``q`` is fitted, consistent
        with this noise); default: fitted with ``q``.
    max_signal_to_noise : float, keyword-only
        Lags are taken up to the first one whose motion part exceeds this many times the noise
        part (the time scale on which the motion shows above the noise).
    min_triplets : int, keyword-only
        Fewest second differences of a lag (a track needs ``3 min_triplets`` detections).
    iterations : int, keyword-only
        Reweighting passes of the least-squares fit.

    Returns
    -------
    q : float
        Acceleration PSD, rad^2/s^3: the upper quartile over tracks (``nan`` without a usable
        track; one value serves every track, and a PSD too small for the more manoeuvring
        sources biases their bearings while one too large costs little precision).
    sigma : float
        Bearing noise standard deviation, rad: the median over tracks (`sigma` if given).

    Notes
    -----
    For three detections ``t_{i-L} < t_i < t_{i+L}`` of one track (``L`` detections apart, gaps
    ``h1``, ``h2``) the change of slope ``D = (z_{i+L} - z_i) / h2 - (z_i - z_{i-L}) / h1`` of a
    white-noise-acceleration bearing of PSD ``q`` seen with white noise ``sigma`` has
    ``E D^2 = q (h1 + h2) / 3 + sigma^2 (1/h1^2 + 1/h2^2 + (1/h1 + 1/h2)^2)`` (the slopes are
    the mean rates over abutting intervals; at equal gaps ``h = L K`` this is ``(2/3) q L^3 K^3
    + 6 sigma^2`` for the second difference ``h^2 D``). Per track and lag ``L`` (about
    geometric, 1, 2, 3, 4, 6, ..., up to a quarter of the track), the robust mean square is
    ``median(D^2) / 0.4549`` with the median coefficients. ``q`` (and ``sigma^2``) are fitted
    by non-negative least squares over the lags, each lag weighted by the inverse of its fitted
    value (relative errors), reweighted a few times. Short lags tell the noise, long lags the
    motion; the lags stop once the motion is ``max_signal_to_noise`` times the noise, so a
    deterministic curvature (growing as ``L^4`` rather than ``L^3``) is fitted at the time
    scale where the smoother has to follow it. Differences of consecutive scans alone see
    mostly noise and give a ``q`` far too small for long tracks.
    """
    noise = None if sigma is None else float(sigma) ** 2
    qs, s2s = [], []
    for t, z in groups:
        if t.size < 3 * min_triplets:
            continue
        m, y = _lag_moments(t, np.unwrap(z), noise=noise,
                            max_signal_to_noise=max_signal_to_noise, min_triplets=min_triplets)
        if y.size < 3:
            continue
        # known noise: fit y - sigma^2 b = q a; weights 1 / (fitted E D^2) either way
        a, rhs, fixed = (m, y, 0.0) if noise is None else (m[:, :1], y - noise * m[:, 1],
                                                             noise * m[:, 1])
        w = 1.0 / y
        for _ in range(iterations):
            x = nnls(a * w[:, None], rhs * w)[0]
            w = 1.0 / np.maximum(a @ x + fixed, 1e-6 * y)
        qs.append(x[0])
        s2s.append(x[1] if noise is None else noise)
    if not qs:
        return float("nan"), float("nan")
    return float(np.quantile(qs, 0.75)), float(np.sqrt(np.median(s2s)))
