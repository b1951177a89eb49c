"""Track score of tentative tracks: the log-likelihood ratio of "target" against "clutter".

Section 2.5 of "Target tracking using fuzzy logic association" forms a track when "multiple
detections are associated within a few events" (M-of-N, :mod:`fusion.active.lifecycle`). A fixed
count treats two clutter echoes per ping and fifteen alike, though in dense clutter a few
detections inside a track's gate are no evidence of a target at all. The track score weighs each
hit by how much more likely it is under the track than as clutter (the sequential
probability-ratio track score of Blackman and Popoli, *Design and Analysis of Modern Tracking
Systems*, 1999, Section 6.2):

- a hit with innovation ``nu`` and covariance ``S`` adds
  ``ln P_D + ln N(nu; 0, S) - ln lambda(z)``, with ``lambda(z)`` the clutter intensity at the
  detection (false returns per m^2 per ping);
- a miss adds ``ln(1 - P_D)``, or nothing where the direct blast hides the track from the
  receiver (its blind zone as the data show it, :meth:`TrackScorer.miss_delta`);
- a hit's classifier score adds ``ln f_T(s) / f_C(s)`` (:meth:`TrackScorer.score_delta`), the
  paper's classifier (Section 2.2) as evidence rather than as a gate;
- a new track starts at 0.

In a multistatic system each receiver is a sensor of its own: a track is scored against every
receiver that reported on a ping (a hit or a miss each), with that receiver's ``P_D`` and
``lambda``. A target seen by three receivers at one place gains three hits per ping, clutter
(independent from receiver to receiver) rarely more than one.

A tentative track is confirmed once it has its M-of-N hits *and* a score of at least
``confirm_llr``; it is deleted when its score falls below ``delete_llr``. The detection
probability ``P_D`` (that a track gets a detection on a ping) and the clutter intensity are
settings the user may give; by default both are estimated from the data, per receiver: ``P_D``
as the hit rate of the tracks the tracker names in ``teach`` (a Beta(7, 3) prior, i.e. 0.7
worth ten pings; :meth:`TrackScorer.scan_delta`), ``lambda`` by a kernel density of the
receiver's detections (:class:`fusion.active.clutter.intensity.ClutterIntensity`) that no
confirmed track took.

Issue 20 (a target seen on four pings in ten): where no track is ever confirmed, a ``P_D``
learnt from confirmed tracks alone stays at its prior 0.7 and charges every miss ``ln 0.3``, so
a rarely seen target's score sinks. The tracker therefore also teaches ``P_D`` with tentative
tracks whose score has reached ``confirm_llr``; a track hidden by the direct blast, or whose
gated echo went to another track (a duplicate of a confirmed track), is no trial. Weighting
every tentative track by its existence probability ``1 / (1 + exp(confirm_llr - score))`` was
tried first: the hundreds of clutter tracks near score 0 each weigh ~0.05 and pulled the
estimate of a 0.9 receiver down to 0.4-0.6.
"""

from __future__ import annotations

import math
from collections.abc import Hashable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.active.clutter.base import Hotspots
from fusion.active.clutter.intensity import ClutterIntensity
from fusion.active.track_pd import TrackRates

__all__ = ["TrackScorer"]


_SCORE_BINS = 10
#: SNR histogram of :meth:`TrackScorer.snr_delta`: bins of 2 dB from 0 dB (the last open).
_SNR_BINS, _SNR_BIN_DB = 20, 2.0
#: Weight (detections) of the prior ``f_T = f_C`` of the SNR likelihood ratio.
_SNR_PRIOR = 20.0


def _excess(xy: NDArray[np.float64], key: Hashable) -> NDArray[np.float64]:
    """Range-sum excess ``|p - s| + |p - r| - |s - r|`` of points for a geometry key
    ``(src_x, src_y, rcv_x, rcv_y)``, m."""
    sx, sy, rx, ry = key  # type: ignore[misc]
    return (np.hypot(xy[:, 0] - sx, xy[:, 1] - sy) + np.hypot(xy[:, 0] - rx, xy[:, 1] - ry)
            - math.hypot(rx - sx, ry - sy))


