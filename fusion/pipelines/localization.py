"""Whale-click localization end to end: the click front end, then the sources of each window.

:class:`ClickLocalization` chains :class:`fusion.pipelines.clicks.ClickFrontEnd` (validated,
associated TDOAs per window) and :class:`fusion.localization.localize.MultiSourceLocalizer` (sources
competing for the window's valid TDOAs, refined on a factor graph, eq. 14-22 of *Localization of
Short Duration Periodic Signals*). It holds no algorithm of its own; :func:`result_document`
turns its output into the ``fusion localize`` JSON (the project's file formats, section 2), with
extra keys a reader may ignore (each TDOA's ``sigma``, ``crb``, ``n_clicks``, ``confirmed``,
``passes``, ``consistent``; each window's click count per channel; each source's
``observable``, ``mirror_ambiguous`` and ``residual_rms_s``). A covariance entry the geometry
leaves unbounded is written as :data:`UNBOUNDED_M2`.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from fusion.geometry import SensorArray
from fusion.localization.localize import LocalizationOutput, MultiSourceLocalizer
from fusion.localization.retime import retime_owned
from fusion.localization.surface_paths import PATHS
from fusion.localization.tracks import SourceTracker, Track, WindowSources
from fusion.localization.whale_settings import (
    WHALE_MAX_CANDIDATES,
    WHALE_MIN_TDOAS,
    LocalizerSettings,
    whale_localizer,
)
from fusion.pipelines.clicks import ClickFrontEnd, ClickWindow
from fusion.pipelines.from_recording import (
    RECORDING_SPAN_S,
    RecordingDecisions,
    decide_from_recording,
    recording_start,
)

# LocalizerSettings, whale_localizer and the WHALE_ constants live in
# fusion.localization.whale_settings; re-exported here, where the chain uses them
__all__ = ["AUTO_EXPLAINED", "WHALE_MAX_CANDIDATES", "WHALE_MIN_TDOAS", "ClickLocalization",
           "LocalizedWindow", "LocalizerSettings", "explained_fraction", "result_document",
           "settings_from_args", "track_windows", "whale_localizer"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class LocalizedWindow:
    """One window: the front end's TDOAs and the sources localized from the valid ones.

    Attributes
    ----------
    window : ClickWindow
        The front end's result.
    valid_index : ndarray of int, shape (m,)
        Indices into ``window.tdoas`` of the TDOAs handed to the localizer.
    output : LocalizationOutput or None
        The localizer's result (None when too few valid TDOAs).
    note : str
        Why a window with enough valid TDOAs has no result (the localizer's error, e.g. too
        few independent pairs); empty otherwise. Written with the window and counted in
        ``fusion localize``'s summary.
    """

    window: ClickWindow
    valid_index: np.ndarray
    output: LocalizationOutput | None
    note: str = ""


#: Added in quadrature to every TDOA sigma by default, s (:class:`ClickLocalization`): what the
#: measured sigma does not hold -- sensor positions, sound speed, the drift model.
SIGMA_FLOOR_S = 1e-6

#: With the paths decided from the data, a window whose direct-path sources explain (own with
#: weight > 1/2) at least this fraction of its valid TDOAs is not read along surface paths.
AUTO_EXPLAINED = 0.8


def settings_from_args(args: object) -> LocalizerSettings:
    """:class:`LocalizerSettings` of ``fusion localize``'s options (an argparse namespace)."""
    return LocalizerSettings(method=args.method, surface_paths=args.surface_paths,
                             sea_floor_z=args.sea_floor_z, max_candidates=args.candidates,
                             min_source_tdoas=args.min_source_tdoas,
                             min_redundant_tdoas=getattr(args, "min_redundant_tdoas", 0),
                             echo_ghost_lag_s=getattr(args, "echo_ghost_lag_s", 0.0),
                             drop_echo_only_sensors=getattr(args, "drop_echo_only_sources",
                                                            False))


