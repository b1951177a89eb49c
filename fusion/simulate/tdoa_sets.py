"""Synthetic validated TDOAs of one processing window: several sources, clutter, gaps, association.

What the click front end hands the localization stage per window (*Localization of Short
Duration Periodic Signals*, steps 50-54), drawn from geometry instead of audio:

* every source contributes one TDOA per sensor pair, the straight-line delay
  ``(|p - s_i| - |p - s_j|)/c`` plus Gaussian noise of a per-TDOA standard deviation drawn
  uniformly from ``noise_range_s``; each is missing with probability ``p_missing``;
* ``n_clutter`` false TDOAs on random pairs, uniform over the pair's physical delay range
  ``|tau| <= |s_i - s_j|/c``;
* the cross-pair association ``alpha`` of eq. (13): zero unless two TDOAs share exactly one
  sensor; for two TDOAs of one source it counts the clicks they share, drawn
  ``Poisson(shared_clicks)``; for any other such pair (two sources, or clutter) it counts chance
  coincidences, ``Poisson(chance_matches)``;
* the rows are shuffled, so the labels are unknown to the localizer.

Examples
--------
>>> s = np.array([[0, 0, -1500.0], [3000, 0, -1600], [0, 3000, -1550], [3000, 3000, -1650]])
>>> w = simulate_tdoa_window(s, [[1000.0, 1200, -800]], c=1500.0, seed=0)
>>> w.taus.shape, w.alpha.shape, int((w.labels == 0).sum())
((6,), (6, 6), 6)
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.tdoa.model import predicted_tdoas

__all__ = ["SyntheticTdoaWindow", "all_pairs", "simulate_tdoa_window", "sharing_one_sensor"]


def all_pairs(n: int) -> NDArray[np.intp]:
    """All sensor pairs ``(i, j)``, ``i < j``, of `n` sensors, shape (n (n - 1) / 2, 2)."""
    return np.array(list(combinations(range(n), 2)), dtype=np.intp).reshape(-1, 2)


def sharing_one_sensor(pairs: ArrayLike) -> NDArray[np.bool_]:
    """Mask (M, M): True where two pairs share exactly one sensor (eq. 13's support)."""
    p = np.asarray(pairs)
    same = (p[:, None, :, None] == p[None, :, None, :]).sum(axis=(2, 3))
    return same == 1


@dataclass(frozen=True)
class SyntheticTdoaWindow:
    """One window of synthetic TDOAs.

    Attributes
    ----------
    pairs : ndarray of int, shape (M, 2)
        Sensor pairs ``(i, j)``.
    taus : ndarray, shape (M,)
        Delays, arrival at ``i`` minus arrival at ``j``, s.
    noise_std_s : ndarray, shape (M,)
        Standard deviation the noise of each true TDOA was drawn with, s (0 for clutter). Truth:
        for scoring only, never for an estimator.
    alpha : ndarray, shape (M, M)
        Cross-pair association (eq. 13), symmetric, zero diagonal.
    labels : ndarray of int, shape (M,)
        Source index of each TDOA, -1 for clutter (truth).
    sources : ndarray, shape (S, 3)
        Source positions, m (truth).
    """

    pairs: NDArray[np.intp]
    taus: NDArray[np.float64]
    noise_std_s: NDArray[np.float64]
    alpha: NDArray[np.float64]
    labels: NDArray[np.intp]
    sources: NDArray[np.float64]


def simulate_tdoa_window(
    sensors: ArrayLike,
    sources: ArrayLike,
    *,
    c: float,
    seed: int | np.random.Generator,
    noise_range_s: tuple[float, float] = (10e-6, 30e-6),
    p_missing: float = 0.0,
    n_clutter: int = 0,
    shared_clicks: float = 24.0,
    chance_matches: float = 0.5,
    pairs: ArrayLike | None = None,
) -> SyntheticTdoaWindow:
    """Draw one window of TDOAs of `sources` with clutter, gaps and association counts.

    Parameters
    ----------
    sensors : array_like, shape (n, 3)
        Sensor positions, m.
    sources : array_like, shape (S, 3)
        Source positions, m.
    c : float, keyword-only
        Sound speed, m/s.
    seed : int or numpy.random.Generator, keyword-only
        Seed (or generator) of every draw.
    noise_range_s : (float, float), keyword-only
        Range of the per-TDOA noise standard deviation, s (uniform).
    p_missing : float, keyword-only
        Probability that a source's TDOA on a pair is absent, in [0, 1).
    n_clutter : int, keyword-only
        Number of false TDOAs.
    shared_clicks : float, keyword-only
        Mean click count shared by two TDOAs of one source (eq. 13's alpha).
    chance_matches : float, keyword-only
        Mean alpha between TDOAs of different origins that share one sensor.
    pairs : array_like of int, shape (P, 2), optional, keyword-only
        Pairs measured; default all pairs.

    Returns
    -------
    SyntheticTdoaWindow
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    s = np.asarray(sensors, dtype=float)
    src = np.asarray(sources, dtype=float).reshape(-1, 3)
    pr = all_pairs(s.shape[0]) if pairs is None else np.asarray(pairs, dtype=np.intp)
    if not 0.0 <= p_missing < 1.0:
        raise ValueError(f"p_missing must lie in [0, 1), got {p_missing!r}")
    if n_clutter < 0:
        raise ValueError(f"n_clutter must be >= 0, got {n_clutter!r}")
    lo, hi = noise_range_s
    if not 0.0 <= lo <= hi:
        raise ValueError(f"noise_range_s must satisfy 0 <= low <= high, got {noise_range_s!r}")
    rows_pairs, rows_tau, rows_std, rows_label = [], [], [], []
    for k, p in enumerate(src):
        keep = rng.random(len(pr)) >= p_missing
        std = rng.uniform(lo, hi, len(pr))
        tau = predicted_tdoas(p, s, pr, c=c) + rng.normal(0.0, 1.0, len(pr)) * std
        rows_pairs.append(pr[keep])
        rows_tau.append(tau[keep])
        rows_std.append(std[keep])
        rows_label.append(np.full(int(keep.sum()), k))
    if n_clutter:
        cp = pr[rng.integers(0, len(pr), n_clutter)]
        span = np.linalg.norm(s[cp[:, 0]] - s[cp[:, 1]], axis=1) / c
        rows_pairs.append(cp)
        rows_tau.append(rng.uniform(-1.0, 1.0, n_clutter) * span)
        rows_std.append(np.zeros(n_clutter))
        rows_label.append(np.full(n_clutter, -1))
    order = rng.permutation(sum(len(x) for x in rows_tau))
    pairs_all = np.concatenate(rows_pairs).astype(np.intp)[order]
    labels = np.concatenate(rows_label).astype(np.intp)[order]
    m = len(labels)
    share = sharing_one_sensor(pairs_all) if m else np.zeros((0, 0), bool)
    same = (labels[:, None] == labels[None, :]) & (labels[:, None] >= 0)
    counts = np.where(same, rng.poisson(shared_clicks, (m, m)), rng.poisson(chance_matches, (m, m)))
    alpha = np.triu(np.where(share, counts, 0).astype(float), 1)
    return SyntheticTdoaWindow(
        pairs=pairs_all, taus=np.concatenate(rows_tau)[order],
        noise_std_s=np.concatenate(rows_std)[order], alpha=alpha + alpha.T, labels=labels,
        sources=src)