class TrackScorer:
    """Log-likelihood-ratio score of tracks, with its clutter and detection settings.

    Every receiver is scored on its own: its detection probability and its clutter intensity
    (receivers differ in both), keyed by the source-receiver geometry of
    :func:`fusion.active.types.receiver_groups` (one key for data without geometry).

    Parameters
    ----------
    confirm_llr : float, optional
        Score a tentative track needs, besides its M-of-N hits, to be confirmed (default 6).
    delete_llr : float, optional
        A tentative track whose score falls below this is deleted (default -4).
    detection_probability : float, optional
        ``P_D`` of a receiver per ping, in (0, 1); None (default): estimated per receiver as the
        hit rate of confirmed tracks with a Beta(``prior_hits``, ``prior_misses``) prior.
    clutter_intensity : float, optional
        Clutter detections per m^2 per ping and receiver, > 0; None (default): estimated over
        the field for each receiver by a copy of `intensity`.
    intensity : ClutterIntensity, optional
        Template of the per-receiver estimators used when `clutter_intensity` is None (default
        ``ClutterIntensity()``).
    prior_hits, prior_misses : float, optional
        Beta prior of the estimated ``P_D`` (defaults 7 and 3).
    score_evidence : bool, optional
        Add the classifier score's likelihood ratio to each hit (default True; see
        :meth:`score_delta`), when the detections carry a ``score``.
    leave_one_out : bool, optional
        The estimated clutter intensity at a detection leaves out that detection's own kernel
        (:meth:`fusion.active.clutter.intensity.ClutterIntensity.self_intensity`; default
        False): the leave-one-out kernel estimate.
    leave_track_out : bool, optional
        The estimated clutter intensity at a track's hit leaves out the detection's own kernel
        and the kernels of the track's own earlier detections that the estimate still holds
        (default False; see :meth:`scan_delta`, argument ``own``).
    snr_evidence : bool, optional
        Add the SNR's likelihood ratio to each hit (default False; :meth:`snr_delta`), when
        the detections carry an ``snr_db``.
    track_pd_prior_pings : float, optional
        Score hits and misses with each track's own ``P_D`` per receiver, a Beta prior of the
        receiver's ``P_D`` worth this many pings updated by the track's hits
        (:mod:`fusion.active.track_pd`); None (default): the receiver's ``P_D``.

    Examples
    --------
    >>> scorer = TrackScorer(detection_probability=0.8, clutter_intensity=1e-7)
    >>> round(float(scorer.miss_delta(None)), 3)
    -1.609
    """

    def __init__(
        self,
        *,
        confirm_llr: float = 6.0,
        delete_llr: float = -4.0,
        detection_probability: float | None = None,
        clutter_intensity: float | None = None,
        intensity: ClutterIntensity | None = None,
        prior_hits: float = 7.0,
        prior_misses: float = 3.0,
        score_evidence: bool = True,
        leave_one_out: bool = False,
        leave_track_out: bool = False,
        snr_evidence: bool = False,
        track_pd_prior_pings: float | None = None,
    ) -> None:
        if not (np.isfinite(confirm_llr) and np.isfinite(delete_llr)) or delete_llr >= confirm_llr:
            raise ValueError(f"need finite delete_llr < confirm_llr, got {delete_llr!r}, "
                             f"{confirm_llr!r}")
        if detection_probability is not None and not 0.0 < detection_probability < 1.0:
            raise ValueError(f"detection_probability must lie in (0, 1), got "
                             f"{detection_probability!r}")
        if clutter_intensity is not None and not (np.isfinite(clutter_intensity)
                                                  and clutter_intensity > 0):
            raise ValueError(f"clutter_intensity must be positive, got {clutter_intensity!r}")
        if not (prior_hits > 0 and prior_misses > 0):
            raise ValueError("prior_hits and prior_misses must be positive")
        self.confirm_llr = float(confirm_llr)
        self.delete_llr = float(delete_llr)
        self.detection_probability = detection_probability
        self.clutter_intensity = clutter_intensity
        self.intensity = intensity if intensity is not None else ClutterIntensity()
        self.prior_hits = float(prior_hits)
        self.prior_misses = float(prior_misses)
        self.score_evidence = bool(score_evidence)
        self.leave_one_out = bool(leave_one_out)
        self.leave_track_out = bool(leave_track_out)
        self.snr_evidence = bool(snr_evidence)
        self.rates = (None if track_pd_prior_pings is None
                      else TrackRates(prior_pings=track_pd_prior_pings))
        self.last_added = np.zeros(0, dtype=bool)
        self.last_update = 0
        self.reset()

    def reset(self) -> None:
        """Forget what was learnt (hit counts of confirmed tracks, clutter intensities, blind
        zones, score histograms)."""
        self._score_all = np.zeros(_SCORE_BINS)
        self._score_target = np.zeros(_SCORE_BINS)
        self._snr_all = np.zeros(_SNR_BINS)
        self._snr_target = np.zeros(_SNR_BINS)
        self._counts: dict[Hashable, list[float]] = {}
        self._intensity: dict[Hashable, ClutterIntensity] = {}
        self._blind: dict[Hashable, float] = {}
        # Per track (in the tracker's order): receiver -> rows (update, x, y) of its detections
        # that went into that receiver's intensity estimate (used with leave_track_out).
        self._own: list[dict[Hashable, list[tuple[float, float, float]]]] = []
        if self.rates is not None:
            self.rates.reset()

    def own_rows(self, tracks: NDArray[np.int64], key: Hashable) -> list[NDArray[np.float64]] | None:
        """The ``own`` argument of :meth:`scan_delta` for these tracks (None without
        ``leave_track_out``)."""
        if not self.leave_track_out:
            return None
        return [np.asarray(self._own[t].get(key, ()), float).reshape(-1, 3) for t in tracks.tolist()]

    def remember(self, tracks: NDArray[np.int64], dets: NDArray[np.int64], key: Hashable,
                 xy: NDArray[np.float64], *, new: int = 0) -> None:
        """After :meth:`scan_delta` (or :meth:`observe`) of a receiver: `new` tracks are born
        (appended), and each of `tracks` took detection `dets` of `xy` (kept if it went into the
        intensity estimate). Only with ``leave_track_out``, apart from the births."""
        self._own += [{} for _ in range(new)]
        if self.rates is not None:
            self.rates.add(new)
        if not self.leave_track_out or self.clutter_intensity is not None:
            return
        u = float(self.last_update)
        for t, d in zip(tracks.tolist(), dets.tolist(), strict=True):
            if self.last_added[d]:
                self._own[t].setdefault(key, []).append((u, *xy[d].tolist()))

    def keep_tracks(self, alive: NDArray[np.bool_]) -> None:
        """Forget the deleted tracks' detections (`alive`: one flag per track)."""
        self._own = [o for o, a in zip(self._own, alive.tolist(), strict=True) if a]
        if self.rates is not None:
            self.rates.keep(alive)

    def pd(self, key: Hashable) -> float:
        """Current detection probability of a receiver per ping (given or estimated)."""
        if self.detection_probability is not None:
            return float(self.detection_probability)
        hits, pings = self._counts.get(key, (0.0, 0.0))
        pd = (self.prior_hits + hits) / (self.prior_hits + self.prior_misses + pings)
        return min(max(pd, 0.05), 0.99)

    def miss_delta(self, key: Hashable, xy: ArrayLike | None = None) -> NDArray[np.float64]:
        """Score change of a miss on a receiver, ``ln(1 - P_D)``; 0 inside its blind zone.

        Parameters
        ----------
        key : hashable
            The receiver: ``(src_x, src_y, rcv_x, rcv_y)`` or None (no geometry).
        xy : array_like, shape (k, 2), optional
            Predicted track positions, m.

        Returns
        -------
        ndarray, shape (k,) (shape () without `xy`)
            A receiver cannot miss what the direct blast hides from it: where the range-sum
            excess ``|p - s| + |p - r| - |s - r|`` of a track is below the smallest excess of
            any detection this receiver has made (its blind zone as the data show it), a miss
            says nothing and scores 0.
        """
        miss = math.log1p(-self.pd(key))
        if xy is None:
            return np.asarray(miss)
        pts = np.asarray(xy, dtype=float).reshape(-1, 2)
        out = np.full(pts.shape[0], miss)
        blind = self._blind.get(key)
        if blind is not None and key is not None:
            out[_excess(pts, key) < blind] = 0.0
        return out

    def observe(self, key: Hashable, xy: ArrayLike, cov: ArrayLike | None,
                hotspots: Hotspots | None = None, *,
                clutter: NDArray[np.bool_] | None = None,
                at: NDArray[np.int64] | None = None) -> NDArray[np.float64]:
        """Add a receiver's detections of a ping to its intensity estimate; their intensities.

        Parameters
        ----------
        key : hashable
            The receiver.
        xy : array_like, shape (n, 2)
            Its detections that may join tracks, m.
        cov : array_like, shape (n, 2, 2), optional
            Their position-error covariances, m^2.
        hotspots : Hotspots, optional
            The clutter map's hotspots: each adds its echo rate per ping and receiver,
            ``cells / (n_pings n_receivers)``, spread as ``N(x; c_h, C_h + R)``, to the
            smooth intensity (an echo at a known hotspot is as likely clutter as target).
        clutter : ndarray of bool, shape (n,), optional
            Which detections may be clutter (default all): those a confirmed track took are
            its target's echoes and are left out of the estimate, which would otherwise rise
            along every target's path and weigh against its own hits.
        at : ndarray of int, optional
            Detections whose ``lambda`` is wanted (default all; every detection is added to
            the estimate either way).

        Returns
        -------
        ndarray, shape (n,) (``(len(at),)`` with `at`)
            ``lambda`` at each detection, per m^2 per ping (the given value when set).
        """
        pts = np.asarray(xy, dtype=float).reshape(-1, 2) if np.size(xy) else np.zeros((0, 2))
        if key is not None and pts.shape[0]:
            low = float(np.min(_excess(pts, key)))
            self._blind[key] = min(self._blind.get(key, low), low)
        sel = np.arange(pts.shape[0]) if at is None else np.asarray(at, np.int64)
        if self.clutter_intensity is not None:
            return np.full(sel.size, float(self.clutter_intensity))
        est = self._intensity.get(key)
        if est is None:
            est = self._intensity[key] = self.intensity.empty_copy()
        keep = np.ones(pts.shape[0], bool) if clutter is None else np.asarray(clutter, bool)
        est.update(pts[keep], None if cov is None else np.asarray(cov, float)[keep])
        lam = est.intensity(pts[sel])
        added = keep.copy()
        added[keep] = est.last_kept
        self.last_added, self.last_update = added, est.updates
        pts = pts[sel]
        if (self.leave_one_out or self.leave_track_out) and pts.shape[0]:
            lam[added[sel]] = np.maximum(lam[added[sel]] - est.self_intensity(),
                                         est.min_intensity)
        if hotspots is not None and len(hotspots) and pts.shape[0]:
            c = (np.zeros((pts.shape[0], 2, 2)) if cov is None
                 else np.asarray(cov, float).reshape(-1, 2, 2)[sel])
            S = hotspots.covariances[None] + c[:, None]                  # (n, h, 2, 2)
            d = pts[:, None, :] - hotspots.positions[None]
            det = S[..., 0, 0] * S[..., 1, 1] - S[..., 0, 1] ** 2
            m2 = (d[..., 0] ** 2 * S[..., 1, 1] - 2 * d[..., 0] * d[..., 1] * S[..., 0, 1]
                  + d[..., 1] ** 2 * S[..., 0, 0]) / det
            rate = hotspots.cells / max(hotspots.n_pings, 1) / max(len(self._intensity), 1)
            lam = lam + np.sum(rate[None] * np.exp(-0.5 * m2) / (2 * np.pi * np.sqrt(det)), axis=1)
        return lam

    def hit_delta(self, key: Hashable, log_pdf: ArrayLike, clutter: ArrayLike) -> NDArray[np.float64]:
        """Score change of hits on a receiver: ``ln P_D + ln N(nu; 0, S) - ln lambda``.

        Parameters
        ----------
        key : hashable
            The receiver.
        log_pdf : array_like, shape (k,)
            ``ln N(nu; 0, S)`` of each hit (density in 1/m^2).
        clutter : array_like, shape (k,)
            Clutter intensity at each hit's detection, per m^2 per ping.
        """
        return (math.log(self.pd(key)) + np.asarray(log_pdf, float)
                - np.log(np.asarray(clutter, float)))

    @staticmethod
    def _bins(scores: ArrayLike) -> NDArray[np.int64]:
        sc = np.clip(np.asarray(scores, float).reshape(-1), 0.0, 1.0 - 1e-9)
        return (sc * _SCORE_BINS).astype(np.int64)

    def score_delta(self, scores: ArrayLike) -> NDArray[np.float64]:
        """Score change of hits from their classifier scores, ``ln f_T(s) / f_C(s)``.

        Parameters
        ----------
        scores : array_like, shape (k,)
            Classifier scores in [0, 1].

        Returns
        -------
        ndarray, shape (k,)
            ``f_C``: histogram (10 bins, one pseudo-count each) of the scores of all detections
            seen, nearly all of them clutter; ``f_T``: histogram of the scores of the detections
            confirmed tracks took, with a prior density ``2 s`` (a classifier scores targets
            higher) worth 20 detections.
        """
        b = self._bins(scores)
        centres = (np.arange(_SCORE_BINS) + 0.5) / _SCORE_BINS
        prior_t = 20.0 * 2.0 * centres / _SCORE_BINS
        f_t = (prior_t + self._score_target) / (prior_t.sum() + self._score_target.sum())
        f_c = (1.0 + self._score_all) / (_SCORE_BINS + self._score_all.sum())
        return np.log(f_t[b] / f_c[b])

    @staticmethod
    def _snr_bins(snr_db: ArrayLike) -> NDArray[np.int64]:
        v = np.nan_to_num(np.asarray(snr_db, float).reshape(-1), nan=0.0)
        return np.clip(v // _SNR_BIN_DB, 0, _SNR_BINS - 1).astype(np.int64)

    def snr_delta(self, snr_db: ArrayLike) -> NDArray[np.float64]:
        """Score change of hits from their SNR, ``ln f_T(snr) / f_C(snr)`` (``snr_evidence``).

        Parameters
        ----------
        snr_db : array_like, shape (k,)
            SNR of each hit's detection, dB.

        Returns
        -------
        ndarray, shape (k,)
            ``f_C``: histogram (2-dB bins, one pseudo-count each) of the SNR of all detections
            seen, nearly all of them clutter; ``f_T``: histogram of the SNR of the detections
            confirmed tracks took, with the prior ``f_T = f_C`` worth 20 detections. Unlike the
            classifier score, the SNR has no side that is the target's a priori, so it is 0
            until confirmed tracks show where targets lie.
        """
        b = self._snr_bins(snr_db)
        f_c = (1.0 + self._snr_all) / (_SNR_BINS + self._snr_all.sum())
        f_t = (_SNR_PRIOR * f_c + self._snr_target) / (_SNR_PRIOR + self._snr_target.sum())
        return np.log(f_t[b] / f_c[b])

    def birth_delta(self, n: int, scores: ArrayLike | None,
                    snr_db: ArrayLike | None) -> NDArray[np.float64]:
        """Starting score of `n` tracks born from detections: the likelihood ratio of their
        classifier score (with ``score_evidence``) and SNR (with ``snr_evidence``), 0 for a
        clue the detections lack; the position of a first detection says nothing of target
        against clutter."""
        out = np.zeros(int(n))
        if scores is not None and self.score_evidence:
            out += self.score_delta(scores)
        if snr_db is not None and self.snr_evidence:
            out += self.snr_delta(snr_db)
        return out

    def scan_delta(
        self, key: Hashable, *, xy: NDArray[np.float64], cov: NDArray[np.float64],
        scores: NDArray[np.float64] | None, hotspots: Hotspots | None,
        track_xy: NDArray[np.float64], hits: NDArray[np.int64], dets: NDArray[np.int64],
        log_pdf: NDArray[np.float64], confirmed: NDArray[np.bool_],
        teach: NDArray[np.bool_] | None = None,
        contested: NDArray[np.bool_] | None = None,
        own: list[NDArray[np.float64]] | None = None,
        snr_db: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """Score change of every track on one receiver's scan; learns from the scan.

        Parameters
        ----------
        key : hashable
            The receiver.
        xy, cov : ndarray, shapes (n, 2) and (n, 2, 2)
            Its detections and their covariances, m and m^2.
        scores : ndarray, shape (n,), or None
            Their classifier scores, if any.
        hotspots : Hotspots or None
            The clutter map's hotspots (:meth:`observe`).
        track_xy : ndarray, shape (t, 2)
            Predicted positions of all tracks, m.
        hits, dets : ndarray of int, shape (k,)
            Tracks that took a detection, and the detection each took.
        log_pdf : ndarray, shape (k,)
            ``ln N(nu; 0, S)`` of those pairs.
        confirmed : ndarray of bool, shape (t,)
            Tracks confirmed before the ping (their hits feed ``f_T``; their detections are
            left out of the clutter intensity).
        teach : ndarray of bool, shape (t,), optional
            Tracks whose hits and misses feed ``P_D`` (default `confirmed`).
        contested : ndarray of bool, shape (t,), optional
            Tracks without a detection of their own though one in their gate went to another
            track: not a miss of their target as far as ``P_D`` is concerned (a duplicate of a
            confirmed track would otherwise teach that targets are missed).
        own : list of ndarray, optional
            With ``leave_track_out``: per hit, the track's earlier detections on this receiver
            that were added to its intensity estimate, rows ``(update, x, y)`` (``update``: the
            estimator's :attr:`~fusion.active.clutter.intensity.ClutterIntensity.updates` after
            adding it, :attr:`last_update`). Their kernels are taken out of ``lambda`` at the
            hit: a target not yet confirmed otherwise raises the clutter intensity along its own
            path and weighs against its own hits (the intensity at the target's hits of
            tentative tracks was measured at ~10 times the clutter at 2 echoes per receiver and
            ping, issue 20).
        snr_db : ndarray, shape (n,), optional
            The detections' SNR, dB (used with ``snr_evidence``: :meth:`snr_delta`).

        Returns
        -------
        ndarray, shape (t,)
            :meth:`miss_delta` for tracks without a detection, :meth:`hit_delta` (plus
            :meth:`score_delta` with scores and ``score_evidence``) for the others.
        """
        maybe_clutter = np.ones(xy.shape[0], dtype=bool)
        maybe_clutter[dets[confirmed[hits]]] = False
        lam = self.observe(key, xy, cov, hotspots, clutter=maybe_clutter, at=dets)
        delta = self.miss_delta(key, track_xy)
        with_scores = scores is not None and self.score_evidence
        if hits.size:
            est = self._intensity.get(key)
            if self.leave_track_out and own is not None and est is not None:
                lam = lam.copy()
                for k in range(hits.size):
                    if own[k].shape[0]:
                        lam[k] = max(lam[k] - est.kernel_intensity(xy[dets[k]], own[k][:, 1:],
                                                                   own[k][:, 0]),
                                     est.min_intensity)
            delta[hits] = self.hit_delta(key, log_pdf, lam)
            if with_scores:
                delta[hits] += self.score_delta(scores[dets])
                self._score_target += np.bincount(self._bins(scores[dets[confirmed[hits]]]),
                                                  minlength=_SCORE_BINS)
        if with_scores:
            self._score_all += np.bincount(self._bins(scores), minlength=_SCORE_BINS)
        if snr_db is not None and self.snr_evidence:
            if hits.size:
                delta[hits] += self.snr_delta(snr_db[dets])
                self._snr_target += np.bincount(self._snr_bins(snr_db[dets[confirmed[hits]]]),
                                                minlength=_SNR_BINS)
            self._snr_all += np.bincount(self._snr_bins(snr_db), minlength=_SNR_BINS)
        # P_D counts: a track hidden by the direct blast (a miss scoring 0) is no trial.
        w = np.asarray(confirmed if teach is None else teach, dtype=float)
        trial = self.miss_delta(key, track_xy) != 0.0
        if self.rates is not None:                # each track's own P_D (track_pd)
            seen = trial.copy()
            seen[hits] = True
            got = np.zeros(seen.size, dtype=bool)
            got[hits] = True
            t_all = np.arange(seen.size)
            p_hat = np.clip(self.rates.predictive(key, self.pd(key), t_all), 1e-3, 1 - 1e-3)
            delta[seen & ~got] = np.log1p(-p_hat[seen & ~got])
            delta[hits] += np.log(p_hat[hits]) - math.log(self.pd(key))
            self.rates.count(key, t_all[seen], got[seen])
        if contested is not None:
            trial &= ~contested
        trial[hits] = True
        self.count_confirmed(key, float(w[hits].sum()), float(w[trial].sum()))
        return delta

    def count_confirmed(self, key: Hashable, hits: int, pings: int) -> None:
        """Add confirmed tracks' hits on a receiver and their pings to its ``P_D`` estimate."""
        c = self._counts.setdefault(key, [0.0, 0.0])
        c[0] += float(hits)
        c[1] += float(pings)
