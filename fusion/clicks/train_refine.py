"""A train-integrated delay refined on the waveforms: the click train's cross-spectra summed.

Train integration (:mod:`fusion.clicks.train_integration`) reads a weak sensor's delay off the
detection statistic's frames (62.5 us apart, smoothed over the 250-us STFT): to 2-20 us on the
15-dB tuning windows. Its clicks are too weak for the per-click delays of
:class:`fusion.clicks.tdoa.TdoaRefiner` (0 dB or less a click), but their sum is not. Each
reference click ``t_n`` of sensor i and the weak sensor k's audio at the delay's prediction
``t_n + d + r (t_n - t_c)`` are cut (``+-half_window_s``), and their in-band cross-spectra
``C_n(f) = conj(X_i) X_k``, each scaled by the cuts' energies (a correlation coefficient: a loud
transient or another source's click weighs no more than a click of the train), are summed
coherently along a correction of the delay, drift and curvature ``a``:

    ``A(dd, dr, a) = sum_n sum_f C_n(f) exp(j w (b_n + dd + dr u_n + a u_n^2 / 2))``,
    ``u_n = t_n - t_c``,

``b_n`` the cuts' rounding residual. The envelope ``|A|`` picks the correction (immune to carrier
cycles), the real part's peak within half a carrier period of it (on a 1-us grid and a parabola)
gives the delay. Its noise: the same sum with the clicks' signs drawn at random (the train's
coherence gone, its noise kept), ``sd``; the refinement is kept where the envelope stands
`min_snr` sds above it, with ``sigma = 1 / (w_rms |A| / sd)`` (the correlation peak's
curvature ``|A| w_rms^2`` against its slope's noise ``sd w_rms``).

An addition to *Localization of Short Duration Periodic Signals* (Baggenstoss, NUWC 102089);
``docs/localization.md`` section 23.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike

from fusion.clicks._scm_grid import parabolic

__all__ = ["TrainRefinement", "refine_train_delay"]


@dataclass(frozen=True)
class TrainRefinement:
    """A delay refined on the waveforms (``t_k - t_i`` at `t_c_s` on sensor i's clock)."""

    delay_s: float
    rate: float
    sigma_s: float
    snr: float
    n_clicks: int


def refine_train_delay(
    audio: ArrayLike,
    fs: float,
    pair: tuple[int, int],
    ref_times_s: ArrayLike,
    delay_s: float,
    rate: float,
    t_c_s: float,
    *,
    audio_t0_s: float = 0.0,
    band_hz: tuple[float, float] = (20e3, 46e3),
    half_window_s: float = 4e-4,
    search_s: float = 1.25e-4,
    rate_half_width: float = 1.5e-5,
    max_accel: float = 2e-6,
    min_snr: float = 5.0,
    seed: int = 0,
) -> TrainRefinement | None:
    """The delay ``t_k - t_i`` of `pair` ``(i, k)`` refined on the waveforms (module notes).

    Parameters
    ----------
    audio : array_like, shape (n, channels)
    fs : float
        Sample rate, Hz.
    pair : (int, int)
        Reference channel i and weak channel k.
    ref_times_s : array_like
        The reference train's click times on sensor i, s.
    delay_s, rate : float
        The delay at `t_c_s` and its drift to refine (train integration's).
    t_c_s : float
        Reference time, s.
    audio_t0_s : float, optional
        Time of ``audio[0]``, s.
    band_hz : (float, float), optional
        Band of the correlation, Hz.
    half_window_s : float, optional
        Half length of each cut, s.
    search_s : float, optional
        Largest delay correction, s.
    rate_half_width : float, optional
        Largest drift correction, s/s (in steps that move the end clicks by a fifth of a
        carrier period).
    max_accel : float, optional
        Largest curvature of the delay searched, s/s^2 (a turning whale; steps as the
        drift's): the delay at `t_c_s` of a train fitted by a straight line is off by its
        curvature's mean.
    min_snr : float, optional
        The envelope's least height over the random-sign sums' sd.
    seed : int, optional
        Seed of the random signs.

    Returns
    -------
    TrainRefinement or None
        None where fewer than four clicks are inside the audio, the band holds too few
        bins, the correction is at the edge of its search or below `min_snr`.
    """
    x = np.asarray(audio)
    i, k = pair
    h = max(int(math.ceil(half_window_s * fs)), 2)
    ti = np.sort(np.asarray(ref_times_s, dtype=float).ravel())
    u = ti - t_c_s
    tk = ti + delay_s + rate * u
    ai = np.round((ti - audio_t0_s) * fs).astype(np.int64) - h
    ak = np.round((tk - audio_t0_s) * fs).astype(np.int64) - h
    ok = (np.minimum(ai, ak) >= 0) & (np.maximum(ai, ak) + 2 * h <= x.shape[0])
    if ok.sum() < 4:
        return None
    ai, ak, u = ai[ok], ak[ok], u[ok]
    nfft = scipy.fft.next_fast_len(4 * h, real=True)
    f = np.fft.rfftfreq(nfft, 1.0 / fs)
    band = np.flatnonzero((f >= band_hz[0]) & (f <= band_hz[1]) & (f > 0))
    if band.size < 4:
        return None
    w = 2.0 * np.pi * f[band]
    idx = np.arange(2 * h)
    seg_i = np.asarray(x[ai[:, None] + idx, i], dtype=float)
    seg_k = np.asarray(x[ak[:, None] + idx, k], dtype=float)
    xi = scipy.fft.rfft(seg_i, nfft, axis=-1)[:, band]
    xk = scipy.fft.rfft(seg_k, nfft, axis=-1)[:, band]
    norm = np.sqrt(np.sum(np.abs(xi) ** 2, axis=1) * np.sum(np.abs(xk) ** 2, axis=1))
    c = np.conj(xi) * xk / np.maximum(norm, 1e-300)[:, None]  # (n, band)
    # cut k starts at (ak - ai) / fs after cut i: the delay is that plus the correlation lag
    base = (delay_s + rate * u) - (ak - ai) / fs  # the prediction's lag within the cuts
    dd = np.arange(-search_s, search_s + 0.5e-6, 1e-6)
    p_c = np.abs(c.sum(axis=0)) + np.abs(c).sum(axis=0) + 1e-300
    f_c = float(np.sum(f[band] * p_c) / p_c.sum())
    span = max(float(np.max(np.abs(u))), 1e-3)
    n_dr = int(math.ceil(rate_half_width * span * f_c / 0.2))  # a fifth of a period at the ends
    drs = np.linspace(-rate_half_width, rate_half_width, 2 * n_dr + 1)
    n_acc = int(math.ceil(max_accel * span * span / 2.0 * f_c / 0.2))
    accs = np.linspace(-max_accel, max_accel, 2 * n_acc + 1) if n_acc else np.zeros(1)
    grid = [(dr, acc) for acc in accs for dr in drs]
    coarse = dd[::4]  # the envelope is smooth over the band's inverse width (~40 us)
    # separable phases: exp(j w (b_n + dr u_n + acc u_n^2 / 2)), summed over the clicks
    p0 = c * np.exp(1j * w[None, :] * base[:, None])  # (n, band)
    e_acc = np.exp(1j * w[None, None, :] * (0.5 * accs[:, None, None] * (u * u)[None, :, None]))
    e_dr = np.exp(1j * w[None, None, :] * (drs[:, None, None] * u[None, :, None]))

    def spectra(signs):
        """Summed cross-spectra at every (curvature, drift) cell with the clicks' `signs`:
        (cells, band), cells in the order of `grid`."""
        return np.einsum("anf,dnf->adf", (signs[:, None] * p0)[None] * e_acc,
                         e_dr).reshape(-1, w.size)

    s_all = spectra(np.ones(u.size))
    env = np.abs(s_all @ np.exp(1j * np.outer(w, coarse)))
    q, jc = np.unravel_index(int(np.argmax(env)), env.shape)
    a_q = s_all[q] @ np.exp(1j * np.outer(w, dd))  # the best cell on the fine grid
    j = int(np.argmax(np.abs(a_q)))
    if j in (0, dd.size - 1):
        return None
    rng = np.random.default_rng(seed)
    aq, dq = divmod(int(q), drs.size)  # grid is curvature-major
    null = []
    for _ in range(16):
        sg = rng.choice([-1.0, 1.0], u.size)
        sq = ((sg[:, None] * p0) * e_acc[aq] * e_dr[dq]).sum(axis=0)
        null.append(np.mean(np.abs(sq @ np.exp(1j * np.outer(w, coarse))) ** 2))
    sd = float(np.sqrt(np.mean(null) / 2.0))  # a complex Gaussian's sd per component
    snr = float(np.abs(a_q[j])) / max(sd, 1e-300)
    if snr < min_snr:
        return None
    # the real part's peak within half a carrier period of the envelope's
    w_rms = 2.0 * np.pi * math.sqrt(float(np.sum(f[band] ** 2 * p_c) / p_c.sum()))
    re = a_q.real
    lo = max(1, j - int(0.5 / f_c / 1e-6))
    hi = min(dd.size - 1, j + int(0.5 / f_c / 1e-6) + 1)
    jr = lo + int(np.argmax(re[lo:hi]))
    corr = float(dd[jr])
    if 0 < jr < dd.size - 1:
        corr += float(parabolic(re[jr - 1], re[jr], re[jr + 1])[0]) * 1e-6
    sigma = max(1.0 / (w_rms * snr), 0.2e-6)
    return TrainRefinement(delay_s=float(delay_s + corr), rate=float(rate + grid[q][0]),
                           sigma_s=float(sigma), snr=snr, n_clicks=int(u.size))
