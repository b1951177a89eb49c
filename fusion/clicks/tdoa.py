"""Precise TDOAs from the click waveforms a pair matched, with their uncertainty and CRB.

The smoothed click maps (:mod:`fusion.clicks.scm`) give a coarse TDOA on a 3 kHz grid and, through
the SCM2, the clicks of one source seen on both sensors of a pair. This stage measures the delay
of every matched click pair from the raw waveforms to a small fraction of an audio sample, fits
the delays over the window (the source moves: the TDOA drifts by up to ``2 v / c``, about 1-3 ms
per second for a whale at 1-2 m/s) and states the uncertainty of the result, from the data, beside
its Cramér-Rao bound. It is an addition to *Localization of Short Duration Periodic Signals*
(Baggenstoss, NUWC 102089), whose TDOAs stay on the SCM grid.

Examples
--------
>>> from fusion.simulate.clicks import ClickWaveform
>>> fs, click = 96_000.0, ClickWaveform()
>>> t = np.arange(int(0.5 * fs)) / fs
>>> ti = np.array([0.1, 0.2, 0.3, 0.4])
>>> tj = ti - 12.3456e-6  # a delay of 1.185 samples
>>> audio = np.stack([sum(click.evaluate(t - x) for x in ti),
...                   sum(click.evaluate(t - x) for x in tj)], axis=1)
>>> audio += 0.01 * np.random.default_rng(0).standard_normal(audio.shape)
>>> res = TdoaRefiner(fs_hz=fs).refine(audio, (0, 1), ti, tj)
>>> round(res.tau_s * 1e6, 2), res.n_clicks_used
(12.35, 4)
"""

from __future__ import annotations

import copy
import logging

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray

from fusion._validation import check_positive
from fusion.clicks._tdoa_stats import cycle_contrast, gamma_median, rms_frequency_hz, tdoa_crb_s
from fusion.clicks.delaytrack import consensus_inliers, fit_delays, shift_matrix
from fusion.clicks.tdoa_types import RefinedTdoa
from fusion.clicks.types import frozen_array

__all__ = ["RefinedTdoa", "TdoaRefiner", "rms_frequency_hz", "tdoa_crb_s"]

logger = logging.getLogger(__name__)


