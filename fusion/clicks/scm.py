"""Smoothed click maps (SCM1), their correlation, TDOA candidate peaks and SCM2.

Implements steps 44-48 and the SCM2 of *Localization of Short Duration Periodic Signals*
(Baggenstoss, NUWC 102089; the project's method text ``localization-short-periodic-signals``,
paragraphs [0032]-[0036], eq. 3-6):

=====  ======================================================  ===============================
step   method                                                   here
=====  ======================================================  ===============================
44     click map of impulses at the click times, smoothed by    :func:`scm1_spectrum` (eq. 3, 4)
       frequency-domain Hann shading (SCM1)
46     time-windowed SCM1 against wrap-around                   ``windowed=True`` (eq. 5)
48     correlation of a windowed and a plain SCM1               :meth:`ClickMapCorrelator.correlate`
                                                                (eq. 6)
--     candidate TDOAs: local maxima within the physically      :class:`TdoaPeak`
       possible delay of the pair (added)
50     SCM2: product of the SCM1 of sensor i and the SCM1 of    :func:`scm2`
       sensor j delayed by tau; its peaks are the clicks the
       pair matched
=====  ======================================================  ===============================

Sign convention: with sensor ``a = i`` windowed and ``b = j`` plain in eq. 6 the correlation
peaks at ``tau = t_i - t_j``, the TDOA of pair ``(i, j)`` as in the file formats.

The correlation value approximates the number of clicks the two maps share, each weighted by
the time window of eq. 5 at its time (1 at the window centre, 0.37 at a quarter window from it,
0.45 on average over the window) and by the correlation pulse at its residual mismatch (1 at no
mismatch, 0.5 at about 5 synthetic samples, 1.7 ms). A single click correlated with itself
gives exactly 1 (eq. 4).

This module holds the correlator (step 48); the grid and SCM1 live in ``_scm_grid``, the SCM2 in
``_scm2`` and the results in :mod:`fusion.clicks.scm_types`, all importable from here.

Examples
--------
>>> import numpy as np
>>> cfg = ScmConfig()
>>> ti = np.array([5.4, 5.77, 6.14, 6.51])  # four clicks near the window centre
>>> c = ClickMapCorrelator(config=cfg).correlate_times([ti, ti - 0.2], t0_s=0.0, max_delay_s=[1.0])
>>> round(c.peaks[0].tau_s, 6), round(c.peaks[0].value, 2)
(0.2, 4.0)
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray

from fusion._validation import check_positive
from fusion.clicks._scm2 import Scm2, scm2, scm2_many
from fusion.clicks._scm_grid import (
    ScmConfig,
    _as_time_list,
    local_maxima,
    parabolic,
    scm1,
    scm1_spectrum,
    window_maps,
    window_weight,
)
from fusion.clicks.scm_types import ScmCorrelation, TdoaPeak
from fusion.clicks.types import ChannelClicks, frozen_array
from fusion.geometry import SensorArray

__all__ = [
    "MAX_TDOA_RATE",
    "TDOA_RATE_STEP",
    "ClickMapCorrelator",
    "Scm2",
    "ScmConfig",
    "ScmCorrelation",
    "TdoaPeak",
    "drift_grid",
    "scm1",
    "scm1_spectrum",
    "scm2",
    "scm2_many",
    "window_weight",
]

logger = logging.getLogger(__name__)

#: Largest delay drift compensated by default, s/s: a whale at 1-2 m/s drifts a delay by up to
#: ``2 v / c``, about 1.3-2.7e-3 s/s (the correlation pulse, 2.7 ms to its first zero, holds a
#: drift of only ~4e-4 s/s over a 12 s window).
MAX_TDOA_RATE = 1.6e-3

#: Spacing of the drift grid, s/s: a delay half a step off drifts +-1.2 ms over 12 s, under half
#: the correlation pulse.
TDOA_RATE_STEP = 4e-4


def drift_grid(max_rate: float = MAX_TDOA_RATE, step: float = TDOA_RATE_STEP) -> tuple:
    """The drifts ``-max_rate .. max_rate`` in steps of at most `step` (0 alone for 0), s/s."""
    if not (np.isfinite(max_rate) and 0 <= max_rate < 0.1 and np.isfinite(step) and step > 0):
        raise ValueError(f"max_rate must be in [0, 0.1) and step > 0, got {max_rate}, {step}")
    k = int(np.ceil(max_rate / step - 1e-9))
    return tuple(float(v) for v in np.linspace(-max_rate, max_rate, 2 * k + 1)) if k else (0.0,)


class ClickMapCorrelator:
    """Correlate the SCM1s of every sensor pair in a window and pick candidate TDOAs.

    Parameters
    ----------
    config : ScmConfig, optional
        The synthetic grid (window ``T``, rate ``f_s``, shading); default :class:`ScmConfig`.
    delay_margin : float, optional
        Relative allowance on the largest physical delay ``d_ij / c`` (sound-speed and
        position errors), default 0.05.
    delay_guard_s : float, optional
        Absolute allowance added to it, s; default 2 ms (about the half-width of the
        correlation pulse, so that a peak at the physical limit is still a local maximum).
    min_peak : float, optional
        Smallest correlation value of a candidate, default 1.5: two matched clicks within
        about 2.2 s of the window centre (window weight >= 0.75 each), or three to four spread
        over the window. A single click pair (<= 1) never qualifies.
    max_peaks : int, optional
        At most this many candidates per pair (the strongest), default 3.
    rates : sequence of float, optional
        Delay drifts ``d tau / dt`` (s/s) to correlate under (drift compensation, added): for
        each rate ``r`` sensor ``j``'s clicks are moved to ``t + r (t - t_c)`` (``t_c`` the
        window centre) so that a delay drifting at ``r`` lines up at its centre value; the
        correlation of a pair is the largest over the rates at each lag, and each peak keeps
        its rate. Default ``(0.0,)``: none, the method text's correlation.

    Notes
    -----
    The correlation of eq. 6 is evaluated as ``irfft(Xw_i * conj(X_j), N)``: with the windowed
    SCM1 of sensor ``i`` (eq. 5) and the plain SCM1 of sensor ``j`` (eq. 3) it peaks at
    ``tau = t_i - t_j`` and is free of wrap-around for ``|tau| <= T/4`` ([0035]). Peaks are
    searched within ``|tau| <= min(T/4, d_ij / c (1 + delay_margin) + delay_guard_s)``, the
    delays a source can produce, and located by parabolic interpolation.
    """

    def __init__(
        self,
        *,
        config: ScmConfig | None = None,
        delay_margin: float = 0.05,
        delay_guard_s: float = 0.002,
        min_peak: float = 1.5,
        max_peaks: int = 3,
        rates: Sequence[float] = (0.0,),
    ) -> None:
        self.config = ScmConfig() if config is None else config
        self.delay_margin = check_positive("delay_margin", delay_margin, allow_zero=True)
        self.delay_guard_s = check_positive("delay_guard_s", delay_guard_s, allow_zero=True)
        self.min_peak = check_positive("min_peak", min_peak)
        if isinstance(max_peaks, bool) or int(max_peaks) != max_peaks or max_peaks < 1:
            raise ValueError(f"max_peaks must be an integer >= 1, got {max_peaks!r}")
        self.max_peaks = int(max_peaks)
        r = np.asarray(rates, dtype=float).ravel()
        if r.size == 0 or not np.all(np.isfinite(r)) or np.any(np.abs(r) >= 0.1):
            raise ValueError(f"rates must be finite drifts |r| < 0.1 s/s, got {rates!r}")
        self.rates = tuple(float(v) for v in sorted(set(r.tolist()), key=lambda v: (v != 0, v)))

    def correlate(
        self,
        clicks: Sequence[ChannelClicks] | Sequence[ArrayLike],
        *,
        t0_s: float,
        sensors: SensorArray,
        pairs: ArrayLike | None = None,
    ) -> ScmCorrelation:
        """SCM correlations and candidate TDOAs of one window.

        Parameters
        ----------
        clicks : sequence of ChannelClicks or of array_like, length n_sensors
            Click times of every channel (channel ``k`` is ``sensors.positions[k]``), s.
        t0_s : float
            Start of the window, s from the start of the audio.
        sensors : SensorArray
            Sensor positions and sound speed (for the physically possible delays).
        pairs : array_like of int, shape (n_pairs, 2), optional
            Sensor pairs ``(i, j)``; default every pair ``i < j``.

        Returns
        -------
        ScmCorrelation
        """
        if len(clicks) != sensors.n_sensors:
            raise ValueError(f"{len(clicks)} click channels for {sensors.n_sensors} sensors")
        pr = np.asarray(sensors.pairs() if pairs is None else pairs, dtype=np.int64).reshape(-1, 2)
        if pr.size and (pr.min() < 0 or pr.max() >= sensors.n_sensors or np.any(pr[:, 0] == pr[:, 1])):
            raise ValueError(f"pairs must hold two different sensor indices < {sensors.n_sensors}")
        sep = np.linalg.norm(sensors.positions[pr[:, 0]] - sensors.positions[pr[:, 1]], axis=1)
        max_delay = sep / sensors.sound_speed * (1.0 + self.delay_margin) + self.delay_guard_s
        return self.correlate_times(clicks, t0_s=t0_s, max_delay_s=max_delay, pairs=pr)

    def correlate_times(
        self,
        clicks: Sequence[ChannelClicks] | Sequence[ArrayLike],
        *,
        t0_s: float,
        max_delay_s: ArrayLike,
        pairs: ArrayLike | None = None,
    ) -> ScmCorrelation:
        """As :meth:`correlate`, with the largest delay of each pair given directly.

        Parameters
        ----------
        clicks : sequence of ChannelClicks or of array_like
            Click times of every channel, s.
        t0_s : float
            Start of the window, s.
        max_delay_s : array_like, shape (n_pairs,)
            Largest ``|tau|`` searched in each pair, s (capped at ``T/4``).
        pairs : array_like of int, shape (n_pairs, 2), optional
            Default ``[(0, 1)]``.

        Returns
        -------
        ScmCorrelation
        """
        cfg = self.config
        n = cfg.n_samples
        pr = np.asarray([(0, 1)] if pairs is None else pairs, dtype=np.int64).reshape(-1, 2)
        max_delay = np.broadcast_to(np.asarray(max_delay_s, dtype=float), (pr.shape[0],))
        if pr.size and pr.max() >= len(clicks):
            raise ValueError(f"pairs refer to channel {pr.max()} but only {len(clicks)} are given")
        if np.any(~np.isfinite(max_delay)) or np.any(max_delay <= 0):
            raise ValueError("max_delay_s must be positive")
        tl = _as_time_list(clicks)
        used = np.unique(pr)
        row = np.full(len(tl), -1, dtype=np.int64)
        row[used] = np.arange(used.size)
        q = n // 4  # |tau| <= T/4: no wrap-around
        lags = np.arange(-q, q + 1)
        # plain SCM1 (eq. 3) and windowed SCM1 (eq. 5) of each channel used
        t_c = t0_s + 0.5 * cfg.window_s
        # sensor j's clicks moved along each drift (sensor i as measured); the measured maps
        # last, so that they stay cached for the window's SCM2s
        moved = {rate: window_maps([tl[ch] + rate * (tl[ch] - t_c) for ch in used], t0_s=t0_s,
                                   config=cfg).plain for rate in self.rates if rate}
        # plain SCM1 (eq. 3) and windowed SCM1 (eq. 5) of each channel used
        base = window_maps([tl[ch] for ch in used], t0_s=t0_s, config=cfg, windowed=True)
        windowed_i = base.windowed[row[pr[:, 0]]]
        values = rate_of = None
        for rate in self.rates:
            plain = moved[rate] if rate else base.plain
            # eq. 6: c(m) = (1/N) sum_k Xw_i(k) conj(X_j(k)) e^{j 2 pi k m / N}, peak at
            # m = (t_i - t_j) fs
            corr = scipy.fft.irfft(windowed_i * np.conj(plain[row[pr[:, 1]]]), n, axis=-1)
            v = np.concatenate([corr[:, n - q:], corr[:, : q + 1]], axis=1)
            if values is None:
                values, rate_of = v, np.full(v.shape, rate)
            else:
                better = v > values
                values = np.where(better, v, values)
                rate_of = np.where(better, rate, rate_of)
        limit = np.minimum(max_delay, q / cfg.fs_hz)
        peaks = self._peaks(values, lags, limit, pr, rate_of)
        return ScmCorrelation(
            t0_s=float(t0_s), pairs=frozen_array(pr, np.int64), lags_s=frozen_array(lags / cfg.fs_hz),
            values=frozen_array(values), max_delay_s=frozen_array(limit), peaks=peaks,
        )

    def _peaks(self, values: NDArray, lags: NDArray, limit: NDArray, pairs: NDArray,
               rate_of: NDArray | None = None) -> tuple:
        fs = self.config.fs_hz
        q = lags.size // 2  # lags[q] = 0
        out: list[TdoaPeak] = []
        for p in range(pairs.shape[0]):
            # interior local maxima >= min_peak within |lag| <= limit (tested there only)
            half = int(np.floor(limit[p] * fs + 1e-9))
            while half >= 0 and abs(lags[q + half]) > limit[p] * fs:
                half -= 1
            a, b = max(q - half, 1), min(q + half, lags.size - 2)
            if b < a:
                continue
            seg = values[p, a - 1:b + 2]
            idx = a + np.flatnonzero(local_maxima(seg, self.min_peak)[1:-1])
            idx = idx[np.argsort(values[p, idx])[::-1][: self.max_peaks]]
            d, v = parabolic(values[p, idx - 1], values[p, idx], values[p, idx + 1])
            pair = (int(pairs[p, 0]), int(pairs[p, 1]))
            order = np.argsort(v)[::-1]
            rate = np.zeros(idx.size) if rate_of is None else rate_of[p, idx]
            # moved along rate r, sensor j's clicks line up at tau_c (1 + r) (tau_c: the delay
            # at the window centre)
            out += [TdoaPeak(pair, float((lags[idx[k]] + d[k]) / fs / (1.0 + rate[k])),
                             float(v[k]), float(rate[k])) for k in order]
        return tuple(out)
