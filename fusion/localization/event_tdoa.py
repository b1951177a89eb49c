"""Waveform TDOAs of one acoustic event: its band, band-passed cross-correlation, consistency.

An event found by any detector is a time span on the audio, optionally with a frequency box.
This module measures the delays of that event between every sensor pair from the waveforms:

1. :func:`estimate_band` -- the band where the event stands above the noise just before it, when
   the detector gave none;
2. :func:`bandpass` -- zero-phase Butterworth band-pass of every channel (``sosfiltfilt``);
3. :func:`pair_tdoas` -- the cross-correlation of every pair restricted to the physically
   possible lags ``|tau| <= d_ij / c`` (plus a few samples), its peak to a small fraction of a
   sample on the band-limited (FFT-interpolated) correlation, and a standard deviation from the
   data: the measured coherence and peak curvature in the Cramér-Rao bound of a delay between
   two noisy copies of one signal;
4. :func:`closure_screen` -- triangle closure ``tau_ab + tau_bc - tau_ac = 0``: TDOAs that break
   most of their triangles are set aside.

Nothing here assumes a scale: lags follow the array's own sensor distances.

Notes
-----
The delay is the lag of the cross-correlation peak (*Localization of Short Duration Periodic
Signals*, step 44 and eq. (3)-(6), there on smoothed click maps; here on the band-passed waveforms
themselves, as the low-frequency events have no click train). The standard deviation is the
Cramér-Rao bound of Carter (*Coherence and time delay estimation*, Proc. IEEE 75(2), 1987, eq. 27)
for a flat coherence ``gamma^2`` over the band ``B`` and an observation ``T``:
``var = (1 - gamma^2) / (gamma^2 2 B T (2 pi beta)^2)``, with ``gamma`` estimated by the normalised
correlation peak ``rho`` and ``(2 pi beta)^2`` by the peak's curvature ``-r''/r``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from itertools import combinations

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage, signal

from fusion._validation import check_positive
from fusion.types import frozen_array

__all__ = ["PairTdoas", "bandpass", "closure_screen", "estimate_band", "pair_tdoas"]

logger = logging.getLogger(__name__)

#: Highest band edge as a fraction of the sample rate (a little under Nyquist).
MAX_EDGE_FRACTION = 0.45


def estimate_band(
    event: NDArray[np.float64],
    noise: NDArray[np.float64],
    fs: float,
    *,
    snr_db: float = 6.0,
    floor_hz: float = 10.0,
) -> tuple[float, float] | None:
    """Band where an event's spectrum exceeds the noise spectrum by `snr_db`.

    Parameters
    ----------
    event : ndarray, shape (n_event, n_channels)
        The event's samples.
    noise : ndarray, shape (n_noise, n_channels)
        Background, e.g. the second before the event (its Welch spectrum is the median over
        segments, so other short transients in it barely count).
    fs : float
        Sample rate, Hz.
    snr_db : float, keyword-only
        Power ratio of event to noise (summed over channels) that counts as signal, dB.
    floor_hz : float, keyword-only
        Lowest band edge, Hz.

    Returns
    -------
    (float, float) or None
        ``(f_low, f_high)``, Hz: the contiguous run of Welch bins (segments of a quarter of the
        event) above `snr_db` that holds the most excess power (gaps of up to two bins
        bridged), clipped to ``[floor_hz, 0.45 fs]``; None when the event is under 32 samples,
        the background is shorter than a segment, or no run at least three bins wide exists.
    """
    nper = max(16, event.shape[0] // 4)  # a few averaged segments of the event
    if event.shape[0] < 32 or noise.shape[0] < nper:
        return None
    f, p_evt = signal.welch(event, fs, nperseg=nper, axis=0)
    # median over segments: other transients in the background do not count as noise
    _, p_noise = signal.welch(noise, fs, nperseg=nper, axis=0, average="median")
    pe, pn = p_evt.sum(axis=1), p_noise.sum(axis=1)
    above = pe > pn * 10.0 ** (snr_db / 10.0)
    # bridge gaps of up to two bins (a closing; padded so the ends are not eroded), label runs
    closed = ndimage.binary_closing(np.pad(above, 3), structure=np.ones(3, bool))[3:-3] | above
    labels, n_runs = ndimage.label(closed)
    if n_runs == 0:
        return None
    excess = ndimage.sum_labels(np.maximum(pe - pn, 0.0), labels, np.arange(1, n_runs + 1))
    run = np.flatnonzero(labels == int(np.argmax(excess)) + 1)
    lo_k, hi_k = int(run[0]), int(run[-1]) + 1
    if hi_k - lo_k < 3:
        return None
    lo = max(float(f[lo_k]), floor_hz)
    hi = min(float(f[hi_k - 1]), MAX_EDGE_FRACTION * fs)
    return (lo, hi) if hi > lo else None


def bandpass(x: ArrayLike, fs: float, band_hz: tuple[float, float], *, order: int = 4
             ) -> NDArray[np.float64]:
    """Zero-phase Butterworth band-pass of every column of `x`.

    Parameters
    ----------
    x : array_like, shape (n, n_channels)
        Samples.
    fs : float
        Sample rate, Hz.
    band_hz : (float, float)
        Pass band ``(f_low, f_high)``, Hz, ``0 < f_low < f_high < fs / 2``.
    order : int, keyword-only
        Butterworth order of the forward filter (``sosfiltfilt`` doubles it).

    Returns
    -------
    ndarray, shape (n, n_channels)
        Filtered samples (no delay).
    """
    lo, hi = (float(v) for v in band_hz)
    if not (0 < lo < hi < fs / 2):
        raise ValueError(f"band {band_hz} Hz must satisfy 0 < f_low < f_high < fs/2 = {fs / 2:g}")
    sos = signal.butter(int(order), [lo, hi], btype="bandpass", fs=fs, output="sos")
    return signal.sosfiltfilt(sos, np.asarray(x, dtype=float), axis=0)


@dataclass(frozen=True)
class PairTdoas:
    """Cross-correlation TDOAs of one event for a set of sensor pairs.

    Attributes
    ----------
    pairs : ndarray of int, shape (m, 2)
        Sensor pairs ``(i, j)``.
    taus : ndarray, shape (m,)
        Delays, arrival at ``i`` minus arrival at ``j``, s.
    sigmas : ndarray, shape (m,)
        Standard deviation of each delay from the data (Carter's bound), s; inf when the
        correlation has no usable peak.
    rho : ndarray, shape (m,)
        Normalised correlation at the peak (estimate of the coherence ``gamma``).
    at_edge : ndarray of bool, shape (m,)
        Peak on the edge of the allowed lag range (not a local maximum inside it).
    """

    pairs: NDArray[np.intp]
    taus: NDArray[np.float64]
    sigmas: NDArray[np.float64]
    rho: NDArray[np.float64]
    at_edge: NDArray[np.bool_]

    def __post_init__(self) -> None:
        object.__setattr__(self, "pairs", frozen_array(self.pairs, np.intp).reshape(-1, 2))
        for name in ("taus", "sigmas", "rho"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        object.__setattr__(self, "at_edge", frozen_array(self.at_edge, bool))
        m = self.pairs.shape[0]
        if any(getattr(self, k).shape != (m,) for k in ("taus", "sigmas", "rho", "at_edge")):
            raise ValueError("PairTdoas arrays must have one entry per pair")

    @property
    def usable(self) -> NDArray[np.bool_]:
        """Finite sigma, positive correlation and an interior peak."""
        return np.isfinite(self.sigmas) & (self.rho > 0) & ~self.at_edge


def _interp(spec: NDArray[np.complex128], n_fft: int, lags: NDArray[np.float64], deriv: int = 0
            ) -> NDArray[np.float64]:
    """The band-limited correlation (or its `deriv`-th derivative) at fractional lags (samples).

    ``r(l) = (1/N) sum_k w_k Re(R_k e^{i omega_k l})`` over the one-sided spectrum ``R``
    (``w_k = 2`` except at 0 and Nyquist); evenly spaced lags go through a zoom FFT.
    """
    k = np.arange(spec.shape[0])
    w = np.full(k.shape, 2.0)  # one-sided spectrum: the conjugate half counted twice
    w[0] = 1.0
    if n_fft % 2 == 0:
        w[-1] = 1.0
    omega = 2.0 * np.pi * k / n_fft  # rad per sample
    coef = w * spec * (1j * omega) ** deriv
    if lags.size < 3:
        return (np.exp(1j * np.outer(lags, omega)) @ coef).real / n_fft
    # sum_k coef_k e^{+i omega_k l} = conj(DFT of conj(coef) at frequency l / N cycles per bin)
    z = signal.zoom_fft(np.conj(coef), [lags[0], lags[-1]], m=lags.size, fs=n_fft, endpoint=True)
    return np.conj(z).real / n_fft


def pair_tdoas(
    segment: ArrayLike,
    fs: float,
    sensors: ArrayLike,
    c: float,
    *,
    band_hz: tuple[float, float],
    pairs: ArrayLike | None = None,
    upsample: int = 16,
    lag_margin_samples: float = 2.0,
) -> PairTdoas:
    """Sub-sample TDOAs of every pair from the cross-correlation of band-passed waveforms.

    Parameters
    ----------
    segment : array_like, shape (n, n_sensors)
        The event, band-passed, with a margin of at least the largest delay on each side.
    fs : float
        Sample rate, Hz.
    sensors : array_like, shape (n_sensors, 3)
        Sensor positions, m.
    c : float
        Sound speed, m/s.
    band_hz : (float, float), keyword-only
        The pass band used, Hz (its width enters the standard deviation).
    pairs : array_like of int, shape (m, 2), optional, keyword-only
        Pairs to measure; default all ``i < j``.
    upsample : int, keyword-only
        Fine lag grid of ``1 / upsample`` samples around the integer peak; a parabola through
        the best fine lag and its neighbours gives the delay.
    lag_margin_samples : float, keyword-only
        Lags beyond ``d_ij / c`` still searched, samples (sensor positions and sound speed are
        not exact).

    Returns
    -------
    PairTdoas

    Notes
    -----
    The correlation ``r(l) = sum_t y_i(t + l) y_j(t)`` is the inverse FFT of
    ``Y_i conj(Y_j)`` (zero-padded: a linear correlation); between samples it is evaluated from
    the same spectrum, which is its band-limited interpolation. The peak's curvature ``-r''/r``
    comes from the spectrum weighted by ``omega^2``. See the module Notes for the bound.
    """
    y = np.asarray(segment, dtype=float)
    s = np.asarray(sensors, dtype=float)
    if y.ndim != 2 or y.shape[1] != s.shape[0]:
        raise ValueError(f"segment must have shape (n, {s.shape[0]}), got {y.shape}")
    fs = check_positive("fs", fs)
    if int(upsample) < 1:
        raise ValueError(f"upsample must be a positive integer, got {upsample!r}")
    pr = (np.array(list(combinations(range(s.shape[0]), 2)), dtype=np.intp) if pairs is None
          else np.asarray(pairs, dtype=np.intp).reshape(-1, 2))
    n = y.shape[0]
    bandwidth = float(band_hz[1] - band_hz[0])
    n_fft = scipy.fft.next_fast_len(2 * n, real=True)
    spec = scipy.fft.rfft(y, n_fft, axis=0)
    energy = (y * y).sum(axis=0)
    up = int(upsample)
    m = pr.shape[0]
    taus, sigmas, rhos = np.zeros(m), np.full(m, np.inf), np.zeros(m)
    edge = np.zeros(m, dtype=bool)
    for k, (i, j) in enumerate(pr):
        max_lag = float(np.linalg.norm(s[i] - s[j]) / c * fs + lag_margin_samples)
        q = min(int(np.floor(max_lag)), n - 1)
        cross = spec[:, i] * np.conj(spec[:, j])
        cc = scipy.fft.irfft(cross, n_fft)
        window = np.concatenate([cc[n_fft - q:], cc[:q + 1]]) if q > 0 else cc[:1]
        k0 = int(np.argmax(window))
        lag0 = k0 - q
        edge[k] = q > 0 and (k0 == 0 or k0 == window.size - 1)
        fine = lag0 + np.arange(-up, up + 1) / up  # +-1 sample around the integer peak
        fine = fine[np.abs(fine) <= max_lag]
        r_fine = _interp(cross, n_fft, fine)
        b = int(np.argmax(r_fine))
        lag = float(fine[b])
        if 0 < b < fine.size - 1:  # parabola through the fine neighbours
            y0, y1, y2 = r_fine[b - 1:b + 2]
            den = y0 - 2.0 * y1 + y2
            if den < 0:
                lag += 0.5 * (y0 - y2) / den / up
        r0, r2 = (float(v[0]) for v in (_interp(cross, n_fft, np.array([lag]), d) for d in (0, 2)))
        taus[k] = lag / fs
        norm = np.sqrt(energy[i] * energy[j])
        rho = r0 / norm if norm > 0 else 0.0
        rhos[k] = rho
        curvature = -r2 / r0 * fs * fs if r0 > 0 else 0.0  # (2 pi beta)^2, s^-2
        if rho > 0 and curvature > 0:
            g2 = min(rho, 1.0 - 1e-9) ** 2
            # Carter's bound: var = (1 - g^2) / (g^2 2 B T (2 pi beta)^2)
            var = (1.0 - g2) / (g2 * 2.0 * bandwidth * (n / fs) * curvature)
            sigmas[k] = float(np.sqrt(var))
    return PairTdoas(pr, taus, sigmas, rhos, edge)


def closure_screen(
    pairs: ArrayLike,
    taus: ArrayLike,
    sigmas: ArrayLike,
    usable: ArrayLike,
    *,
    n_sigma: float = 3.0,
    min_rank: int = 3,
) -> tuple[NDArray[np.bool_], float]:
    """Set aside TDOAs that break most of their triangle closures.

    Parameters
    ----------
    pairs : array_like of int, shape (m, 2)
        Sensor pairs ``(i, j)``.
    taus, sigmas : array_like, shape (m,)
        Delays and their standard deviations, s.
    usable : array_like of bool, shape (m,)
        TDOAs eligible at all.
    n_sigma : float, keyword-only
        A triangle fails when ``|tau_ab + tau_bc - tau_ac|`` exceeds `n_sigma` times the root
        sum of the three variances.
    min_rank : int, keyword-only
        Never drop a TDOA when that would leave fewer independent TDOAs (incidence rank).

    Returns
    -------
    keep : ndarray of bool, shape (m,)
        TDOAs kept.
    closure_rms_s : float
        RMS closure over the triangles of usable TDOAs, s (NaN when there are none).

    Notes
    -----
    A delay between two sensors equals the difference of their arrival times, so the three
    delays of a triangle of sensors sum to zero whatever the source. Greedily, the TDOA with
    the largest share of failing triangles (over half of them) is dropped and the rest
    re-checked.
    """
    pr = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
    tau = np.asarray(taus, dtype=float)
    sig = np.asarray(sigmas, dtype=float)
    keep = np.asarray(usable, dtype=bool).copy()
    index = {}
    for k, (i, j) in enumerate(pr):
        index[(int(i), int(j))] = (k, 1.0)
        index[(int(j), int(i))] = (k, -1.0)
    nodes = sorted({int(v) for v in pr.ravel()})
    triangles = []
    for a, b, cc in combinations(nodes, 3):
        legs = [index.get(e) for e in ((a, b), (b, cc), (a, cc))]
        if all(leg is not None for leg in legs):
            triangles.append(legs)

    def closures(mask: NDArray[np.bool_]) -> tuple[list, NDArray, NDArray]:
        live = [t for t in triangles if all(mask[k] for k, _ in t)]
        e = np.array([t[0][1] * tau[t[0][0]] + t[1][1] * tau[t[1][0]] - t[2][1] * tau[t[2][0]]
                      for t in live])  # tau_ab + tau_bc - tau_ac
        s = np.array([np.sqrt(sum(sig[k] ** 2 for k, _ in t)) for t in live])
        return live, e, s

    live, e, _ = closures(keep)
    rms = float(np.sqrt(np.mean(e**2))) if len(live) else float("nan")
    n_sensors = max(nodes) + 1 if nodes else 0
    while True:
        live, e, s = closures(keep)
        if not live:
            break
        fail = np.abs(e) > n_sigma * s
        bad, total = np.zeros(pr.shape[0]), np.zeros(pr.shape[0])
        for t, f in zip(live, fail, strict=True):
            for k, _ in t:
                total[k] += 1
                bad[k] += f
        share = np.where(total > 0, bad / np.maximum(total, 1), 0.0)
        worst = int(np.argmax(share))
        if share[worst] <= 0.5:
            break
        trial = keep.copy()
        trial[worst] = False
        inc = np.zeros((int(trial.sum()), n_sensors))
        for row, (i, j) in enumerate(pr[trial]):
            inc[row, i], inc[row, j] = 1.0, -1.0
        if inc.shape[0] == 0 or np.linalg.matrix_rank(inc) < min_rank:
            break
        logger.debug("closure: pair %s set aside (%.0f%% of its triangles fail)",
                     tuple(pr[worst]), 100 * share[worst])
        keep = trial
    return keep, rms