class TdoaRefiner:
    """Measure a pair's TDOA from the waveforms of its matched clicks.

    Parameters
    ----------
    fs_hz : float
        Audio sample rate, Hz.
    band_hz : (float, float), optional
        Band of the correlation and of the noise and SNR measurement, Hz; default 20-46 kHz
        (the 20 kHz centre-frequency screen of [0031] up to just below 48 kHz).
    half_window_s : float, optional
        Half length of the waveform cut around each detected click, s; default 0.4 ms (the
        click plus the detection time error).
    max_lag_s : float, optional
        Largest correction to the detected delay ``t_i(n) - t_j(n)`` searched, s; default
        0.25 ms. At most `half_window_s`.
    min_snr_db : float, optional
        Clicks whose measured energy-to-noise ratio is below this on either channel are left
        out, dB; default 8 (below it a click rarely helps: its correlation peak is lost in
        the fine-structure ambiguity).
    max_degree : int, optional
        Highest degree of the polynomial drift of the TDOA over the window, 0 to 3; default 2
        (a source at 1-2 m/s about 1 km from the sensors bends its TDOA by several
        microseconds over a 12 s window, more than the per-click precision).
    outlier_z : float, optional
        Per-click delays further than this many (scatter-inflated) standard deviations from a
        consensus fit are rejected before the final fit; default 4.
    max_rate : float, optional
        Largest TDOA drift considered by the consensus fit, s/s; default 0.004 (``2 v / c``
        for a source at 3 m/s in water).
    slip_periods : float, optional
        Clicks whose first delay estimate lies within this many carrier periods (``1 / beta``)
        of the consensus track are re-measured at the correlation peak nearest the track
        (a cycle slip resolved); those further away are mismatched pairs and left out;
        default 2.5.
    max_accel : float, optional
        Largest TDOA curvature ``|d^2 tau / dt^2|`` considered by the consensus fit, s/s^2;
        default 5e-5 (3 m/s at 240 m from a sensor).
    replica : array_like, shape (m,), optional
        Click waveform sampled at `fs_hz` for the RMS frequency of the bound; default: the
        noise-subtracted power spectrum of the clicks themselves.
    n_noise_segments : int, optional
        Noise-only cuts per channel for the noise level, default 64.
    upsample : int, optional
        Upsampling of the correlation before the Newton refinement of its peak, default 8.

    Notes
    -----
    Per matched click ``n``: cut ``2 h`` samples centred on the detected time on each
    channel, correlate them in the frequency domain over `band_hz` (zero-padded: no
    wrap-around), take the peak of the upsampled correlation within `max_lag_s` and refine it
    to the maximum of the band-limited continuous correlation
    ``r(tau) = Re sum_k X_i(k) conj(X_j(k)) exp(j 2 pi f_k tau)`` by Newton steps. The delay is
    ``d_n = (a_i - a_j) / fs + tau_n`` with ``a`` the first sample of each cut.

    SNR and bound, from the data only: the noise variance per channel is the median (corrected
    for the median of a gamma variate) of the in-band power of `n_noise_segments` cuts spread
    over the span of the clicks and at least 2 ms from any of them; a click's energy is its
    in-band energy minus the expected noise part. Each click gets the bound of
    :func:`tdoa_crb_s` at its two measured energy-to-noise ratios.

    Cycle slips. The click's correlation has fine structure one carrier period ``1 / beta``
    apart (side peaks 0.81 of the main one for the simulated 25-45 kHz click), so below about
    20 dB a click's peak is often one period off. The first delays are fitted by a consensus
    polynomial track (:func:`fusion.clicks.delaytrack.consensus_inliers`); clicks within
    `slip_periods` periods of it are re-measured at their peak nearest the track, on the
    carrier cycle (the track shifted by -2 .. 2 periods) that maximises the summed
    correlation; clicks further off are mismatched pairs and dropped. A paired one-sided
    t-test over the clicks (at 1 %) of the relative correlation at the chosen cycle against
    the cycles either side decides whether the cycle is resolved (and the track is trusted
    only if it keeps at least half of the screened clicks).

    Combination (:func:`fusion.clicks.delaytrack.fit_delays`): a second consensus drops the
    remaining outliers; then weighted least squares of ``d_n = sum_k c_k (t_n - t_ref)^k``
    with weights ``1 / crb_n^2``, ``t_ref`` the weighted centroid of the click times,
    raising the degree from 0 while that lowers chi-square by more than 6.63 (a
    likelihood-ratio test at 1 %; the sigmas are known). ``crb_s`` is the standard deviation
    of the fitted TDOA at the reference time from the bounds of the clicks
    (``1 / sum_n crb_n^-2`` for a constant or linear fit at the centroid).

    Reported standard deviation: ``sigma = crb_s * max(1, birge)`` with
    ``birge = sqrt(chi2 / dof)``: the bound when the per-click delays scatter as it predicts,
    larger when they scatter more (overlaps, multipath, an unmodelled drift). A scatter-only
    estimate from 3-5 clicks is itself uncertain by 30-50 %, which the bound at the measured
    SNR is not. When the cycle is not resolved, one period and the robust scatter of the
    first delays of all screened clicks about the track (over the square root of the clicks
    used) are added in quadrature: such a TDOA is known to tens of microseconds, not to the
    bound.
    """

    def __init__(
        self,
        *,
        fs_hz: float,
        band_hz: tuple[float, float] = (20_000.0, 46_000.0),
        half_window_s: float = 4e-4,
        max_lag_s: float = 2.5e-4,
        min_snr_db: float = 8.0,
        max_degree: int = 2,
        outlier_z: float = 4.0,
        max_rate: float = 0.004,
        max_accel: float = 5e-5,
        slip_periods: float = 2.5,
        replica: ArrayLike | None = None,
        n_noise_segments: int = 64,
        upsample: int = 8,
    ) -> None:
        self.fs_hz = check_positive("fs_hz", fs_hz)
        lo, hi = (float(b) for b in band_hz)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi <= 0.5 * self.fs_hz):
            raise ValueError(f"band_hz must satisfy 0 <= low < high <= fs/2, got {band_hz!r}")
        self.band_hz = (lo, hi)
        self.half_window_s = check_positive("half_window_s", half_window_s)
        self.max_lag_s = check_positive("max_lag_s", max_lag_s)
        if self.max_lag_s > self.half_window_s:
            raise ValueError(f"max_lag_s={max_lag_s!r} exceeds half_window_s={half_window_s!r}")
        if not np.isfinite(min_snr_db):
            raise ValueError(f"min_snr_db must be finite, got {min_snr_db!r}")
        self.min_snr_db = float(min_snr_db)
        if isinstance(max_degree, bool) or int(max_degree) != max_degree or not 0 <= max_degree <= 3:
            raise ValueError(f"max_degree must be an integer from 0 to 3, got {max_degree!r}")
        self.max_degree = int(max_degree)
        self.outlier_z = check_positive("outlier_z", outlier_z)
        self.max_rate = check_positive("max_rate", max_rate)
        self.max_accel = check_positive("max_accel", max_accel)
        self.slip_periods = check_positive("slip_periods", slip_periods)
        self.replica = None if replica is None else np.asarray(replica, dtype=float).ravel()
        for name, v, lo_v in (("n_noise_segments", n_noise_segments, 4), ("upsample", upsample, 1)):
            if isinstance(v, bool) or int(v) != v or v < lo_v:
                raise ValueError(f"{name} must be an integer >= {lo_v}, got {v!r}")
        self.n_noise_segments = int(n_noise_segments)
        self.upsample = int(upsample)
        self._h = max(int(np.ceil(self.half_window_s * self.fs_hz)), 2)
        self._nfft = scipy.fft.next_fast_len(4 * self._h, real=True)
        f = np.fft.rfftfreq(self._nfft, 1.0 / self.fs_hz)
        self._band = np.flatnonzero((f >= lo) & (f <= hi) & (f > 0) & (f < 0.5 * self.fs_hz))
        if self._band.size < 2:
            raise ValueError(f"band_hz {band_hz!r} holds fewer than 2 frequency bins")
        self._f = f[self._band]
        self._w = 2.0 * np.pi * self._f
        n_up = self.upsample * self._nfft
        self._roots = np.exp(2j * np.pi * np.arange(n_up) / n_up)  # exp(j w_k tau) on the grid
        self._memo: _CutMemo | None = None

    def remember_cuts(self) -> TdoaRefiner:
        """Keep the spectra of the click cuts and the correlations of the cut pairs, by
        recording sample, for later calls on the same recording (a new refiner: this one
        unchanged).

        A click is cut in every pair of its sensor and every window it falls in (about 6 at
        the default window and hop): its spectrum and the correlation of each cut pair are
        then computed once. Each row of a batched FFT is the FFT of that row alone, so the
        results are the same to the bit. Valid while every call reads the same recording with
        ``audio_t0_s`` on its sample grid; :meth:`forget_before` drops what is no longer
        needed.
        """
        out = copy.copy(self)
        out._memo = _CutMemo()
        return out

    def forget_before(self, sample: int) -> None:
        """Drop the remembered cuts starting before recording sample `sample`."""
        if self._memo is not None:
            self._memo.forget_before(int(sample))

    # ------------------------------------------------------------------------------------------
    def refine(
        self,
        audio: ArrayLike,
        pair: tuple[int, int],
        times_i: ArrayLike,
        times_j: ArrayLike,
        *,
        audio_t0_s: float = 0.0,
        reference_time_s: float | None = None,
    ) -> RefinedTdoa | None:
        """Sub-sample TDOA of `pair` from matched click pairs.

        Parameters
        ----------
        audio : array_like, shape (n_samples, n_channels)
            Audio (raw or replica-correlated) of every channel; sample 0 at `audio_t0_s`.
        pair : (int, int)
            Sensor (channel) indices ``(i, j)``.
        times_i, times_j : array_like, shape (n,)
            Matched click times on sensors ``i`` and ``j``, s from the start of the audio
            (``times_j[n]`` is the same emission as ``times_i[n]``): the SCM2 matches
            (:attr:`fusion.clicks.scm.Scm2.index_i`, ``index_j``), best extended through the
            window by :func:`fusion.clicks.delaytrack.match_along_track`.
        audio_t0_s : float, optional
            Time of the first sample of `audio`, s.
        reference_time_s : float, optional
            Report the TDOA at this time on sensor ``i``'s clock (e.g. the window centre);
            default the weighted centroid of the clicks used.

        Returns
        -------
        RefinedTdoa or None
            None when no matched click pair lies inside the audio and passes the SNR screen.
        """
        x = np.asarray(audio)  # no copy: cuts are converted to float64 one by one
        if x.ndim != 2:
            raise ValueError(f"audio must have shape (n_samples, n_channels), got {x.shape}")
        i, j = (int(p) for p in pair)
        if i == j or not (0 <= i < x.shape[1] and 0 <= j < x.shape[1]):
            raise ValueError(f"pair {pair!r} must name two different channels of {x.shape[1]}")
        ti = np.asarray(times_i, dtype=float).ravel()
        tj = np.asarray(times_j, dtype=float).ravel()
        if ti.shape != tj.shape or not (np.all(np.isfinite(ti)) and np.all(np.isfinite(tj))):
            raise ValueError("times_i and times_j must be finite and of one length")
        fs, h = self.fs_hz, self._h
        ai = np.round((ti - audio_t0_s) * fs).astype(np.int64) - h  # first sample of each cut
        aj = np.round((tj - audio_t0_s) * fs).astype(np.int64) - h
        inside = (np.minimum(ai, aj) >= 0) & (np.maximum(ai, aj) + 2 * h <= x.shape[0])
        ti, ai, aj = ti[inside], ai[inside], aj[inside]
        tj = tj[inside]
        if ti.size == 0:
            return None
        memo, first = self._memo, None
        if memo is not None:  # the cuts by recording sample (audio_t0_s on the sample grid)
            first = int(round(audio_t0_s * fs))
            if abs(first - audio_t0_s * fs) > 1e-6:
                memo, first = None, None
        spec_i = self._spectra(x[:, i], ai, memo, i, first)  # (n, n_band)
        spec_j = self._spectra(x[:, j], aj, memo, j, first)
        var_i = self._noise_var(x[:, i], ai)
        var_j = self._noise_var(x[:, j], aj)
        enr_i, enr_j = self._enr(spec_i, var_i), self._enr(spec_j, var_j)
        beta = self._rms_freq(spec_i, spec_j, var_i, var_j)
        ok = np.minimum(enr_i, enr_j) >= 10.0 ** (self.min_snr_db / 10.0)
        if not np.any(ok):
            logger.debug("pair %s: no matched click above %.1f dB", pair, self.min_snr_db)
            return None
        ti, base = ti[ok], (ai[ok] - aj[ok]) / fs  # delay of cut j relative to cut i
        g, r_up = self._correlate(spec_i[ok], spec_j[ok], None if memo is None else (
            memo, (i, j), ai[ok] + first, aj[ok] + first))
        delays = base + self._peak(g, r_up, np.zeros(base.size), self.max_lag_s)[0]
        sig = tdoa_crb_s(beta, enr_i[ok], enr_j[ok])
        enr_eff = 2.0 / (1.0 / enr_i[ok] + 1.0 / enr_j[ok])
        # cycle slips: re-pick each click's correlation peak nearest the consensus track, on
        # the carrier cycle of the track that maximises the summed correlation
        keep = consensus_inliers(ti, delays, sig, max_degree=self.max_degree,
                                 outlier_z=self.outlier_z, max_rate=self.max_rate,
                                 max_accel=self.max_accel)
        first_pass = (ti, delays)
        if keep.sum() >= 2:
            coef, _, t_ref, _ = fit_delays(ti[keep], delays[keep], sig[keep],
                                           max_degree=self.max_degree)
            pred = ((ti - t_ref)[:, None] ** np.arange(coef.size)) @ coef
            near = np.abs(delays - pred) <= self.slip_periods / beta
            near &= np.abs(pred - base) <= self.max_lag_s + 0.5 / beta
            if not near.any():
                return None
            ks = np.arange(-3, 4)  # the track and its neighbours one carrier cycle apart
            rows = np.tile(np.flatnonzero(near), ks.size)
            centre = (pred[near] - base[near])[None, :] + ks[:, None] / beta
            lag, val = self._peak(g, r_up, centre.ravel(), 0.5 / beta, rows)
            lags, v = lag.reshape(ks.size, -1), val.reshape(ks.size, -1)  # (7, n_near)
            kb = 1 + int(np.argmax(v[1:-1].sum(axis=1)))  # best of k = -2 .. 2
            # relative contrast per click: the clicks' energies differ, their peak shape not
            scale = np.maximum(np.abs(v[kb]), 1e-300)
            contrast = np.stack([v[kb] - v[kb - 1], v[kb] - v[kb + 1]], axis=1) / scale[:, None]
            ti, delays, sig, enr_eff = ti[near], base[near] + lags[kb], sig[near], enr_eff[near]
        else:
            contrast = np.zeros((ti.size, 2))
        period = 1.0 / beta
        return self._combine((i, j), ti, delays, sig, enr_eff, reference_time_s, contrast, period,
                             first_pass)

    # ------------------------------------------------------------------------------------------
    def _spectra(self, x: NDArray, starts: NDArray, memo: _CutMemo | None = None,
                 channel: int = 0, first: int | None = None) -> NDArray[np.complex128]:
        """In-band spectra of the cuts ``x[a : a + 2h]``, zero-padded to the FFT length (with
        `memo`: those of channel `channel` remembered by recording sample ``first + a``)."""
        def full(rows: NDArray) -> NDArray[np.complex128]:
            seg = np.asarray(x[starts[rows, None] + np.arange(2 * self._h)], dtype=float)
            return scipy.fft.rfft(seg, self._nfft, axis=-1)

        if memo is None or first is None:
            return full(np.arange(starts.size))[:, self._band]
        keys = [(channel, int(a) + first) for a in starts]
        # whole spectra kept and the band taken as a view, as above: the same memory layout
        # (contiguous in-band rows gave results that differed in the last bit)
        return memo.rows(memo.spectra, keys, full)[:, self._band]

    def _noise_var(self, x: NDArray, click_starts: NDArray) -> float:
        """White-equivalent noise variance per sample in the band, from cuts away from clicks."""
        n2, fs = 2 * self._h, self.fs_hz
        span = int(0.5 * fs)
        lo = max(int(click_starts.min()) - span, 0)
        hi = min(int(click_starts.max()) + span, x.shape[0] - n2)
        if hi <= lo:
            lo, hi = 0, x.shape[0] - n2
        starts = np.unique(np.linspace(lo, max(hi, lo), 4 * self.n_noise_segments).astype(np.int64))
        centres = click_starts + self._h
        gap = np.abs(starts[:, None] + self._h - centres[None, :]).min(axis=1)
        free = starts[gap >= self._h + int(2e-3 * fs)][:: 4 if starts.size > 4 else 1]
        if free.size < 4:
            free = starts
        power = np.mean(np.abs(self._spectra(x, free)) ** 2, axis=1)  # E = n2 * sigma^2 per bin
        # median of a mean of n_eff independent exponential bins: gamma(n_eff) / n_eff
        n_eff = max((self.band_hz[1] - self.band_hz[0]) * n2 / fs, 1.0)
        med = gamma_median(n_eff) / n_eff
        return float(np.median(power) / med / n2)

    def _enr(self, spec: NDArray, var: float) -> NDArray[np.float64]:
        """Energy-to-noise ratio of each cut: in-band energy minus its expected noise part."""
        n2 = 2 * self._h
        # Parseval, one-sided and zero-padded: E = (2 / nfft) sum_band |X_k|^2
        energy = 2.0 / self._nfft * np.sum(np.abs(spec) ** 2, axis=1)
        noise = 2.0 * self._band.size * n2 / self._nfft * var
        return np.maximum(energy - noise, 1e-12 * var) / var

    def _rms_freq(self, si: NDArray, sj: NDArray, vi: float, vj: float) -> float:
        """RMS frequency of the replica, or of the noise-subtracted click spectra."""
        if self.replica is not None:
            p = np.abs(scipy.fft.rfft(self.replica, max(self._nfft, self.replica.size)))
            f = np.fft.rfftfreq(max(self._nfft, self.replica.size), 1.0 / self.fs_hz)
            band = (f >= self.band_hz[0]) & (f <= self.band_hz[1])
            return rms_frequency_hz(p[band] ** 2, f[band])
        n2 = 2 * self._h
        p = np.sum(np.abs(si) ** 2 - n2 * vi, axis=0) + np.sum(np.abs(sj) ** 2 - n2 * vj, axis=0)
        p = np.maximum(p, 0.0)
        if not np.sum(p) > 0:
            return rms_frequency_hz(np.ones(self._f.size), self._f)
        return rms_frequency_hz(p, self._f)

    def _correlate(self, si: NDArray, sj: NDArray, memo: tuple | None = None
                   ) -> tuple[NDArray, NDArray]:
        """In-band cross-spectra and the upsampled cross-correlations of the cut pairs (with
        `memo`, ``(memo, pair, first samples i, first samples j)``: the correlations
        remembered by pair and recording samples)."""
        g = si * np.conj(sj)  # the transform of g peaks at the delay of cut i after cut j

        def upsampled(rows: NDArray) -> NDArray:
            full = np.zeros((rows.size, self._nfft // 2 + 1), dtype=complex)
            full[:, self._band] = g[rows]
            return scipy.fft.irfft(full, self.upsample * self._nfft, axis=-1)

        if memo is None:
            return g, upsampled(np.arange(g.shape[0]))
        store, pair, a_i, a_j = memo
        keys = [(*pair, int(p), int(q)) for p, q in zip(a_i, a_j, strict=True)]
        return g, store.rows(store.correlations, keys, upsampled)

    def _peak(self, g: NDArray, r_up: NDArray, centre_s: NDArray, halfwidth_s: float,
              rows: NDArray | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Maximum of each correlation within ``centre +- halfwidth``: lag (s, Newton-refined)
        and value ``Re sum_k g_k exp(j w_k tau)``; of the rows `rows` of `g` and `r_up` (default
        all, one centre each)."""
        fs, up = self.fs_hz, self.upsample
        n_up = r_up.shape[1]
        rr = np.arange(g.shape[0]) if rows is None else rows
        q = int(np.floor(halfwidth_s * fs * up))
        c = np.round(centre_s * fs * up).astype(np.int64)
        lags = c[:, None] + np.arange(-q, q + 1)  # (n, 2q + 1) in upsampled samples
        vals = r_up[rr[:, None], np.mod(lags, n_up)]
        best = lags[np.arange(lags.shape[0]), np.argmax(vals, axis=1)]
        tau = best / (up * fs)
        gg = g[rr]
        # exp(j w_k tau) on the upsampled grid: roots of unity of order n_up (w_k tau = 2 pi k b / n_up)
        rot = self._roots[np.mod(np.multiply.outer(best, self._band), n_up)]
        w, w2 = self._w, self._w * self._w
        step_max = 1.0 / (up * fs)
        active = slice(None)  # rows still moving: all, then an index array
        for _ in range(4):  # Newton on r(tau) = Re sum_k g_k exp(j w_k tau)
            z = gg[active] * rot[active]
            d1 = -(z.imag @ w)
            d2 = -(z.real @ w2)
            step = np.clip(np.where(d2 < 0, -d1 / np.where(d2 < 0, d2, -1.0), 0.0),
                           -step_max, step_max)
            tau[active] += step
            # exp(j w_k step) = exp(j w_0 step) exp(j dw step)^k on the uniform frequency grid
            powers = np.empty((step.size, w.size), dtype=complex)
            powers[:, 0] = np.exp(1j * w[0] * step)
            powers[:, 1:] = np.exp(1j * (w[1] - w[0]) * step)[:, None]
            rot[active] *= np.cumprod(powers, axis=1)
            moving = np.abs(step) > 1e-7 * step_max  # the others have converged
            if not moving.any():
                break
            if not moving.all():
                active = np.arange(tau.size)[active][moving]
        val = np.sum(gg.real * rot.real - gg.imag * rot.imag, axis=1)
        return tau, val

    def _combine(self, pair: tuple[int, int], t: NDArray, d: NDArray, sig: NDArray,
                 enr: NDArray, t_req: float | None, contrast: NDArray,
                 period: float, first_pass: tuple[NDArray, NDArray]) -> RefinedTdoa:
        """Robust polynomial fit of the per-click delays; the TDOA at the reference time."""
        keep = consensus_inliers(t, d, sig, max_degree=self.max_degree, outlier_z=self.outlier_z,
                                 max_rate=self.max_rate, max_accel=self.max_accel)
        tk, dk, sk = t[keep], d[keep], sig[keep]
        coef, cov, t_ref, birge = fit_delays(tk, dk, sk, max_degree=self.max_degree)
        # scatter of the first (slip-prone) delays of every screened click about the track
        t1, d1 = first_pass
        track1 = ((t1 - t_ref)[:, None] ** np.arange(coef.size)) @ coef
        spread = 1.4826 * float(np.median(np.abs(d1 - track1)))
        if t_req is not None:  # re-expand the polynomial about the requested time
            shift = shift_matrix(coef.size, float(t_req) - t_ref)
            coef, cov, t_ref = shift @ coef, shift @ cov @ shift.T, float(t_req)
        crb = float(np.sqrt(cov[0, 0]))
        cycle_t = cycle_contrast(contrast[keep, 0], contrast[keep, 1])
        # a track is trusted only if it explains most of the screened clicks
        cycle_t = (cycle_t[0], cycle_t[1] and int(keep.sum()) >= 0.6 * first_pass[0].size)
        sigma = crb * (max(1.0, birge) if np.isfinite(birge) else 1.0)
        if not cycle_t[1]:  # carrier cycle, maybe the track itself, not resolved
            sigma = float(np.sqrt(sigma**2 + period**2 + spread**2 / keep.sum()))
        return RefinedTdoa(
            pair=pair, tau_s=float(coef[0]), sigma_s=sigma, cycle_t=cycle_t[0],
            cycle_resolved=cycle_t[1], period_s=float(period),
            t_ref_s=t_ref, rate=float(coef[1]) if coef.size > 1 else 0.0,
            n_clicks_used=int(keep.sum()), n_clicks_screened=t1.size,
            snr_db=float(10.0 * np.log10(np.median(enr[keep]))),
            crb_s=crb, birge=birge, coef=frozen_array(coef), coef_cov=frozen_array(cov),
            click_times_s=frozen_array(tk), click_delays_s=frozen_array(dk),
            click_sigma_s=frozen_array(sk),
        )


class _CutMemo:
    """Spectra of click cuts and correlations of cut pairs, by recording sample
    (:meth:`TdoaRefiner.remember_cuts`)."""

    def __init__(self) -> None:
        self.spectra: dict[tuple[int, int], NDArray] = {}  # (channel, first sample)
        self.correlations: dict[tuple[int, int, int, int], NDArray] = {}  # (i, j, a_i, a_j)

    @staticmethod
    def rows(table: dict, keys: list, compute) -> NDArray:
        """The rows of `keys`, those not in `table` computed (one batch) and kept:
        ``compute(index array of the missing keys)`` gives their rows."""
        missing = [k for k, key in enumerate(keys) if key not in table]
        if missing:
            new = compute(np.array(missing, dtype=np.intp))
            for k, row in zip(missing, new, strict=True):
                table[keys[k]] = row
        return np.stack([table[key] for key in keys]) if keys else compute(
            np.zeros(0, dtype=np.intp))

    def forget_before(self, sample: int) -> None:
        for key in [k for k in self.spectra if k[1] < sample]:
            del self.spectra[key]
        for key in [k for k in self.correlations if min(k[2], k[3]) < sample]:
            del self.correlations[key]