class ClickLocalization:
    """Audio blocks in, localized windows out.

    Parameters
    ----------
    front_end : ClickFrontEnd, optional
        Default: the method's parameters and the shipped validator.
    localizer : MultiSourceLocalizer, LocalizerSettings or None, optional
        Default ``LocalizerSettings()``, as ``fusion localize`` runs it: candidates competing
        for the TDOAs (eq. 19-22), read along direct paths and, when every sensor is below the
        surface z = 0, along surface-reflected paths too in the windows whose direct sources
        leave TDOAs unexplained (see :meth:`localize`). Settings are turned into localizers
        for each array met (:meth:`LocalizerSettings.localizers`). ``None`` skips
        localization (TDOAs only).
    min_tdoas : int, optional
        Fewest valid TDOAs a window needs to be localized (default 3, a 3-D fix).
    sigma_floor_s : float, optional
        Added in quadrature to every TDOA sigma, s (default 1 us): what the measured sigma
        does not hold -- sensor positions, sound speed, the drift model.
    decide : bool, optional
        Decide the replica, the detection band, the echo suppression and the sea floor from
        the first :data:`~fusion.pipelines.from_recording.RECORDING_SPAN_S` seconds of each
        recording run through :meth:`iter_windows` or :meth:`run_array`, as ``fusion
        localize`` does (default True; :meth:`with_recording_decisions`,
        ``docs/localization.md`` sections 1, 2, 9 and 14). False runs the front end and the
        localizer as given (the ablation). :meth:`localize` of one window and the chunks of
        :mod:`fusion.pipelines.clicks.chunks` never decide: decide once first.

    Attributes
    ----------
    decisions : RecordingDecisions or None
        The decisions made for the last recording run (None before one, or with
        ``decide=False``).
    """

    def __init__(
        self,
        *,
        front_end: ClickFrontEnd | None = None,
        localizer: MultiSourceLocalizer | LocalizerSettings | None | bool = True,
        min_tdoas: int = 3,
        sigma_floor_s: float = SIGMA_FLOOR_S,
        decide: bool = True,
    ) -> None:
        self.front_end = front_end if front_end is not None else ClickFrontEnd()
        if localizer is True:
            localizer = LocalizerSettings()
        self.settings = localizer if isinstance(localizer, LocalizerSettings) else None
        self.localizer = None if self.settings is not None else (localizer or None)
        self._resolved: tuple[bytes, tuple] | None = None
        self.min_tdoas = int(min_tdoas)
        self.sigma_floor_s = float(sigma_floor_s)
        self.decide = bool(decide)
        self.decisions: RecordingDecisions | None = None

    def with_recording_decisions(
        self, samples: ArrayLike, fs: float, sensors: SensorArray, **options: Any
    ) -> tuple[ClickLocalization, RecordingDecisions]:
        """This pipeline with the decisions made from a recording's start (``fusion localize``'s).

        :func:`fusion.pipelines.from_recording.decide_from_recording` on the first
        :data:`~fusion.pipelines.from_recording.RECORDING_SPAN_S` seconds of `samples`
        (n, n_sensors), starting from this front end's detector and these settings: the
        replica (step 32), the detection band, the bottom echoes (echo suppression) and the
        sea floor. A localizer given as a :class:`MultiSourceLocalizer` keeps its own search
        region (only the detector's decisions apply).

        Parameters
        ----------
        samples : array_like, shape (n, n_sensors)
            The recording, or at least its first minute.
        fs : float
            Sample rate, Hz.
        sensors : SensorArray
            The array.
        **options
            Passed on to :func:`~fusion.pipelines.from_recording.decide_from_recording`
            (``estimate_replica``, ``estimate_band``, ``replica_source``, ``span``,
            ``weak_echoes``).

        Returns
        -------
        pipeline : ClickLocalization
            A new pipeline (``decide`` False) with the decided detector and settings; its
            ``decisions`` set.
        decisions : RecordingDecisions
        """
        x = np.asarray(samples)[:int(round(RECORDING_SPAN_S * fs))]
        decided = decide_from_recording(x, fs, sensors, detector=self.front_end.detector,
                                        settings=self.settings, **options)
        front = copy.copy(self.front_end)
        front.detector = decided.detector
        pipe = ClickLocalization(
            front_end=front, localizer=decided.settings if self.settings is not None
            else self.localizer, min_tdoas=self.min_tdoas, sigma_floor_s=self.sigma_floor_s,
            decide=False)
        pipe.decisions = decided
        return pipe, decided

    def localizers_for(self, sensors: SensorArray
                       ) -> tuple[MultiSourceLocalizer | None, MultiSourceLocalizer | None]:
        """The localizer used for this array and its surface-path fallback (or None).

        Settings are resolved once per array (:meth:`LocalizerSettings.localizers`).
        """
        if self.settings is None:
            return self.localizer, None
        key = np.asarray(sensors.positions, dtype=float).tobytes()
        if self._resolved is None or self._resolved[0] != key:
            self._resolved = (key, self.settings.localizers(sensors.positions))
        return self._resolved[1]

    def localizer_for(self, sensors: SensorArray) -> MultiSourceLocalizer | None:
        """The localizer used first for this array (settings resolved once per array)."""
        return self.localizers_for(sensors)[0]

    def localize(self, window: ClickWindow, sensors: SensorArray) -> LocalizedWindow:
        """Localize the sources of one front-end window from its valid TDOAs.

        Notes
        -----
        Each refined TDOA is measured at the window centre on the clock of its pair's first
        sensor, and a moving source drifts it (``rate``, up to ~2.7 ms/s at 2 m/s). TDOAs of
        different pairs therefore refer to different emission times, up to the array's
        travel-time spread apart. Two passes: (1) every sigma is widened by the drift over half
        that spread (plus `sigma_floor_s`); (2) each TDOA is moved along its drift to the
        arrival time at its first sensor of one emission of the source that owns it (emitted
        when the mean arrival is at the window centre, the arrival along the path the source
        reads the TDOA on) and the window is solved again with the measured sigmas (plus the
        floor). With surface-reflected paths (the localizer's ``surface_z``) pass (2) runs
        twice: the paths found by the first retimed solve retime the echoes.

        Paths decided from the data (settings with ``surface_paths`` None, sensors below the
        surface): the window is solved along direct paths; when its sources explain less
        than :data:`AUTO_EXPLAINED` of the valid TDOAs (a TDOA is explained when one source
        owns it with weight > 1/2) it is solved again reading surface-reflected paths too,
        and that solution is kept if it explains more of them.
        """
        idx = np.array([k for k, d in enumerate(window.tdoas) if d.valid], dtype=int)
        localizer, fallback = self.localizers_for(sensors)
        if localizer is None or idx.size < self.min_tdoas:
            return LocalizedWindow(window, idx, None)
        out, note = self._solve(localizer, window, idx, sensors)
        if fallback is not None and explained_fraction(out) < AUTO_EXPLAINED:
            other, other_note = self._solve(fallback, window, idx, sensors)
            if explained_fraction(other) > explained_fraction(out):
                out = other
            note = note or other_note
        return LocalizedWindow(window, idx, out, "" if out is not None else note)

    def _solve(self, localizer: MultiSourceLocalizer, window: ClickWindow, idx: np.ndarray,
               sensors: SensorArray) -> tuple[LocalizationOutput | None, str]:
        """The window's valid TDOAs (indices `idx`) solved by one localizer (the passes above),
        and the localizer's error when it found no solution."""
        d = [window.tdoas[k] for k in idx]
        pos = sensors.positions
        c = sensors.sound_speed
        pairs = np.array([t.pair for t in d])
        taus = np.array([t.tau_s for t in d])
        sig = np.hypot(np.array([t.sigma_s for t in d]), self.sigma_floor_s)
        rate = np.array([t.rate for t in d])
        alpha = window.alpha[np.ix_(idx, idx)]
        spread = float(np.max(np.linalg.norm(pos[:, None] - pos[None], axis=2))) / c
        surface_z = getattr(localizer, "surface_z", None)
        try:
            # pass 1: direct paths, sigmas widened by the drift over half the travel-time spread
            out = localizer.localize(pos, pairs, taus, np.hypot(sig, rate * 0.5 * spread),
                                          alpha, c=c)
            # pass 2 (and 3 when surface-reflected paths are read: the paths of pass 2 retime
            # the echoes): each TDOA moved to one emission of the source that owns it
            for _ in range(1 if surface_z is None else 2):
                if not (out.sources and np.any(rate != 0)):
                    break
                retimed = retime_owned(out, taus, rate, pairs, pos, c, surface_z)
                out = localizer.localize(pos, pairs, retimed, sig, alpha, c=c)
        except ValueError as e:  # e.g. too few independent pairs: no fix in this window
            logger.info("window %.1f s: not localized (%s)", window.t_start, e)
            return None, str(e)
        return out, ""

    def iter_windows(
        self, blocks: Iterable, *, fs: float, sensors: SensorArray, duration_s: float | None = None
    ) -> Iterator[LocalizedWindow]:
        """Stream audio blocks (see :meth:`ClickFrontEnd.iter_windows`); yield each window.

        With ``decide`` (the default) the first minute of blocks is held, the decisions are
        made from it (:meth:`with_recording_decisions`, kept in ``decisions``) and the stream
        is run through the decided pipeline.
        """
        pipe = self
        if self.decide:
            first, blocks = recording_start(blocks, fs)
            pipe, self.decisions = self.with_recording_decisions(first, fs, sensors)
        for w in pipe.front_end.iter_windows(blocks, fs=fs, sensors=sensors,
                                             duration_s=duration_s):
            yield pipe.localize(w, sensors)

    def run_array(self, audio: ArrayLike, fs: float, sensors: SensorArray
                  ) -> list[LocalizedWindow]:
        """Every localized window of audio held in memory (n, n_sensors), in blocks of one
        update (:meth:`iter_windows`)."""
        x = np.asarray(audio)
        if x.ndim != 2:
            raise ValueError(f"audio must have shape (n, n_sensors), got {x.shape}")
        step = int(round(self.front_end.hop_s * fs))
        blocks = ((a / fs, x[a:a + step]) for a in range(0, x.shape[0], step))
        return list(self.iter_windows(blocks, fs=fs, sensors=sensors,
                                      duration_s=x.shape[0] / fs))


