"""Synthetic SCM2s for training and testing the TDOA validator before full-chain data exist.

A simulator (it draws click trains), so it lives beside the other scenario generators; no
estimator imports it. It renders the click front end's own window weight and features
(:func:`fusion.clicks.scm.window_weight`, :func:`fusion.clicks.validate.scm2_features`) of the
series it draws. Its old import path ``fusion.clicks.training`` forwards here for one release.

The validator of :mod:`fusion.clicks.validate` needs SCM2s (second-order smoothed click maps)
of valid and of invalid TDOAs. The shipped model is meant to be trained on SCM2s of simulated
audio through the whole click chain; this module draws SCM2-like series directly from click
times, so the validator can be trained and tested on its own.

An SCM2 is the product of two first-order click maps (*Localization of Short Duration Periodic
Signals*, eq. 3 and paragraph [0036]): one per hydrophone, the second shifted by the candidate
TDOA into the first one's time reference. Each click of a first-order map is the pulse of the
method's frequency-domain Hann shading of half-width ``N/8`` bins, which for large ``N`` is
``h(t) = sinc(x) / (1 - x^2)``, ``x = t fs_syn / 4`` (:func:`scm1_pulse`, peak 1, main lobe
+-8 samples). A click on sensor ``a`` at ``t_a`` and one of sensor ``b`` at ``t_b`` (shifted)
leave ``h(t - t_a) h(t - t_b)`` in the SCM2: amplitude 1 for a perfect match, less for a
partial one; pairs more than a main-lobe width (16 samples) apart, whose main lobes do not
overlap, are left out. A series is the sum of these pulses over all pairs of the two lists.

Training assumptions (the classes, each drawn with its own random parameters per series):

* ``valid`` — one click train at the true lag: ICI uniform in `ici_range_s`, gamma-distributed
  intervals with relative jitter uniform in `jitter_range`; each sensor misses a fraction of
  the clicks uniform in ``[0, miss_max]``; the two sensors' click times differ by Gaussian
  errors of standard deviation uniform in ``[0.05, 0.5]`` ms; a few false clicks (Poisson, mean
  uniform in ``[0, 10]`` per window) on each sensor.
* ``alias`` — the same train with sensor ``b`` mis-shifted by one mean ICI (two with probability
  0.2), either sign: only clicks whose interval happens to equal the mean ICI match. Its
  jitter is drawn from `alias_jitter_range` (default 2-15 %): with less jitter a one-ICI alias
  of a periodic train is the true train again and no SCM2 feature can tell them apart — that
  ambiguity is left to the time and cross-pair association (closure) of
  :mod:`fusion.clicks.associate`.
* ``echo`` — sensor ``a``'s direct clicks matched with sensor ``b``'s surface echoes, which
  are weak and detected for only a fraction of the clicks uniform in `echo_detect_range`
  (plus ``b``'s direct clicks, displaced by the echo delay, uniform in 0.01-1 s).
* ``coincidence`` — random coincidences of unrelated clicks: ``1 + Poisson(lam)`` pulses,
  ``lam`` uniform in 0.5-4, at uniform times, each pair offset uniformly within +-8 samples.
* ``isolated`` — one or two well-matched pulses.

In every class the candidate lag is uniform in ``[-T/4, T/4]`` and only the overlap of the two
sensors' windows carries pulses. An echo matched with every click is indistinguishable from a
valid train in its SCM2 and is not an invalid class here.

Examples
--------
>>> s = synthetic_training_set(40, seed=1)
>>> s.z.shape, int(s.label.sum())
((80, 4), 40)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion._validation import check_positive
from fusion.clicks.scm import window_weight
from fusion.clicks.validate import scm2_features
from fusion.simulate.whale_range.synthesis import draw_emission_times

__all__ = ["INVALID_KINDS", "KINDS", "SyntheticScm2Set", "scm1_pulse", "synthetic_scm2",
           "synthetic_training_set"]

#: Every class :func:`synthetic_scm2` draws.
KINDS: tuple[str, ...] = ("valid", "alias", "echo", "coincidence", "isolated")
#: The invalid (H0) classes, in equal shares in :func:`synthetic_training_set`.
INVALID_KINDS: tuple[str, ...] = KINDS[1:]

_HALF = 16  # samples each side of a pulse that are rendered (|h| < 0.003 beyond)


@dataclass(frozen=True)
class SyntheticScm2Set:
    """Features of synthetic SCM2s with their class.

    Attributes
    ----------
    z : ndarray, shape (n, 4)
        Features (:func:`fusion.clicks.validate.scm2_features`).
    label : ndarray of int, shape (n,)
        1 for valid, 0 for invalid.
    kind : ndarray of str, shape (n,)
        Class name, one of :data:`KINDS`.
    """

    z: NDArray[np.float64]
    label: NDArray[np.int_]
    kind: NDArray[np.str_]

    @property
    def z_valid(self) -> NDArray[np.float64]:
        """Features of the valid rows, shape (n1, 4)."""
        return self.z[self.label == 1]

    @property
    def z_invalid(self) -> NDArray[np.float64]:
        """Features of the invalid rows, shape (n0, 4)."""
        return self.z[self.label == 0]


def scm1_pulse(t_s: NDArray[np.float64], fs_syn: float) -> NDArray[np.float64]:
    """The pulse of one click in a first-order smoothed click map, peak 1.

    Parameters
    ----------
    t_s : ndarray
        Time from the click, s.
    fs_syn : float
        Synthetic sample rate, Hz.

    Returns
    -------
    ndarray, shape of `t_s`
        ``sinc(x) / (1 - x^2)`` with ``x = t fs_syn / 4`` (value 1/2 at ``x = +-1``).

    Notes
    -----
    *Localization of Short Duration Periodic Signals*, eq. (3): the inverse transform of a Hann
    shading of total width ``N/4`` bins, in the large-``N`` limit.
    """
    x = np.asarray(t_s, dtype=float) * fs_syn / 4.0
    pole = np.isclose(np.abs(x), 1.0, rtol=0.0, atol=1e-9)
    return np.where(pole, 0.5, np.sinc(x) / np.where(pole, 1.0, 1.0 - x**2))


def synthetic_scm2(
    kind: str,
    n: int,
    *,
    seed: int,
    fs_syn: float = 3000.0,
    T: float = 12.0,
    ici_range_s: tuple[float, float] = (0.2, 1.5),
    jitter_range: tuple[float, float] = (0.0, 0.15),
    alias_jitter_range: tuple[float, float] = (0.02, 0.15),
    miss_max: float = 0.2,
    echo_detect_range: tuple[float, float] = (0.05, 0.3),
    taper: bool = False,
) -> NDArray[np.float64]:
    """Draw SCM2-like series of one class (module docstring: the training assumptions).

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    n : int
        Number of series.
    seed : int
        Random seed.
    fs_syn : float, optional
        Synthetic sample rate, Hz.
    T : float, optional
        Window length, s; series have ``round(T fs_syn)`` samples.
    ici_range_s : (float, float), optional
        Range of the mean inter-click interval, s.
    jitter_range : (float, float), optional
        Range of the ICI's relative standard deviation (valid and echo trains).
    alias_jitter_range : (float, float), optional
        Range of the relative ICI jitter of the ``alias`` class.
    miss_max : float, optional
        Largest fraction of clicks a sensor misses, in [0, 1).
    echo_detect_range : (float, float), optional
        Range of the fraction of surface echoes detected (``echo`` class).
    taper : bool, optional
        Weight each pulse by the time window of eq. (5) (:func:`fusion.clicks.scm.window_weight`), for
        SCM2s built from a time-windowed first-order map.

    Returns
    -------
    ndarray, shape (n, round(T fs_syn))
        The series, times from the window start.
    """
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    fs = check_positive("fs_syn", fs_syn)
    window = check_positive("T", T)
    if not 0.0 <= miss_max < 1.0:
        raise ValueError(f"miss_max must be in [0, 1), got {miss_max!r}")
    for name, (lo, hi) in (("ici_range_s", ici_range_s), ("jitter_range", jitter_range),
                           ("alias_jitter_range", alias_jitter_range),
                           ("echo_detect_range", echo_detect_range)):
        if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo <= hi):
            raise ValueError(f"{name} must be an increasing pair of values >= 0, got {(lo, hi)}")
    if ici_range_s[0] <= 0:
        raise ValueError(f"ici_range_s must be positive, got {ici_range_s}")
    rng = np.random.default_rng(seed)
    n_samp = int(round(window * fs))
    opts = dict(T=window, fs=fs, ici=ici_range_s, jitter=jitter_range, alias_jitter=alias_jitter_range,
                miss=miss_max, echo=echo_detect_range)
    rows, ta, tb = [], [], []
    for i in range(int(n)):
        a = b = np.empty(0)
        while not np.any(np.abs(a - b) < 8.0 / fs):  # a correlation peak needs a coincidence
            a, b = _draw_pairs(kind, rng, **opts)
        rows.append(np.full(a.size, i))
        ta.append(a)
        tb.append(b)
    return _render(np.concatenate(rows), np.concatenate(ta), np.concatenate(tb), int(n), n_samp, fs,
                   window if taper else None)


def synthetic_training_set(
    n: int,
    *,
    seed: int,
    fs_syn: float = 3000.0,
    T: float = 12.0,
    chunk: int = 200,
    smooth_s: float = 0.02,
    **kinds_options: object,
) -> SyntheticScm2Set:
    """Features of `n` valid and `n` invalid synthetic SCM2s (invalid classes in equal shares).

    Parameters
    ----------
    n : int
        Number of valid series, and of invalid ones.
    seed : int
        Random seed (each class and chunk draws from its own child seed).
    fs_syn : float, optional
        Synthetic sample rate, Hz.
    T : float, optional
        Window length, s.
    chunk : int, optional
        Series rendered at once (bounds the memory to ``chunk * T * fs_syn`` floats).
    smooth_s : float, optional
        ACF smoothing of the features (:func:`fusion.clicks.validate.scm2_features`).
    **kinds_options
        Further options of :func:`synthetic_scm2` (ICI and jitter ranges, ...).

    Returns
    -------
    SyntheticScm2Set
        Valid rows first, then the invalid classes in the order of :data:`INVALID_KINDS`.
    """
    if int(n) < len(INVALID_KINDS):
        raise ValueError(f"n must be at least {len(INVALID_KINDS)}, got {n!r}")
    if int(chunk) < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk!r}")
    shares = np.diff(np.linspace(0, int(n), len(INVALID_KINDS) + 1).round().astype(int))
    counts = [("valid", int(n))] + list(zip(INVALID_KINDS, shares.tolist(), strict=True))
    seeds = np.random.SeedSequence(seed)
    z, kind = [], []
    for (name, count), child in zip(counts, seeds.spawn(len(counts)), strict=True):
        for k, grandchild in zip(range(0, count, chunk), child.spawn(-(-count // chunk)), strict=True):
            m = min(chunk, count - k)
            series = synthetic_scm2(name, m, seed=int(grandchild.generate_state(1)[0]), fs_syn=fs_syn,
                                    T=T, **kinds_options)
            z.append(scm2_features(series, fs_syn, T=T, smooth_s=smooth_s))
            kind.extend([name] * m)
    kind_arr = np.array(kind)
    return SyntheticScm2Set(np.vstack(z), (kind_arr == "valid").astype(int), kind_arr)


# --------------------------------------------------------------------------------------------
# drawing and rendering
# --------------------------------------------------------------------------------------------
def _draw_pairs(kind: str, rng: np.random.Generator, *, T: float, fs: float, ici: tuple[float, float],
                jitter: tuple[float, float], alias_jitter: tuple[float, float], miss: float,
                echo: tuple[float, float]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Matched click pairs ``(t_a, t_b)`` of one SCM2 (times in sensor a's reference, s)."""
    half_main = 8.0 / fs  # main-lobe half-width of a pulse
    lag = rng.uniform(-T / 4.0, T / 4.0)
    lo_b, hi_b = max(0.0, lag), min(T, T + lag)  # sensor b's window, shifted onto a's
    if kind in ("coincidence", "isolated"):
        count = 1 + rng.poisson(rng.uniform(0.5, 4.0)) if kind == "coincidence" else rng.integers(1, 3)
        t_a = rng.uniform(lo_b, hi_b, count)
        if kind == "coincidence":
            return t_a, t_a + rng.uniform(-half_main, half_main, count)
        return t_a, t_a + rng.normal(0.0, rng.uniform(0.05e-3, 0.5e-3), count)

    t0 = rng.uniform(*ici)
    rel_jit = rng.uniform(*(alias_jitter if kind == "alias" else jitter))
    train = draw_emission_times(ici_mean_s=t0, ici_jitter_s=rel_jit * t0, t_start_s=-3.0 * t0 - 2.0,
                                t_end_s=T + 3.0 * t0 + 2.0, rng=rng)
    sigma_e = rng.uniform(0.05e-3, 0.5e-3)

    def detected(times: NDArray[np.float64], p_detect: float) -> NDArray[np.float64]:
        return times[rng.random(times.size) < p_detect]

    def clutter() -> NDArray[np.float64]:
        return rng.uniform(0.0, T, rng.poisson(rng.uniform(0.0, 10.0)))

    t_a = np.concatenate([detected(train, 1.0 - rng.uniform(0.0, miss)), clutter()])
    b_true = train + rng.normal(0.0, sigma_e, train.size)  # b's clicks at the true lag
    if kind == "valid":
        t_b = detected(b_true, 1.0 - rng.uniform(0.0, miss))
    elif kind == "alias":
        shift = rng.choice([-1.0, 1.0]) * (2.0 if rng.random() < 0.2 else 1.0) * t0
        t_b = detected(b_true + shift, 1.0 - rng.uniform(0.0, miss))
    else:  # echo: the lag aligns b's (weak, rarely detected) echoes with a's direct clicks
        delay = rng.uniform(0.01, 1.0)
        t_b = np.concatenate([detected(b_true, rng.uniform(*echo)),
                              detected(b_true - delay, 1.0 - rng.uniform(0.0, miss))])
    t_b = np.concatenate([t_b, clutter() + lag])
    t_a = t_a[(t_a >= 0.0) & (t_a < T)]
    t_b = t_b[(t_b >= lo_b) & (t_b < hi_b)]
    # clicks whose pulses' main lobes overlap leave a pulse; sort b and look each a up
    t_b.sort()
    lo = np.searchsorted(t_b, t_a - 2.0 * half_main)
    hi = np.searchsorted(t_b, t_a + 2.0 * half_main)
    ia = np.repeat(np.arange(t_a.size), hi - lo)
    ib = lo[ia] + np.arange(ia.size) - np.repeat(np.cumsum(hi - lo) - (hi - lo), hi - lo)
    return t_a[ia], t_b[ib]


def _render(row: NDArray[np.int_], t_a: NDArray[np.float64], t_b: NDArray[np.float64], n: int,
            n_samp: int, fs: float, taper_T: float | None) -> NDArray[np.float64]:
    """Sum ``h(t - t_a) h(t - t_b)`` of every pair into an ``(n, n_samp)`` array."""
    centre = np.round(0.5 * (t_a + t_b) * fs).astype(int)
    idx = centre[:, None] + np.arange(-_HALF, _HALF + 1)  # (pairs, 2 HALF + 1)
    t = idx / fs
    val = scm1_pulse(t - t_a[:, None], fs) * scm1_pulse(t - t_b[:, None], fs)
    if taper_T is not None:  # eq. (5) time window at the pulse
        val *= window_weight(0.5 * (t_a + t_b), taper_T)[:, None]
    keep = (idx >= 0) & (idx < n_samp)
    flat = (row[:, None] * n_samp + idx)[keep]
    return np.bincount(flat, weights=val[keep], minlength=n * n_samp).reshape(n, n_samp)
