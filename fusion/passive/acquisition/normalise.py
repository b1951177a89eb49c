"""Program segment 22 of the acquisition method: beam spectra normalised to unit noise mean.

The method text (*Acquisition system particularly suited for tracking targets having high bearing
rates*, segment 22) asks for approximately unit-mean data in every bin without a narrowband
signal but names no normaliser; :func:`normalize_spectra` is a split-window median across
frequency, made unbiased for chi-square noise by :func:`expected_median_fraction`.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import integrate, optimize, stats

__all__ = ["UNIT_NOISE_TOLERANCE", "estimate_noise_dof", "expected_median_fraction",
           "noise_mean_level", "normalize_spectra"]

#: A cube whose median noise level is within this factor of 1 is taken as already normalised.
UNIT_NOISE_TOLERANCE = 1.25


@lru_cache(maxsize=256)
def expected_median_fraction(n: int, dof: float = 2.0) -> float:
    """Expected sample median of `n` unit-mean chi-square noise values.

    Parameters
    ----------
    n : int
        Sample size (>= 1).
    dof : float
        Degrees of freedom of the noise (2 for one periodogram look: exponential).

    Returns
    -------
    float
        ``E[median]`` of `n` independent gamma variables of shape ``dof / 2`` and unit mean; the
        median of an even sample is the mean of its two middle order statistics.

    Notes
    -----
    The ``k``-th order statistic of ``n`` values with distribution ``F`` is ``F^-1(U)`` with
    ``U ~ Beta(k, n - k + 1)``, so ``E[X_(k)] = int_0^1 F^-1(u) beta_pdf(u) du`` (numerical
    quadrature). For ``dof = 2`` this equals ``H_n - H_(n-k)`` (harmonic numbers).
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    if not np.isfinite(dof) or dof <= 0:
        raise ValueError(f"dof must be positive, got {dof!r}")
    shape = dof / 2.0

    def order_mean(k: int) -> float:
        beta = stats.beta(k, n - k + 1)
        lo, hi = beta.ppf(1e-13), beta.isf(1e-13)  # where the order statistic's mass lies
        val, _ = integrate.quad(
            lambda u: stats.gamma.ppf(u, shape, scale=1.0 / shape) * beta.pdf(u), lo, hi,
            limit=200,
        )
        return float(val)

    if n % 2:
        return order_mean((n + 1) // 2)
    return 0.5 * (order_mean(n // 2) + order_mean(n // 2 + 1))


def estimate_noise_dof(power: ArrayLike, *, exclude_bins: ArrayLike = ()) -> float:
    """Degrees of freedom of the noise, from the median-to-mean ratio of its cells.

    Parameters
    ----------
    power : array_like, shape (n_scans, n_beams, n_bins)
        Linear power of the beam spectra.
    exclude_bins : array_like of int, optional
        Bins left out (those that may hold the line).

    Returns
    -------
    float
        ``2 k`` with ``k`` the shape of the gamma distribution (unit mean) whose median equals
        the observed ratio ``median / mean`` of the cells, each (beam, bin) series over the scans
        divided by its own mean first (so that the noise level may differ across beams and
        frequency); clipped to [0.5, 100]. One periodogram look gives about 2 (exponential
        noise, ratio ln 2), ``m`` averaged looks about ``2 m`` (a few per cent more with 60
        scans, as each series' mean is itself estimated); a heavier-tailed background gives
        less.

    Notes
    -----
    The normaliser of program segment 22 (:func:`normalize_spectra`) turns a median into a mean
    through :func:`expected_median_fraction`, which depends on the noise statistics; they are
    estimated here rather than assumed. The median-to-mean ratio is the quantity the normaliser
    needs, so it is matched directly instead of through the variance, which a few strong cells
    dominate.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> x = rng.gamma(3.0, 1.0 / 3.0, size=(60, 32, 16))      # 3 looks: 6 degrees of freedom
    >>> bool(abs(estimate_noise_dof(x) - 6.0) < 0.5)
    True
    """
    p = np.asarray(power, dtype=float)
    if p.ndim != 3:
        raise ValueError(f"power must have shape (scans, beams, bins), got {p.shape}")
    keep = np.setdiff1d(np.arange(p.shape[2]), np.asarray(exclude_bins, dtype=int))
    if keep.size == 0 or p.shape[0] < 3:
        raise ValueError("need at least 3 scans and one bin outside exclude_bins")
    cells = p[:, :, keep]
    mean = cells.mean(axis=0)
    if np.any(mean <= 0):
        raise ValueError("a (beam, bin) series has zero mean power")
    ratio = float(np.median(cells / mean[None]))
    lo, hi = 0.25, 50.0
    f = lambda k: stats.gamma.ppf(0.5, k, scale=1.0 / k) - ratio  # noqa: E731
    if f(lo) >= 0:
        return 2.0 * lo
    if f(hi) <= 0:
        return 2.0 * hi
    return 2.0 * float(optimize.brentq(f, lo, hi, xtol=1e-4))


def _window(k: int, n_bins: int, window_bins: int, gap_bins: int) -> NDArray[np.intp]:
    j = np.arange(n_bins)
    d = np.abs(j - k)
    return j[(d > gap_bins) & (d <= gap_bins + window_bins)]


def normalize_spectra(
    power: ArrayLike,
    *,
    window_bins: int = 8,
    gap_bins: int = 1,
    noise_dof: float = 2.0,
    pool_scans: int | None = None,
    bins: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Normalise beam spectra to unit noise mean with a split-window median across frequency.

    Parameters
    ----------
    power : array_like, shape (n_scans, n_beams, n_bins)
        Linear power of the beam spectra (scans in time order).
    window_bins : int
        Bins on each side of the window (>= 1).
    gap_bins : int
        Bins on each side of the bin being normalised left out of its window (>= 0), so that a
        line spread over neighbouring bins does not raise its own noise estimate.
    noise_dof : float
        Degrees of freedom of the noise in one cell (2 for a single periodogram, ``2 m`` for ``m``
        averaged looks); sets the median-to-mean factor.
    pool_scans : int, optional
        Scans pooled into each noise estimate: a centred run of this many scans (1: every update
        on its own); None (default): the whole history.
    bins : array_like of int, optional
        Normalise only these bins (default all); the output's last axis follows `bins`.

    Returns
    -------
    ndarray, shape (n_scans, n_beams, n_bins) or (n_scans, n_beams, len(bins))
        Normalised power: noise alone has mean 1 (to the accuracy of the noise estimate).

    Raises
    ------
    ValueError
        Wrong shape, non-finite or negative power, a window with fewer than 3 bins, a zero noise
        estimate, a bad option.

    Notes
    -----
    Program segment 22 of the method text asks for approximately unit-mean data in every bin
    without a narrowband signal, but does not name a normaliser. Here the noise level of bin ``k``
    of a beam is the median of the bins ``gap < |j - k| <= gap + window`` (one side only near
    the band edges) over the pooled scans, divided by :func:`expected_median_fraction` of the
    sample size, which makes the level unbiased for chi-square noise; the bin itself and its gap
    neighbours are left out, so a line never raises its own level (a line inside another bin's
    window moves that median by at most one rank). The normalised mean exceeds 1 by about the
    level estimate's relative variance, since ``E[1 / level] > 1 / E[level]``.

    Pooling scans matters for narrow cubes: with 16 bins one update offers about 14 window
    values, whose median scatters by about 40 % and would multiply every cell by that error;
    the whole 60-scan history brings it to about 5 %. ``pool_scans=1`` is the per-update
    normaliser of the text.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = 5.0 * rng.exponential(size=(60, 8, 32))
    >>> bool(abs(normalize_spectra(x).mean() - 1.0) < 0.02)
    True
    """
    p = np.asarray(power, dtype=float)
    if p.ndim != 3 or min(p.shape) < 1:
        raise ValueError(f"power must have shape (scans, beams, bins), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("power contains NaN or infinite values")
    if np.any(p < 0):
        raise ValueError("power has negative values")
    if int(window_bins) != window_bins or window_bins < 1:
        raise ValueError(f"window_bins must be a positive integer, got {window_bins!r}")
    if int(gap_bins) != gap_bins or gap_bins < 0:
        raise ValueError(f"gap_bins must be a non-negative integer, got {gap_bins!r}")
    n_scans, n_beams, n_bins = p.shape
    pool = n_scans if pool_scans is None else int(pool_scans)
    if pool_scans is not None and (int(pool_scans) != pool_scans or not 1 <= pool <= n_scans):
        raise ValueError(f"pool_scans must be an integer in [1, {n_scans}], got {pool_scans!r}")
    targets = np.arange(n_bins) if bins is None else np.asarray(bins, dtype=int).reshape(-1)
    if targets.size and (targets.min() < 0 or targets.max() >= n_bins):
        raise ValueError(f"bins must lie in [0, {n_bins - 1}]")
    out = np.empty((n_scans, n_beams, targets.size))
    for i, k in enumerate(targets):  # a few bins; each median is vectorised over scans x beams
        win = _window(int(k), n_bins, int(window_bins), int(gap_bins))
        if win.size < 3:
            raise ValueError(
                f"normalisation window of bin {k} has {win.size} bins (need >= 3): the cube has "
                f"{n_bins} bins; use fewer gap bins or a pre-normalised cube"
            )
        w = p[:, :, win]  # (scans, beams, window)
        if pool == n_scans:  # one estimate per beam from the whole history
            samples = np.moveaxis(w, 0, 1).reshape(n_beams, -1)[None]  # (1, beams, n)
        else:  # centred runs of `pool` scans (clipped at the ends of the history)
            start = np.clip(np.arange(n_scans) - pool // 2, 0, n_scans - pool)
            runs = np.lib.stride_tricks.sliding_window_view(w, pool, axis=0)[start]
            samples = np.moveaxis(runs, 3, 2).reshape(n_scans, n_beams, -1)
        # sample median by a sort along the short sample axis (faster than np.median here)
        srt = np.sort(samples, axis=-1)
        n, m = srt.shape[-1], srt.shape[-1] // 2
        med = srt[..., m] if n % 2 else 0.5 * (srt[..., m - 1] + srt[..., m])
        level = med / expected_median_fraction(n, noise_dof)
        if np.any(level <= 0):
            raise ValueError(f"noise level of bin {k} is zero in some spectra (all-zero window)")
        out[:, :, i] = p[:, :, k] / level
    return out


def noise_mean_level(power: ArrayLike, *, pool_scans: int = 60) -> float:
    """The median noise level of a cube: 1 when it is already normalised to unit noise mean.

    Parameters
    ----------
    power : array_like, shape (n_scans, n_beams, n_bins)
        Beam spectra (power, linear).
    pool_scans : int
        The first scans, pooled into one noise estimate per beam and bin
        (:func:`normalize_spectra`).

    Returns
    -------
    float
        The median over the cells of ``power / normalize_spectra(power)``: the split-window
        noise estimate of :func:`normalize_spectra`, robust to lines (a median of medians).
        ``fusion passive`` normalises a cube whose level is outside
        ``[1 / UNIT_NOISE_TOLERANCE, UNIT_NOISE_TOLERANCE]``.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> round(noise_mean_level(40.0 * rng.exponential(size=(60, 4, 32))) / 40.0, 1)
    1.0
    """
    p = np.asarray(power, dtype=float)
    if p.ndim == 3:  # the first pool of scans tells the level (and bounds the cost)
        p = p[:max(1, int(pool_scans))]
    normalised = normalize_spectra(p, pool_scans=p.shape[0] if p.ndim == 3 else pool_scans)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = p / normalised
    return float(np.median(ratio[np.isfinite(ratio)]))