def explained_fraction(out: LocalizationOutput | None) -> float:
    """Fraction of a solution's TDOAs owned by one of its sources with weight > 1/2."""
    if out is None or not out.sources:
        return 0.0
    w = np.stack([s.weights for s in out.sources])
    return float(np.mean(w.max(axis=0) > 0.5)) if w.size else 0.0


#: Variance written for a direction the geometry leaves unobservable, m^2 (``observable`` false).
UNBOUNDED_M2 = 1e12


def _f(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def track_windows(
    windows: Sequence[LocalizedWindow], tracker: SourceTracker | None = None
) -> tuple[Track, ...]:
    """Link the windows' sources into tracks and smooth each (:class:`SourceTracker`).

    Sources of consecutive windows are linked first through the TDOAs they own that the front
    end's time association linked (eq. 12), then by position; the window centre is each point's
    time. Fixes flagged unobservable are not tracked.
    """
    tracker = tracker if tracker is not None else SourceTracker()
    items = []
    prev_pos: dict[int, int] = {}
    for lw in windows:
        w = lw.window
        pos_of = {int(k): m for m, k in enumerate(lw.valid_index)}  # all-TDOA index -> valid
        prev_of = dict((cur, prev) for prev, cur in w.links_previous)
        links = np.array([prev_pos.get(prev_of.get(int(k), -1), -1) for k in lw.valid_index],
                         dtype=np.intp)
        # a fix flagged unobservable is reported but not tracked (the tracker skips fixes
        # without a finite covariance; indices stay those of the window's sources)
        sources = () if lw.output is None else tuple(
            f if f.observable else dataclasses.replace(f, covariance=np.full((3, 3), np.nan))
            for f in lw.output.sources)
        items.append(WindowSources(0.5 * (w.t_start + w.t_end), sources,
                                   links if sources else None))
        prev_pos = pos_of
    return tracker.track(items)


def result_document(windows: Iterable[LocalizedWindow], *, tracks: Iterable[Track] = ()) -> dict:
    """The ``fusion localize`` JSON document of localized windows and tracks (formats, 2)."""
    doc_windows = []
    for lw in windows:
        w = lw.window
        tdoas = [
            {"pair": [int(d.pair[0]), int(d.pair[1])], "tau": float(d.tau_s),
             "t": float(d.t_s), "rate": float(d.rate), "valid": d.valid,
             "llr": _f(d.llr) if np.isfinite(d.llr) else 0.0, "sigma": float(d.sigma_s),
             "crb": _f(d.crb_s), "n_clicks": int(d.n_clicks), "passes": d.passes,
             "confirmed": d.confirmed, "consistent": d.consistent}
            for d in w.tdoas
        ]
        sources = []
        if lw.output is not None:
            for s in lw.output.sources:
                # an unobservable direction has no finite variance: written as UNBOUNDED_M2
                cov = np.where(np.isfinite(s.covariance), s.covariance, UNBOUNDED_M2)
                owned = np.flatnonzero(s.weights > 0.5)
                sources.append({
                    "x": float(s.position[0]), "y": float(s.position[1]),
                    "z": float(s.position[2]), "cov": cov.tolist(),
                    "tdoas_used": int(s.tdoas_used), "observable": bool(s.observable),
                    "mirror_ambiguous": bool(s.mirror_ambiguous),
                    "residual_rms_s": _f(s.residual_rms_s),
                    "owned_tdoas": [int(lw.valid_index[k]) for k in owned],
                    "paths": [PATHS[max(int(s.paths[k]), 0)] for k in owned],
                })
        doc_windows.append({"t_start": float(w.t_start), "t_end": float(w.t_end),
                            "clicks": [int(c.n_clicks) for c in w.clicks],
                            "tdoas": tdoas, "sources": sources,
                            **({"not_localized": lw.note} if lw.note else {})})
    return {"windows": doc_windows, "tracks": [t.to_dict() for t in tracks]}
