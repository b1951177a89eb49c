"""The click front end as one pipeline: audio in, validated and associated TDOAs out.

Chains the stages of :mod:`fusion.clicks` in the order of *Localization of Short Duration
Periodic Signals* (Baggenstoss, NUWC 102089, FIG. 2, steps 34-54):

=====  ============================================  ==========================================
step   stage                                         part (in :mod:`fusion.clicks`)
=====  ============================================  ==========================================
34-42  replica correlation, click detection          :class:`detect.ClickDetector`
44-48  smoothed click maps, correlation, peaks       :class:`scm.ClickMapCorrelator`
50     SCM2, ACF features, GMM likelihood ratio      :func:`scm.scm2_many`, :class:`validate.TdoaValidator`
--     sub-sample TDOA, sigma and CRB (added)        :class:`tdoa.TdoaRefiner`
52     association across time (eq. 12)              :class:`associate.TimeAssociator`
54     association across pairs (eq. 13), closure    :func:`associate.cross_pair_alpha`,
                                                     :func:`associate.closure_check`
=====  ============================================  ==========================================

The pipeline holds no algorithm of its own. It streams: audio arrives in consecutive blocks
(:func:`fusion.io.iter_audio_blocks` with block = hop), clicks are detected once per sample (each
block with a guard margin on both sides, so the result equals whole-signal detection), and a
processing window (``window_s``, every ``hop_s``; 12 s every 2 s by default, as in the text) is
processed as soon as its clicks are final. Only the last ``window_s`` plus two guards of audio are
held in memory, whatever the length of the recording.

Acceptance (decisions where the text leaves a choice, documented here):

* a TDOA **passes validation** when its GMM log-likelihood ratio (eq. 11) is at least the
  validator's threshold and it is not an alias of a stronger TDOA of its pair (the same clicks
  at both sensors re-paired one click apart, :func:`fusion.clicks.aliases.train_aliases`);
* it is **confirmed** when the time association links it to a TDOA of the previous *or* the next
  window ([0041]: seen in two consecutive updates); a window is therefore reported one update
  after it is processed, when its successor is known;
* it is **valid** (the ``valid`` of the result file) when it passes validation and is confirmed;
* the triangle closure ``tau_ab + tau_bc - tau_ac`` is reported per TDOA (``consistent``), not
  used to reject: a TDOA of a pair whose third side was missed is untested, not wrong.

Examples
--------
>>> from fusion.simulate.clicks import simulate_clicks
>>> sc = simulate_clicks(seed=3, n_sensors=4, n_sources=1, duration_s=16.0, snr_db=30.0)
>>> fe = ClickFrontEnd()
>>> windows = fe.run_array(sc.audio, sc.fs, sc.sensors)
>>> [round(w.t_start, 1) for w in windows]
[0.0, 2.0, 4.0]
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._validation import check_positive
from fusion.click_defaults import DETECT_FALSE_ALARMS_PER_S, LLR_THRESHOLD
from fusion.clicks.aliases import train_aliases
from fusion.clicks.associate import (
    TimeAssociator,
    closure_check,
    cross_pair_alpha,
)
from fusion.clicks.delaytrack import match_along_track
from fusion.clicks.detect import ClickDetector
from fusion.clicks.scm import ClickMapCorrelator, ScmConfig, drift_grid, scm2_many
from fusion.clicks.support import SUPPORT_MIN_LLR, closure_support
from fusion.clicks.tdoa import TdoaRefiner
from fusion.clicks.train_integration import TRAIN_FALSE_ALARMS
from fusion.clicks.types import ChannelClicks
from fusion.clicks.validate import TdoaValidator, scm2_features
from fusion.clicks.window import ClickWindow, WindowTdoa
from fusion.geometry import SensorArray
from fusion.pipelines.clicks.stream import MeasuredWindow, measure_stream, window_starts_count
from fusion.pipelines.clicks.train_tdoas import train_tdoas

__all__ = ["DETECT_FALSE_ALARMS_PER_S", "LLR_THRESHOLD", "ClickFrontEnd", "ClickWindow",
           "WindowTdoa", "default_validator",
           "window_starts"]

logger = logging.getLogger(__name__)




def default_validator(threshold: float | None = None) -> TdoaValidator:
    """The validator shipped with the package (:data:`fusion.clicks.validate.DEFAULT_MODEL_PATH`,
    ``validator_v2.npz``), at its own threshold or at `threshold` (e.g. :data:`LLR_THRESHOLD`)."""
    import dataclasses

    from fusion.clicks.validate import DEFAULT_MODEL_PATH

    v = TdoaValidator.load(DEFAULT_MODEL_PATH)
    return v if threshold is None else dataclasses.replace(v, threshold=float(threshold))


def window_starts(duration_s: float, window_s: float, hop_s: float) -> NDArray[np.float64]:
    """Start times of the processing windows of a recording.

    Windows ``[k hop, k hop + window)`` that fit inside the recording; a recording shorter than
    one window gives one window over all of it.
    """
    return np.arange(window_starts_count(duration_s, window_s, hop_s)) * hop_s


class ClickFrontEnd:
    """Audio to validated, associated TDOAs, window by window (steps 34-54).

    Parameters
    ----------
    detector : ClickDetector, optional
        Click detection (default: the method's parameters, the threshold from
        :data:`~fusion.click_defaults.DETECT_FALSE_ALARMS_PER_S` noise clicks a channel-second,
        as ``fusion localize``).
    correlator : ClickMapCorrelator, optional
        Smoothed click maps and their correlation; its ``config.window_s`` is the processing
        window (default 12 s, 3 kHz synthetic rate, delay drifts up to
        :data:`fusion.clicks.scm.MAX_TDOA_RATE` compensated: :func:`fusion.clicks.scm.drift_grid`).
    validator : TdoaValidator or False, optional
        The GMM validator (default: the model shipped with the package at
        :data:`~fusion.click_defaults.LLR_THRESHOLD`, as ``fusion localize``). ``False`` computes
        the features only (``llr`` NaN, every TDOA passes): the mode of training.
    refiner : callable, optional
        ``fs -> TdoaRefiner``; default ``TdoaRefiner(fs_hz=fs)``. ``False`` skips refinement
        (TDOAs stay on the SCM grid, as in the text).
    associator : TimeAssociator, optional
        Association across time (default: beta > 7, |dtau| < 3 ms at a 2 s update, scaled with
        `hop_s`).
    hop_s : float, optional
        Update period, s (default 2).
    sigma_t_s : float, optional
        Click-time tolerance of eq. 12-13, s (default 1 ms).
    scm_level : float, optional
        Smallest normalised SCM2 peak counted as a source click.
    feature_decimation : int, optional
        Block size of the SCM2 before its ACF features (see
        :func:`fusion.clicks.validate.scm2_features`; 10 at the default 3 kHz grid). The
        shipped validator was trained with the default.
    alias_screen : bool, optional
        Fail a TDOA that re-pairs the clicks of a stronger TDOA of its pair one click apart
        (:func:`fusion.clicks.aliases.train_aliases`; default True).
    closure_support : bool, optional
        Where the validated TDOAs of a window span fewer than four sensors, admit the partial
        trains of another sensor that close with them (:func:`fusion.clicks.support.
        closure_support`; default True, ``docs/localization.md`` section 15).
    train_integration : bool, optional
        Where they still span fewer than four, sum each other sensor's detection statistic
        along a well-heard sensor's click train (:mod:`fusion.pipelines.clicks.train_tdoas`;
        default True, ``docs/localization.md`` section 19).
    train_false_alarms : float, optional
        False-alarm probability of one (window, pair) train search.
    train_refine : bool, optional
        Refine each train-integrated delay on the waveforms (the train's cross-spectra summed,
        :func:`fusion.clicks.train_refine.refine_train_delay`; default True,
        ``docs/localization.md`` section 23).
    """

    def __init__(
        self,
        *,
        detector: ClickDetector | None = None,
        correlator: ClickMapCorrelator | None = None,
        validator: TdoaValidator | bool | None = None,
        refiner: Callable[[float], TdoaRefiner] | bool | None = None,
        associator: TimeAssociator | None = None,
        hop_s: float = 2.0,
        sigma_t_s: float = 1e-3,
        scm_level: float = 0.5,
        feature_decimation: int = 10,
        alias_screen: bool = True,
        closure_support: bool = True,
        train_integration: bool = True,
        train_false_alarms: float = TRAIN_FALSE_ALARMS,
        train_refine: bool = True,
    ) -> None:
        check_positive("hop_s", hop_s)
        check_positive("sigma_t_s", sigma_t_s)
        self.detector = (detector if detector is not None
                         else ClickDetector(false_alarms_per_s=DETECT_FALSE_ALARMS_PER_S))
        self.correlator = (correlator if correlator is not None
                           else ClickMapCorrelator(rates=drift_grid()))
        self.config: ScmConfig = self.correlator.config
        if hop_s > self.config.window_s:
            raise ValueError(f"hop_s {hop_s} is longer than the window {self.config.window_s} s")
        if validator is None or validator is True:
            validator = default_validator(LLR_THRESHOLD)
        self.validator: TdoaValidator | None = validator if validator is not False else None
        if refiner is None or refiner is True:
            self._make_refiner: Callable[[float], TdoaRefiner] | None = (
                lambda fs: TdoaRefiner(fs_hz=fs))
        elif refiner is False:
            self._make_refiner = None
        else:
            self._make_refiner = refiner
        self.associator = (associator if associator is not None
                           else TimeAssociator(sigma_t_s=sigma_t_s, update_period_s=hop_s))
        self.hop_s = float(hop_s)
        self.sigma_t_s = float(sigma_t_s)
        self.scm_level = float(scm_level)
        self.feature_decimation = int(feature_decimation)
        self.alias_screen = bool(alias_screen)
        self.closure_support = bool(closure_support)
        self.train_integration = bool(train_integration)
        self.train_false_alarms = check_positive("train_false_alarms", train_false_alarms)
        self.train_refine = bool(train_refine)

    @property
    def window_s(self) -> float:
        """Processing window length, s."""
        return float(self.config.window_s)

    # ----------------------------------------------------------------------------------------
    def measure_window(
        self,
        clicks: Sequence[ChannelClicks],
        *,
        t0_s: float,
        sensors: SensorArray,
        audio: NDArray | None = None,
        audio_t0_s: float = 0.0,
        fs: float | None = None,
        refiner: TdoaRefiner | None = None,
    ) -> list[WindowTdoa]:
        """Candidate TDOAs of one window, validated (not yet associated across time).

        Parameters
        ----------
        clicks : sequence of ChannelClicks
            Each channel's clicks (any times; the window's are used).
        t0_s : float
            Window start, s.
        sensors : SensorArray
            The array (pairs and their physically possible delays).
        audio : ndarray, shape (n, n_sensors), optional
            Audio covering the window, for sub-sample refinement; without it the TDOAs stay
            on the SCM grid.
        audio_t0_s : float, optional
            Time of ``audio[0]``, s.
        fs : float, optional
            Sample rate of `audio`, Hz.
        refiner : TdoaRefiner, optional
            The refiner to use (e.g. :meth:`stream_refiner`'s, which remembers the click cuts
            of a recording from window to window); default a new one for `fs`.

        Returns
        -------
        list of WindowTdoa
            In pair order, strongest peak first within a pair.
        """
        t1 = t0_s + self.window_s
        inside = [c.between(t0_s, t1) for c in clicks]
        corr = self.correlator.correlate(inside, t0_s=t0_s, sensors=sensors)
        if not corr.peaks:
            return self._trains([], inside, sensors, audio, audio_t0_s, fs, t0_s)
        if audio is None or fs is None:
            refiner = None
        elif refiner is None and self._make_refiner is not None:
            refiner = self._make_refiner(fs)
        maps = self._scm2s(inside, corr.peaks, t0_s)
        z = scm2_features(np.stack([m.series for m in maps]), self.config.fs_hz, T=self.window_s,
                          decimate=self.feature_decimation)
        if self.validator is None:  # features only (training)
            llr = np.full(len(maps), np.nan)
            passes = np.ones(len(maps), dtype=bool)
        else:
            llr = self.validator.llr(z)
            passes = llr >= self.validator.threshold
        def measured(k: int, refine: bool) -> WindowTdoa:
            """Candidate k, refined when `refine` (a TDOA to be used) and a refiner is given."""
            peak, s2 = corr.peaks[k], maps[k]
            i, j = peak.pair
            tau, sigma, crb, snr, rate = (peak.tau_s, self.config.pulse_halfwidth_s, math.nan,
                                          math.nan, peak.rate)
            times = s2.click_times_s
            if refine and refiner is not None and s2.index_i.size:
                # the SCM2's matches, extended through the window along the delay's drift
                ii, jj = match_along_track(inside[i].times_s, inside[j].times_s, s2.index_i,
                                           s2.index_j, t_start_s=t0_s, t_end_s=t1)
                ref = refiner.refine(audio, peak.pair, inside[i].times_s[ii],
                                     inside[j].times_s[jj], audio_t0_s=audio_t0_s,
                                     reference_time_s=t0_s + 0.5 * self.window_s)
                if ref is not None and abs(ref.tau_s - peak.tau_s) < 2.0 * self.config.pulse_halfwidth_s:
                    tau, sigma, crb, snr, rate = (ref.tau_s, ref.sigma_s, ref.crb_s, ref.snr_db,
                                                  ref.rate)
                    # the clicks matched along the delay's drift through the whole window
                    # (the SCM2 matches only those within its pulse width of the coarse delay)
                    if ref.click_times_s.size >= times.size:
                        times = np.sort(ref.click_times_s)
            return WindowTdoa(
                pair=peak.pair, tau_s=float(tau), tau_coarse_s=float(peak.tau_s),
                sigma_s=float(sigma), crb_s=float(crb), snr_db=float(snr), rate=float(rate),
                scm_peak=float(peak.value),
                n_clicks=int(s2.click_times_s.size), features=z[k], llr=float(llr[k]),
                passes=bool(passes[k]), click_times_s=times, t_s=t0_s + 0.5 * self.window_s)

        # refine only what passed validation: the rest is dropped downstream anyway
        out = [measured(k, bool(passes[k])) for k in range(len(maps))]
        alias = np.zeros(len(out), dtype=bool)
        if self.validator is not None and self.alias_screen:  # one delay per click train
            alias = np.asarray(train_aliases(out), dtype=bool)
            out = [dataclasses.replace(d, passes=False) if a else d
                   for d, a in zip(out, alias, strict=True)]
        if self.validator is not None and self.closure_support:
            out = self._supported(out, alias, measured)
        return self._trains(out, inside, sensors, audio, audio_t0_s, fs, t0_s)

    def _trains(self, out: list[WindowTdoa], inside: list[ChannelClicks], sensors: SensorArray,
                audio: NDArray | None, audio_t0_s: float, fs: float | None,
                t0_s: float) -> list[WindowTdoa]:
        """`out` and the TDOAs of click trains integrated on weakly heard sensors
        (:func:`fusion.pipelines.clicks.train_tdoas.train_tdoas`), when switched on, validated
        and given the audio."""
        if not self.train_integration or self.validator is None or audio is None or fs is None:
            return out
        return out + train_tdoas(out, inside, detector=self.detector, sensors=sensors,
                                 audio=audio, audio_t0_s=audio_t0_s, fs=fs,
                                 t_c_s=t0_s + 0.5 * self.window_s,
                                 max_rate=float(np.max(np.abs(self.correlator.rates))),
                                 false_alarms=self.train_false_alarms,
                                 waveform_refine=self.train_refine)

    def _supported(self, out: list[WindowTdoa], alias: NDArray[np.bool_],
                   measured: Callable[[int, bool], WindowTdoa]) -> list[WindowTdoa]:
        """A weakly heard sensor's partial trains admitted by closure with the validated TDOAs
        (:func:`fusion.clicks.support.closure_support`), where those span fewer than four
        sensors: the candidates that may be admitted are refined first; the others stay as
        they were."""
        passes = np.array([d.passes for d in out], dtype=bool)
        if len({s for d, p in zip(out, passes, strict=True) if p for s in d.pair}) >= 4:
            return out
        llr = np.array([d.llr for d in out])
        pool = ~passes & ~alias & (llr >= SUPPORT_MIN_LLR)
        if pool.sum() < 2:
            return out
        trial = [measured(k, True) if pool[k] else d for k, d in enumerate(out)]
        admit = closure_support([d.as_clicks() for d in trial], passes, pool, llr,
                                sigma_t_s=self.sigma_t_s, t_ref_s=out[0].t_s)
        return [dataclasses.replace(trial[k], passes=True) if admit[k] else d
                for k, d in enumerate(out)]

    def stream_refiner(self, fs: float) -> TdoaRefiner | None:
        """The refiner of one stream of audio at `fs` (None without refinement): it remembers
        the click cuts from window to window when it can
        (:meth:`fusion.clicks.tdoa.TdoaRefiner.remember_cuts`; the same results)."""
        if self._make_refiner is None:
            return None
        refiner = self._make_refiner(fs)
        remember = getattr(refiner, "remember_cuts", None)
        return refiner if remember is None else remember()

    def _scm2s(self, inside: list[ChannelClicks], peaks, t0_s: float) -> list:
        """The SCM2 of each candidate peak, sensor j's clicks moved along the peak's drift."""
        out: list = [None] * len(peaks)
        n = len(inside)
        t_c = t0_s + 0.5 * self.window_s
        times = [c.times_s for c in inside]
        for rate in sorted({p.rate for p in peaks}, key=lambda r: (r != 0, r)):
            ks = [k for k, p in enumerate(peaks) if p.rate == rate]
            if rate:  # channels n.. hold the moved clicks; pairs (i, n + j)
                chans = times + [t + rate * (t - t_c) for t in times]
                pairs = [(peaks[k].pair[0], n + peaks[k].pair[1]) for k in ks]
            else:
                chans, pairs = inside, [peaks[k].pair for k in ks]
            maps = scm2_many(chans, pairs, [peaks[k].tau_s * (1.0 + rate) for k in ks],
                             t0_s=t0_s, config=self.config, level=self.scm_level)
            for k, m in zip(ks, maps, strict=True):
                out[k] = m
        return out

    def _finish(self, window: ClickWindow, linked_next: NDArray[np.bool_]) -> ClickWindow:
        """Mark confirmations from the next window; closure and alpha on the final TDOAs."""
        tdoas = [
            WindowTdoa(**{**d.__dict__, "confirmed": bool(d.confirmed or linked_next[k])})
            for k, d in enumerate(window.tdoas)
        ]
        # alpha and closure among the TDOAs that passed validation (the others are not used)
        keep = np.array([k for k, d in enumerate(tdoas) if d.passes], dtype=int)
        alpha = np.zeros((len(tdoas), len(tdoas)))
        if keep.size:
            sub = [tdoas[k].as_clicks() for k in keep]
            a_sub = cross_pair_alpha(sub, sigma_t_s=self.sigma_t_s)
            alpha[np.ix_(keep, keep)] = a_sub
            check = closure_check(sub, a_sub)
            for n, k in enumerate(keep):
                tdoas[k] = WindowTdoa(**{**tdoas[k].__dict__,
                                         "consistent": bool(check.consistent[n])})
        return ClickWindow(window.t_start, window.t_end, window.clicks, tuple(tdoas), alpha,
                           window.links_previous)

    # ----------------------------------------------------------------------------------------
    def measure(
        self,
        blocks: Iterable[tuple[float, ArrayLike]] | Iterable[tuple[float, ArrayLike, float]],
        **stream: Any,
    ) -> Iterator[MeasuredWindow]:
        """Measure the windows of a stream of audio blocks, not yet associated across time.

        :func:`fusion.pipelines.clicks.stream.measure_stream` with this front end: `stream` are
        its keyword parameters (``fs``, ``sensors``, ``duration_s``, ``start_sample``, ...).
        Clicks are detected once per sample and each window is measured
        (:meth:`measure_window`) as soon as its clicks are final; a stream may start part-way
        through a recording.
        """
        return measure_stream(self, blocks, **stream)

    def associate(self, measured: Iterable[MeasuredWindow]) -> Iterator[ClickWindow]:
        """Associate consecutive measured windows across time (eq. 12), then across pairs.

        Parameters
        ----------
        measured : iterable of MeasuredWindow
            Consecutive windows in order.

        Yields
        ------
        ClickWindow
            Each window once its successor is known (the last at the end): ``confirmed`` when
            linked to the previous or the next window, closure and alpha (eq. 13) on the final
            TDOAs. Depends only on the window and its two neighbours.
        """
        pending: ClickWindow | None = None
        prev_tdoas: Sequence[WindowTdoa] = ()
        for m in measured:
            assoc = self.associator.associate([d.as_clicks() for d in prev_tdoas],
                                              [d.as_clicks() for d in m.tdoas])
            tdoas = [WindowTdoa(**{**d.__dict__, "confirmed": bool(assoc.confirmed[k])})
                     for k, d in enumerate(m.tdoas)]
            links = tuple((lk.previous, lk.current) for lk in assoc.links)
            if pending is not None:
                yield self._finish(pending, assoc.previous_linked)
            pending = ClickWindow(m.t_start, m.t_end, m.clicks, tuple(tdoas),
                                  np.zeros((len(tdoas), len(tdoas))), links)
            prev_tdoas = m.tdoas
        if pending is not None:
            yield self._finish(pending, np.zeros(len(pending.tdoas), dtype=bool))

    def iter_windows(
        self,
        blocks: Iterable[tuple[float, ArrayLike]] | Iterable[tuple[float, ArrayLike, float]],
        *,
        fs: float,
        sensors: SensorArray,
        duration_s: float | None = None,
    ) -> Iterator[ClickWindow]:
        """Process a stream of consecutive audio blocks; yield each finished window in order.

        Parameters
        ----------
        blocks : iterable of (t0, samples) or (t0, samples, fs)
            Consecutive, non-overlapping blocks (n, n_sensors) in time order, the first at 0.
        fs : float
            Sample rate, Hz.
        sensors : SensorArray
            The array; channel i is sensor i.
        duration_s : float, optional
            Length of the recording, s (to place the windows before the end is reached);
            default: windows are placed as the audio arrives, and a recording shorter than
            one window gives one window over all of it.

        Yields
        ------
        ClickWindow
            Each window once its successor's time association is known (the last at the end):
            :meth:`associate` over :meth:`measure`.
        """
        yield from self.associate(self.measure(blocks, fs=fs, sensors=sensors,
                                               duration_s=duration_s))

    def run_array(
        self, audio: ArrayLike, fs: float, sensors: SensorArray, *, block_s: float | None = None
    ) -> list[ClickWindow]:
        """Process audio held in memory (n, n_sensors); returns every window."""
        x = np.asarray(audio)
        if x.ndim != 2:
            raise ValueError(f"audio must have shape (n, n_sensors), got {x.shape}")
        step = int(round((block_s or self.hop_s) * fs))
        blocks = ((a / fs, x[a:a + step]) for a in range(0, x.shape[0], step))
        return list(self.iter_windows(blocks, fs=fs, sensors=sensors,
                                      duration_s=x.shape[0] / fs))
